"""``uavloc demo`` stopped by a signal at any moment leaves no fake-fleet process behind."""

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # a whole search or demo: `pytest -m 'not slow and not sitl'` leaves it out

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _children(pid: int) -> set[int]:
    out = set()
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                stat = (d / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                out.add(int(d.name))
    return out


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.parametrize("sig,when", [(signal.SIGTERM, "flying"), (signal.SIGINT, "flying"),
                                      (signal.SIGTERM, "starting")])
def test_a_signal_stops_the_demo_and_its_fleet(tmp_path, sig, when):
    out = tmp_path / "demo"
    proc = subprocess.Popen(
        [sys.executable, "-m", "uavloc_gcs", "demo", "--scenario", str(EXAMPLES / "small.toml"), "--people", "2",
         "--speedup", "20", "--base-port", "0", "--out", str(out)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        children: set[int] = set()
        while time.monotonic() < deadline and proc.poll() is None:
            children |= _children(proc.pid)
            if when == "starting" and children:
                break
            if when == "flying" and (out / "uav1.tlog").exists() and (out / "uav1.tlog").stat().st_size > 20000:
                break
            time.sleep(0.05)
        assert proc.poll() is None and children, "the demo started its fleet"
        proc.send_signal(sig)
        _, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 128 + sig, stderr
    assert "Traceback" not in stderr and f"stopped by {signal.Signals(sig).name}" in stderr, stderr
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline and any(_alive(c) for c in children):
        time.sleep(0.1)
    assert not any(_alive(c) for c in children), "a child of the demo outlived it"


def test_ctrl_c_in_the_field_world_ends_within_seconds_with_the_results_written(tmp_path):
    """Issue 42 item 3: Ctrl-C in the field world took 4.5 minutes to end the process (the stop
    statement after 3 s, the files after 70 s, the policy planning and fitting on). Stopped once
    the looks have begun, when fits of many people are under way, the demo ends within seconds,
    its fitting worker and fleet with it, and the partial results are written."""
    out = tmp_path / "demo"
    proc = subprocess.Popen(
        [sys.executable, "-m", "uavloc_gcs", "demo", "--scenario", "field", "--no-web", "--base-port", "0",
         "--out", str(out)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 300
        children: set[int] = set()
        log = out / "uavloc.log"
        while time.monotonic() < deadline and proc.poll() is None:
            children |= _children(proc.pid)
            if log.exists() and "looks at" in log.read_text():
                break
            time.sleep(0.2)
        assert proc.poll() is None, "the demo ended before its looks began"
        children |= _children(proc.pid)
        t0 = time.monotonic()
        proc.send_signal(signal.SIGINT)
        _, stderr = proc.communicate(timeout=120)
        took = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 128 + signal.SIGINT, stderr
    assert took < 30.0, f"the demo took {took:.0f} s to end after Ctrl-C"
    assert "PARTIAL" in (out / "results.txt").read_text()
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline and any(_alive(c) for c in children):
        time.sleep(0.1)
    assert not any(_alive(c) for c in children), "a child of the demo outlived it"
