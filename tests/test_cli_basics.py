import subprocess
import sys


def test_help_lists_commands():
    out = subprocess.run([sys.executable, "-m", "uavloc_gcs", "--help"], capture_output=True, text=True)
    assert out.returncode == 0
    assert "uavloc" in out.stdout


def test_no_command_is_an_error():
    out = subprocess.run([sys.executable, "-m", "uavloc_gcs"], capture_output=True, text=True)
    assert out.returncode == 2


def test_every_command_has_working_help():
    from uavloc_gcs.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    assert {"plan", "preview", "localize", "route", "sim", "demo", "daemon", "bench"} <= set(sub.choices)
    for name, p in sub.choices.items():
        assert p.format_help(), name
        nested = [a for a in p._actions if a.__class__.__name__ == "_SubParsersAction"]
        for action in nested:
            for subname, subp in action.choices.items():
                assert subp.format_help(), f"{name} {subname}"
