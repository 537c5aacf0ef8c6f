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


def test_bench_help_lists_benchmarks_and_their_options():
    out = subprocess.run([sys.executable, "-m", "uavloc_gcs", "bench", "--help"], capture_output=True, text=True)
    assert out.returncode == 0 and "localize" in out.stdout and "plan" in out.stdout
    out = subprocess.run([sys.executable, "-m", "uavloc_gcs", "bench", "plan", "--help"], capture_output=True, text=True)
    assert out.returncode == 0 and "uavloc bench plan" in out.stdout
    out = subprocess.run([sys.executable, "-m", "uavloc_gcs", "bench", "nope"], capture_output=True, text=True)
    assert out.returncode == 2 and "invalid choice" in out.stderr


def test_bench_localize_runs_with_an_estimator_switch_and_names_it():
    cmd = [sys.executable, "-m", "uavloc_gcs", "bench", "localize", "--runs", "2", "--family", "two parallel, static, NM"]
    out = subprocess.run(cmd + ["--switch", "turn-mixture"], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "estimator switch turn-mixture: estimate.TURN_MIXTURE = True" in out.stdout
    assert "two parallel, static, NM" in out.stdout
    out = subprocess.run(cmd + ["--switch", "nope"], capture_output=True, text=True)
    assert out.returncode == 2 and "turn-mixture" in out.stderr
    out = subprocess.run(cmd + ["--maneuver-time", "0"], capture_output=True, text=True)
    assert out.returncode == 2 and "--maneuver-time must be a positive number of seconds, got 0.0" in out.stderr


def test_startup_does_not_load_the_simulator_or_scipy():
    code = ("import sys; from uavloc_gcs.cli import build_parser; build_parser(); "
            "print(sorted(m for m in ('sim_link.world', 'scipy.optimize', 'benchmarks.localize') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr


def test_every_bench_looks_variant_names_switches_that_exist():
    """A variant whose switch names no module attribute would silently run the default."""
    from benchmarks.looks import COMBINED, SWITCHES, VARIANTS, switch_modules

    modules = switch_modules()
    for name, (module, attr, value) in SWITCHES.items():
        assert hasattr(modules[module], attr), name
        assert getattr(modules[module], attr) != value, f"{name} is the shipped value"
    assert all(one in SWITCHES for parts in COMBINED.values() for one in parts)
    assert set(VARIANTS) == {"default", *SWITCHES, *COMBINED}
