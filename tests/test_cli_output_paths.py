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
