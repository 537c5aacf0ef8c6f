"""SIGTERM stops a test run even while a daemon inside a test holds SIGTERM (issue 29: `kill` of
pytest was caught by the daemon's handler, that test failed and the run went on)."""

import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_sigterm_during_a_daemons_signal_handlers_stops_the_whole_run(tmp_path):
    marker = tmp_path / "second_test_ran"
    (tmp_path / "test_inner.py").write_text(textwrap.dedent(f"""
        import os, signal
        from uavloc_gcs.service.run import _signal_handlers

        def test_a_daemon_catches_sigterm():
            got = []
            with _signal_handlers(lambda s, f: got.append(s)):
                os.kill(os.getpid(), signal.SIGTERM)
            raise AssertionError("the run went on after SIGTERM")

        def test_later():
            open({str(marker)!r}, "w").close()
    """))
    # the suite's conftest as a plugin, on a test file of its own
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "tests.conftest", "-p", "no:cacheprovider",
                           str(tmp_path / "test_inner.py")], cwd=ROOT, capture_output=True, text=True, timeout=120)
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0, out
    assert "stopped by SIGTERM" in out, out
    assert not marker.exists(), "the test after the SIGTERM ran"
    assert "the run went on after SIGTERM" not in out
