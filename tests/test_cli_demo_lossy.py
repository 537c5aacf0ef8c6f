"""``uavloc demo --loss 0.2`` (20 % of the datagrams lost in each direction on every link) runs to
its end on several seeds: no link error aborts the search, every vehicle ends home."""

import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # a whole search or demo: `pytest -m 'not slow and not sitl'` leaves it out

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_lossy_demo_runs_to_its_end(tmp_path, seed):
    out = tmp_path / "demo"
    r = subprocess.run(
        [sys.executable, "-m", "uavloc_gcs", "demo", "--scenario", str(EXAMPLES / "small.toml"), "--loss", "0.2",
         "--people", "2", "--speedup", "50", "--seed", str(seed), "--base-port", "0", "--out", str(out)],
        capture_output=True, text=True, timeout=240)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert "Traceback" not in r.stderr and "error" not in r.stderr, r.stderr[-2000:]
    statement = [line for line in r.stdout.splitlines() if "located" in line and "home" in line]
    assert statement, r.stdout[-2000:]
    assert "All vehicles are home" in statement[-1] or "returning home" in statement[-1], statement[-1]
    assert (out / "people.csv").is_file() and (out / "result.png").is_file()
