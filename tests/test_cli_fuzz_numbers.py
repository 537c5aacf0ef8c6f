"""Issue 29 item 3: every command's numeric flags fuzzed (hypothesis). Whatever number -- or
non-number -- is typed, the command ends without a traceback, with exit 0, 1 or 2 (bad input),
and an error is one line naming the flag or key.

Each case stays fast: small scenarios, few examples, and where a valid value would start a long
run (a fleet, a search, a benchmark) a later input is missing on purpose so the command stops
right after checking its numbers (that later failure is exit 2 too).
"""

from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from uavloc_gcs.cli import main

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"

FAST = settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])

# what an operator might type: numbers of every size and sign, non-finite spellings, junk
NUMBERS = st.one_of(
    st.integers(min_value=-10**12, max_value=10**12).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(["", "x", "1e309", "-0", "0x10", "1_000", " 3", "nan", "-inf", "1e-320"]),
)


def _run(capsys, *args):
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    assert code in (0, 1, 2), (args, code, out.err[-2000:])
    assert "Traceback" not in out.err, out.err
    if code == 2:
        errors = [ln for ln in out.err.splitlines() if "error:" in ln]
        assert len(errors) == 1, out.err
    return code, out


@FAST
@given(flag=st.sampled_from(["--lane-spacing"]), value=NUMBERS)
def test_plan(tmp_path, capsys, flag, value):
    code, out = _run(capsys, "plan", "small", f"{flag}={value}", "--out", tmp_path / "o")
    if code == 2:
        assert flag in out.err and "small.toml" not in out.err


@FAST
@given(value=NUMBERS)
def test_preview(tmp_path, capsys, value):
    _run(capsys, "preview", EXAMPLES.parent / "tests" / "data" / "files" / "do_jump_px4.plan", f"--width={value}", "--no-table")


@FAST
@given(value=NUMBERS)
def test_localize(tmp_path, capsys, value):
    code, out = _run(capsys, "localize", EXAMPLES / "slots_small.csv", "--scenario", "small", f"--t-ref={value}",
                     "--out", tmp_path / "o")
    if code == 2:
        assert "--t-ref" in out.err


@FAST
@given(flag=st.sampled_from(["--time-limit", "--seed"]), value=NUMBERS)
def test_route(tmp_path, capsys, flag, value):
    try:
        if flag == "--time-limit" and 0.05 < float(value) < float("inf"):
            value = "0.05"  # a valid long search is not the point here
    except ValueError:
        pass
    code, out = _run(capsys, "route", "route_paper", f"{flag}={value}", "--out", tmp_path / "r.json")
    if code == 2:
        assert flag in out.err


@FAST
@given(flag=st.sampled_from(["--speedup", "--loss", "--latency-ms", "--seed", "--base-port", "--status-s"]),
       value=NUMBERS)
def test_sim(tmp_path, capsys, flag, value):
    # a missing scenario: valid numbers then stop at loading it instead of running a fleet
    code, _ = _run(capsys, "sim", tmp_path / "missing.toml", f"{flag}={value}")
    assert code == 2


@FAST
@given(flag=st.sampled_from(["--timeout", "--system"]), value=NUMBERS)
def test_upload_and_download(tmp_path, capsys, flag, value):
    code, out = _run(capsys, "upload", tmp_path / "missing.plan", "--to", "udpout:127.0.0.1:9", f"{flag}={value}")
    assert code == 2
    code, out = _run(capsys, "download", "--from", "udpout:127.0.0.1:9", f"{flag}={value}", "--out",
                     tmp_path / "x.csv")
    assert code == 2


@FAST
@given(flag=st.sampled_from(["--connect-timeout", "--planner-time-limit", "--web-port"]), value=NUMBERS)
def test_daemon(tmp_path, capsys, flag, value):
    code, _ = _run(capsys, "daemon", "--config", tmp_path / "missing.toml", f"{flag}={value}")
    assert code == 2


@FAST
@given(flag=st.sampled_from(["--speedup", "--people", "--seed", "--loss", "--base-port"]), value=NUMBERS)
def test_demo(capsys, flag, value):
    # valid numbers go through the scenario overrides, then the output directory cannot be made
    code, out = _run(capsys, "demo", "--scenario", "small", "--no-web", f"{flag}={value}", "--out", "/proc/uavloc-x")
    assert code == 2
    assert "small.toml" not in out.err


@FAST
@given(flag=st.sampled_from(["--runs", "--jobs", "--seed", "--iterations", "--error-people", "--people"]),
       value=NUMBERS)
def test_experiment(tmp_path, capsys, flag, value):
    code, _ = _run(capsys, "experiment", "paper", f"{flag}={value}", "--scenario", tmp_path / "missing.toml",
                   "--out", tmp_path / "o")
    assert code == 2


@FAST
@given(bench=st.sampled_from([("localize", "--runs"), ("localize", "--seed"), ("looks", "--people"),
                              ("looks", "--jobs"), ("identity", "--runs"), ("identity", "--duration"),
                              ("plan", "--time-limit"), ("scan_coverage", "--runs")]), value=NUMBERS)
def test_bench(tmp_path, capsys, bench, value):
    name, flag = bench
    code, _ = _run(capsys, "bench", name, f"{flag}={value}", "--scenario", tmp_path / "missing.toml")
    assert code == 2


@FAST
@given(flag=st.sampled_from(["--slot-ms", "--dwell-ms", "--duration-s", "--vehicle", "--clock-offset-s",
                             "--learn-min-frames", "--sysid"]), value=NUMBERS)
def test_sense(tmp_path, capsys, flag, value):
    """Issue 40: --slot-ms nan, --clock-offset-s inf, --learn-min-frames -1 were taken (garbage slots,
    exit 0) and --sysid 999 was a struct.error; a missing capture stops valid numbers."""
    code, out = _run(capsys, "sense", tmp_path / "missing.pcap", f"{flag}={value}", "--out", tmp_path / "o")
    assert code == 2


@FAST
@given(flag=st.sampled_from(["--seed", "--speedup", "--base-port", "--home-alt", "--ready-timeout"]), value=NUMBERS)
def test_sitl(tmp_path, capsys, flag, value):
    """sitl --seed -1 crashed after the vehicles had started; a missing scenario stops valid numbers."""
    code, _ = _run(capsys, "sitl", tmp_path / "missing.toml", f"{flag}={value}")
    assert code == 2


@FAST
@given(bench=st.sampled_from([("sense", "--frames"), ("sense", "--repeats"), ("sense", "--scapy-frames")]),
       value=NUMBERS)
def test_bench_sense_counts(capsys, bench, value):
    """bench sense --frames 0/-1 were ZeroDivisionError/IndexError. Valid counts would run the
    benchmark, so only the refused ones are run here."""
    name, flag = bench
    try:
        ok = 1 <= int(value) <= 2_000_000  # as argparse reads it ("1_000", " 3")
    except ValueError:
        ok = False
    if ok:
        return
    code, _ = _run(capsys, "bench", name, f"{flag}={value}")
    assert code == 2
