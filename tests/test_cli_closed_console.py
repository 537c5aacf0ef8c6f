"""Issue 26: a closed or broken stdout/stderr never stops or freezes the search.

Reported: ``uavloc demo --no-web | head -2`` exited 0 after 4 s and abandoned the search;
``uavloc daemon ... | timeout 8 cat`` kept running but made no decision after 138 s. Here the
reader is a real pipe closed early, as ``head -2`` and ``timeout 8 cat`` close it: the search
still completes, its results are written (not marked partial) and its log goes on to the store
and uavloc.log.
"""

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from uavloc_gcs.service.store import StoreReader

pytestmark = pytest.mark.slow  # a whole search or demo: `pytest -m 'not slow and not sitl'` leaves it out

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("close", ["stdout after 2 lines", "stdout and stderr after 8 s"])
def test_a_closed_console_does_not_stop_the_search(tmp_path, close):
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "uavloc_gcs", "demo", "--no-web", "--scenario", "small", "--people", "2",
           "--base-port", "0", "--out", str(out)]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, cwd=tmp_path)
    try:
        if close.startswith("stdout after"):
            p.stdout.readline(), p.stdout.readline()  # head -2
            p.stdout.close()
        else:  # timeout 8 cat, its 8 s counted from the search's start (a loaded machine starts slowly)
            while b"connected" not in p.stdout.readline():
                assert p.poll() is None, p.stderr.read()
            time.sleep(8.0)
            p.stdout.close()
            p.stderr.close()
        rc = p.wait(timeout=900)
    finally:
        if p.poll() is None:
            p.kill()
    assert rc == 0, (rc, out.exists() and (out / "uavloc.log").read_text()[-2000:])
    with StoreReader(out / "search.sqlite") as rd:
        meta = rd.meta()
        ends = [e.text for e in rd.events("end")]
    assert meta.get("finished") is True, ends
    assert any("replans" in t for t in ends), ends  # the search went on to its end
    csv_text = (out / "people.csv").read_text()
    assert csv_text.startswith("label,") and "PARTIAL" not in csv_text
    assert (out / "result.png").exists()
    assert "vehicle 1" in (out / "uavloc.log").read_text()
