"""Stopping ``uavloc daemon`` (SIGTERM/Ctrl-C) tells where every vehicle goes and sends the
airborne home (or lets them fly on with on_stop = "continue"); a second daemon on the same
store is refused while the first runs."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from sim_link.vehicles.fleet import FakeFleet
from tests.e2e_helpers import SMALL, small_scenario

ROOT = Path(__file__).resolve().parents[1]


def _env():
    return {**os.environ, "PYTHONPATH": str(ROOT)}


def _config(tmp_path, fleet, on_stop):
    conns = ", ".join(f'"{c}"' for _n, c in fleet.endpoints)
    extra = f'[link]\nconnections = [{conns}]\non_stop = "{on_stop}"\n'
    path = tmp_path / "mission.toml"
    path.write_text(SMALL.format(autopilot="ardupilot", seed=3, speedup=10.0, extra=extra))
    return path


def _wait(pred, timeout_s, what):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if pred():
            return
        time.sleep(0.1)
    raise AssertionError(f"timed out waiting for {what}")


@pytest.mark.slow
@pytest.mark.parametrize("on_stop,sig", [("rtl", signal.SIGTERM), ("continue", signal.SIGINT)])
def test_stopping_the_daemon_says_what_each_vehicle_does(tmp_path, on_stop, sig):
    sc = small_scenario("ardupilot", speedup=10.0)
    fleet = FakeFleet(sc, speedup=10.0, seed=3, base_port=0).start_in_thread()
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "uavloc_gcs", "daemon", "--config", str(_config(tmp_path, fleet, on_stop)),
           "--out", str(out)]
    first = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env(), cwd=tmp_path)
    try:
        _wait(lambda: all(not v.landed and v.position_xyz_m[2] > 20.0 for v in fleet.vehicles) or first.poll() is not None,
              90, "both vehicles airborne")
        assert first.poll() is None, first.communicate()
        second = subprocess.run(cmd, capture_output=True, text=True, env=_env(), cwd=tmp_path, timeout=60)
        assert second.returncode == 2, second.stderr
        line = second.stderr.strip()
        assert "\n" not in line and f"in use by another uavloc daemon (pid {first.pid})" in line, line
        first.send_signal(sig)
        _stdout, stderr = first.communicate(timeout=60)
    finally:
        if first.poll() is None:
            first.kill()
        modes = [v.mode for v in fleet.vehicles]
        fleet.stop()
    assert first.returncode == 128 + sig, stderr
    assert f"stopped by {signal.Signals(sig).name}" in stderr and "Traceback" not in stderr, stderr
    if on_stop == "rtl":
        assert modes == ["RTL", "RTL"], modes
        for vid in (1, 2):
            assert f"vehicle {vid}: airborne, returning home (RTL" in stderr, stderr
    else:
        assert modes == ["AUTO", "AUTO"], modes
        for vid in (1, 2):
            assert f"vehicle {vid}: airborne, continues its scan mission" in stderr and "ends in RTL" in stderr
    # the results so far are written, marked partial in the files and the final sentence (issue 26)
    assert "PARTIAL RESULTS" in stderr and "people.csv" in stderr, stderr
    csv_text = (out / "people.csv").read_text()
    assert csv_text.startswith("# PARTIAL RESULTS"), csv_text[:200]
    assert "PARTIAL" in (out / "results.txt").read_text().splitlines()[0]
    import json

    assert "PARTIAL" in json.loads((out / "people.geojson").read_text())["partial"]
    assert (out / "result.png").stat().st_size > 1000
    # the lock died with the process: the same store can be used again at once
    again = subprocess.run([*cmd[:-2], "--out", str(out), "--connect-timeout", "0.5"], capture_output=True,
                           text=True, env=_env(), cwd=tmp_path, timeout=60)
    assert "in use by another" not in again.stderr
