"""Output paths that cannot be written are one sentence and exit 2, before any work, with nothing
half-written: an existing directory where a file is wanted, a file in a missing directory."""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ROUTE = ROOT / "examples" / "route_paper.json"
PLAN = ROOT / "tests" / "data" / "small" / "uav1.plan"


def _uavloc(*args, cwd):
    return subprocess.run([sys.executable, "-m", "uavloc_gcs", *map(str, args)], capture_output=True, text=True,
                          timeout=120, cwd=cwd, env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})


CASES = {
    "route --out EXISTING_DIR": (lambda d: ["route", ROUTE, "--time-limit", "0.2", "--out", d / "existing"],
                                 "--out", "is a directory"),
    "route --png missing_dir/x.png": (lambda d: ["route", ROUTE, "--time-limit", "0.2", "--png", d / "missing" / "x.png"],
                                      "--png", "does not exist"),
    "download --out EXISTING_DIR": (lambda d: ["download", "--from", "udpout:127.0.0.1:9", "--out", d / "existing"],
                                    "--out", "is a directory"),
    "download --out missing_dir/x.plan": (lambda d: ["download", "--from", "udpout:127.0.0.1:9",
                                                     "--out", d / "missing" / "x.plan"], "--out", "does not exist"),
    "preview --png missing_dir/x.png": (lambda d: ["preview", PLAN, "--png", d / "missing" / "x.png"],
                                        "--png", "does not exist"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_an_unwritable_output_path_is_one_sentence(tmp_path, case):
    args, option, words = CASES[case]
    (tmp_path / "existing").mkdir()
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    r = _uavloc(*args(tmp_path), cwd=tmp_path)
    assert r.returncode == 2, (r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert option in lines[0] and words in lines[0], lines[0]
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before  # nothing written


# ---------------------------------------------------------------------------------------------
# issue 40 item 4: a directory where nothing can be written is refused before any work (as
# /proc on Linux, even for root), and --out on another filesystem works

SLOTS = ROOT / "examples" / "slots_small.csv"
PCAP = ROOT / "tests" / "uavloc_gcs" / "sense" / "real" / "ieee802.11_exthdr.pcap"
UNWRITABLE = Path("/proc/uavloc-test-out")  # /proc holds no files or directories of ours, for any user
IN_PROC = Path("/proc")

UNWRITABLE_CASES = {
    "preview --png": (["preview", PLAN, "--png", IN_PROC / "uavloc-test.png"], "--png"),
    "route --out": (["route", ROUTE, "--time-limit", "0.2", "--out", IN_PROC / "uavloc-test.json"], "--out"),
    "route --png": (["route", ROUTE, "--time-limit", "0.2", "--png", IN_PROC / "uavloc-test.png"], "--png"),
    # a connection nobody answers: refused before connecting (a connection attempt is exit 3)
    "download --out": (["download", "--from", "udpout:127.0.0.1:9", "--out", IN_PROC / "uavloc-test.plan"], "--out"),
    "download --tlog": (["download", "--from", "udpout:127.0.0.1:9", "--out", "x.plan", "--tlog",
                         IN_PROC / "uavloc-test.tlog"], "--tlog"),
    "upload --tlog": (["upload", PLAN, "--to", "udpout:127.0.0.1:9", "--tlog", IN_PROC / "uavloc-test.tlog"], "--tlog"),
    "plan --out": (["plan", "small", "--out", UNWRITABLE], "--out"),
    "localize --out": (["localize", SLOTS, "--scenario", "small", "--out", UNWRITABLE], "--out"),
    "sense --out": (["sense", PCAP, "--out", UNWRITABLE], "--out"),
    "sense --learn-team": (["sense", PCAP, "--learn-team", IN_PROC / "team.txt"], "--learn-team"),
    "experiment --out": (["experiment", "paper", "--runs", "1", "--people", "5", "--scenario", "small",
                          "--out", UNWRITABLE], "--out"),
    "plan --out FILE/x": (["plan", "small", "--out", "afile/x"], "--out"),
}


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs Linux's /proc, where no file can be created")
@pytest.mark.parametrize("case", sorted(UNWRITABLE_CASES))
def test_an_output_where_nothing_can_be_written_is_refused_first(tmp_path, case):
    args, option = UNWRITABLE_CASES[case]
    (tmp_path / "afile").write_text("")
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    r = _uavloc(*args, cwd=tmp_path)
    assert r.returncode == 2, (r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert option in lines[0] and ("cannot write in" in lines[0] or "is a file, not a directory" in lines[0]), lines[0]
    assert r.stdout == ""  # no work was done: nothing planned, estimated, parsed or run
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before


OWN_FILE_CASES = {
    "route --out INSTANCE": (["route", "r.json", "--time-limit", "0.2", "--out", "r.json"], "r.json",
                             "routing instance"),
    "upload --tlog MISSION": (["upload", "m.plan", "--to", "udpout:127.0.0.1:9", "--tlog", "m.plan"], "m.plan",
                              "mission file"),
    "sense --learn-team CAPTURE": (["sense", "c.pcap", "--learn-team", "c.pcap"], "c.pcap", "capture"),
}


@pytest.mark.parametrize("case", sorted(OWN_FILE_CASES))
def test_an_output_that_is_the_commands_own_input_is_refused(tmp_path, case):
    import shutil

    args, name, words = OWN_FILE_CASES[case]
    shutil.copy(ROUTE, tmp_path / "r.json")
    shutil.copy(PLAN, tmp_path / "m.plan")
    shutil.copy(PCAP, tmp_path / "c.pcap")
    before = (tmp_path / name).read_bytes()
    r = _uavloc(*args, cwd=tmp_path)
    assert r.returncode == 2, (r.stdout, r.stderr)
    line, = r.stderr.strip().splitlines()
    assert words in line and "give another name" in line, line
    assert (tmp_path / name).read_bytes() == before


@pytest.fixture
def usb(tmp_path):
    """``tmp_path/usb``: a link to a directory on another filesystem (a tmpfs under /dev/shm), as
    a USB stick's mount point is; skipped, saying why, where the machine has no second one."""
    import os
    import shutil
    import tempfile

    shm = Path("/dev/shm")
    if not shm.is_dir() or not os.access(shm, os.W_OK) or shm.stat().st_dev == tmp_path.stat().st_dev:
        pytest.skip("no second filesystem here (/dev/shm missing or on the temporary directory's device); "
                    "tests/uavloc_gcs/test_atomicfile.py also makes rename fail with EXDEV")
    stick = Path(tempfile.mkdtemp(prefix="uavloc-usb-", dir=shm))
    (tmp_path / "usb").symlink_to(stick)
    yield stick
    shutil.rmtree(stick, ignore_errors=True)


ACROSS = {
    "plan": (["plan", "small", "--out", "usb"], {"uav1.plan", "preview.png", "scan.geojson"}),
    "localize": (["localize", SLOTS, "--scenario", "small", "--out", "usb"], {"estimates.csv", "estimates.png"}),
    "sense": (["sense", PCAP, "--out", "usb"], {"frames.csv"}),
    "experiment": (["experiment", "paper", "--runs", "1", "--people", "5", "--methods", "MLE-EPSO (M)",
                    "--error-people", "0", "--iterations", "1", "--scenario", "small", "--no-progress",
                    "--out", "usb"], {"runs.csv", "summary.md"}),
}


@pytest.mark.parametrize("command", sorted(ACROSS))
def test_out_on_another_filesystem_is_written(tmp_path, usb, command):
    """Was ``OSError: Invalid cross-device link`` from the rename (issue 40)."""
    args, some = ACROSS[command]
    (usb / "mine.txt").write_text("the operator's own file")
    r = _uavloc(*args, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    names = {p.name for p in usb.iterdir()}
    assert some <= names and "mine.txt" in names, names
    assert not [n for n in names if n.startswith(".")], names  # no staging left on the stick
    assert sorted(p.name for p in tmp_path.iterdir()) == ["usb"]  # and none beside it
