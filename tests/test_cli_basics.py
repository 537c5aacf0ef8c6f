import subprocess
import sys


def test_help_lists_commands():
    out = subprocess.run([sys.executable, "-m", "uavloc_gcs", "--help"], capture_output=True, text=True)
    assert out.returncode == 0
    assert "uavloc" in out.stdout


def test_no_command_is_an_error():
    out = subprocess.run([sys.executable, "-m", "uavloc_gcs"], capture_output=True, text=True)
    assert out.returncode == 2
