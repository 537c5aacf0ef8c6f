"""uavloc installs like a tool: a wheel built from this tree, installed (non-editable) into a
throwaway virtual environment, runs ``--version``, ``demo``, ``experiment`` and every ``bench``
from a directory that is not the checkout; the shipped examples are the repository's."""

import filecmp
import os
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_the_shipped_examples_are_the_repository_examples():
    shipped = ROOT / "uavloc_gcs" / "examples"
    repo = sorted(p.name for p in (ROOT / "examples").iterdir() if p.is_file())
    missing = [n for n in repo if not (shipped / n).is_file()]
    assert not missing, f"copy {missing} from examples/ into uavloc_gcs/examples/ (they ship with the package)"
    different = [n for n in repo if not filecmp.cmp(ROOT / "examples" / n, shipped / n, shallow=False)]
    assert not different, f"examples/ and uavloc_gcs/examples/ differ in {different}; keep them identical"


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """A venv holding only the uavloc wheel; its dependencies come from this interpreter's
    site-packages through a .pth file (no download, and no editable uavloc on the path)."""
    base = tmp_path_factory.mktemp("pkg")
    build = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(base / "dist"),
                            str(ROOT)], capture_output=True, text=True, timeout=300)
    if build.returncode != 0 and "setuptools" in build.stderr and "No matching distribution" in build.stderr:
        pytest.skip("pip cannot fetch the build backend (setuptools>=68, wheel): no package index here")
    assert build.returncode == 0, build.stderr[-3000:]
    wheel, = (base / "dist").glob("uavloc-*.whl")
    venv = base / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True, timeout=120)
    py = venv / "bin" / "python"
    clean = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    subprocess.run([sys.executable, "-m", "pip", "--python", str(py), "install", "-q", "--no-deps",
                    "--ignore-installed", str(wheel)], check=True, timeout=300, env=clean)
    site = Path(subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                               capture_output=True, text=True, check=True).stdout.strip())
    (site / "zz_shared_deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    elsewhere = base / "elsewhere"
    elsewhere.mkdir()
    return venv / "bin" / "uavloc", elsewhere


def _run(installed, *args, timeout=300):
    exe, cwd = installed
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    r = subprocess.run([str(exe), *args], capture_output=True, text=True, cwd=cwd, env=env, timeout=timeout)
    assert r.returncode == 0, (args, r.stdout[-2000:], r.stderr[-3000:])
    return r


def test_the_installed_tool_is_not_this_checkout(installed):
    exe, cwd = installed
    r = subprocess.run([str(exe.parent / "python"), "-c", "import uavloc_gcs; print(uavloc_gcs.__file__)"],
                       capture_output=True, text=True, cwd=cwd, env={"PATH": "/usr/bin:/bin"}, check=True)
    assert "site-packages" in r.stdout and str(ROOT) not in r.stdout, r.stdout
    assert _run(installed, "--version").stdout.strip() == "uavloc 0.1.0"


@pytest.mark.slow
def test_demo_and_experiment_run_from_anywhere(installed):
    r = _run(installed, "demo", "--scenario", "small", "--people", "1", "--speedup", "40", "--base-port", "0",
             "--out", "demo")
    assert "All vehicles are home" in r.stdout or "returning home" in r.stdout, r.stdout[-1500:]
    assert (installed[1] / "demo" / "people.csv").is_file()
    r = _run(installed, "demo", "--help")
    assert "default: field" in r.stdout  # the shipped field scenario is found by name
    _run(installed, "experiment", "paper", "--runs", "1", "--people", "5", "--methods", "MLE-EPSO (M)",
         "--error-people", "0", "--iterations", "5", "--jobs", "1", "--no-progress", "--out", "exp")
    assert (installed[1] / "exp" / "runs.csv").is_file()


@pytest.mark.parametrize("bench", [
    ["localize", "--runs", "1", "--family", "crossing, static"],
    ["plan", "--families", "mtsp", "--size", "5", "--seeds", "1", "--time-limit", "0.1", "--no-anchors",
     "--no-baselines"],
    ["scan_coverage", "--runs", "1", "--scenario", "small", "--time-limit", "0.1"],
    ["looks", "--runs", "1", "--scenario", "small", "--people", "2", "--variants", "default,no-inside-cut", "--jobs", "1"],
    ["link", "--no-mavsdk", "--runs-clean", "1", "--loss", "0", "--items", "20", "--no-service"],
])
@pytest.mark.slow
def test_every_bench_runs_from_anywhere(installed, bench):
    r = _run(installed, "bench", *bench)
    assert "done in" in r.stderr, r.stderr[-1000:]  # the progress report
    assert "--scenario" in _run(installed, "bench", bench[0], "--help").stdout


@pytest.mark.slow
def test_every_command_finds_the_shipped_files_by_name(installed):
    """Issue 29 item 4: plan, localize, route and sim know the shipped scenarios and route file by
    name from any directory, as demo, bench and experiment do."""
    import signal
    import time

    exe, cwd = installed
    _run(installed, "plan", "small", "--out", "p1")
    _run(installed, "plan", "paper.toml", "--out", "p2")
    assert (cwd / "p1" / "uav1.plan").is_file() and (cwd / "p2" / "uav4.plan").is_file()
    # issue 40: the shipped slots by name too (was: only by their full path inside the package)
    r = _run(installed, "localize", "slots_small.csv", "--scenario", "small", "--out", "loc")
    assert (cwd / "loc" / "estimates.csv").is_file(), r.stdout
    _run(installed, "route", "route_paper.json", "--time-limit", "0.1", "--out", "r.json")
    _run(installed, "route", "route_paper", "--time-limit", "0.1", "--out", "r2.json")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    sim = subprocess.Popen([str(exe), "sim", "small", "--base-port", "0", "--status-s", "0"], cwd=cwd, env=env,
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = sim.stdout.readline()  # the first line names the vehicles: the scenario was found
        assert "not found" not in line and line.strip(), (line, sim.stderr.read() if sim.poll() is not None else "")
        time.sleep(0.5)
        assert sim.poll() is None
    finally:
        sim.send_signal(signal.SIGINT)
        sim.wait(timeout=60)
    r = subprocess.run([str(exe), "plan", "no-such-scenario", "--out", "p3"], capture_output=True, text=True,
                       cwd=cwd, env=env, timeout=300)
    assert r.returncode == 2 and "shipped scenarios, usable by name: " in r.stderr and "small" in r.stderr
