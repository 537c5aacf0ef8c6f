"""The paper experiment harness: a tiny run end to end, determinism, statistics."""

import csv
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sim_link.experiments import (
    ALL_METHODS,
    ExperimentConfig,
    make_tasks,
    mean_ci95,
    reductions,
    run_experiment,
    world_seed,
)
from uavloc_gcs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
SMALL = ROOT / "examples" / "small.toml"


def test_mean_ci95_matches_student_t():
    mean, half, n = mean_ci95([1.0, 2.0, 3.0, float("nan")])
    assert (mean, n) == (2.0, 3)
    assert half == pytest.approx(4.302653 * 1.0 / math.sqrt(3), rel=1e-5)
    assert math.isnan(mean_ci95([5.0])[1]) and mean_ci95([])[2] == 0


def test_every_method_flies_over_the_same_people():
    cfg = ExperimentConfig(load_scenario(SMALL), people=(2, 4), runs=2, seed=3, error_people=0)
    tasks = make_tasks(cfg)
    assert len(tasks) == 2 * 2 * len(ALL_METHODS)
    for n in (2, 4):
        for r in range(2):
            seeds = {t.world_seed for t in tasks if t.people == n and t.run == r}
            assert seeds == {world_seed(3, n, r)}
    assert world_seed(3, 2, 0) != world_seed(3, 2, 1) != world_seed(4, 2, 1)


def test_results_do_not_depend_on_the_number_of_jobs():
    cfg = ExperimentConfig(load_scenario(SMALL), people=(2,), runs=1, seed=1, iterations=5, error_people=0,
                           methods=("MLE-EPSO (M)", "MLE-GA", "RL-NM"))
    a = run_experiment(cfg, jobs=1)
    b = run_experiment(cfg, jobs=2)
    assert sorted(a.results) == sorted(b.results)
    for k in a.results:
        ra, rb = a.results[k], b.results[k]
        assert ra.completion_time_s == rb.completion_time_s
        assert [p.error_m for p in ra.persons] == pytest.approx([p.error_m for p in rb.persons], nan_ok=True)
    red = reductions(a)
    assert set(red) == {"MLE-GA", "RL-NM"}


@pytest.mark.slow
def test_cli_tiny_run_end_to_end(tmp_path):
    out = tmp_path / "paper"
    proc = subprocess.run(
        [sys.executable, "-m", "uavloc_gcs", "experiment", "paper", "--runs", "2", "--people", "2,3",
         "--error-people", "2", "--iterations", "5", "--jobs", "2", "--seed", "5", "--scenario", str(SMALL),
         "--out", str(out)],
        capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "Completion-time reduction of MLE-EPSO (M)" in proc.stdout
    assert "2/" in proc.stderr or "[" in proc.stderr  # the progress bar
    for name in ("runs.csv", "fig_a_completion_time.csv", "fig_b_runtime.csv", "fig_c_error_vs_time.csv",
                 "summary.md", "fig_a_completion_time.png", "fig_b_runtime.png", "fig_c_error_vs_time.png"):
        assert (out / name).stat().st_size > 0, name
    assert (out / "fig_a_completion_time.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    runs = list(csv.DictReader((out / "runs.csv").open()))
    assert len(runs) == 2 * 2 * len(ALL_METHODS)
    assert {r["method"] for r in runs} == set(ALL_METHODS)
    for r in runs:
        assert float(r["completion_time_s"]) > 0
        assert 0.0 <= float(r["located_fraction"]) <= 1.0
    fig_a = list(csv.DictReader((out / "fig_a_completion_time.csv").open()))
    assert len(fig_a) == 2 * len(ALL_METHODS)
    mean = np.mean([float(r["completion_time_s"]) for r in runs if r["method"] == "MLE-GA" and r["people"] == "3"])
    row = next(r for r in fig_a if r["method"] == "MLE-GA" and r["people"] == "3")
    assert float(row["completion_time_mean_s"]) == pytest.approx(mean, rel=1e-5)
    # the clairvoyant yardstick: computed for the reference method only, never later than it
    for r in runs:
        oracle = float(r["oracle_completion_time_s"] or "nan")
        if r["method"] == "MLE-EPSO (M)":
            assert float(r["scan_time_s"]) < oracle <= float(r["completion_time_s"]) + 1e-6
        else:
            assert math.isnan(oracle)
    assert "clairvoyant [s]" in (out / "summary.md").read_text()


def test_cli_rejects_bad_arguments(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "uavloc_gcs", "experiment", "paper", "--methods", "MLE-XYZ",
                           "--out", str(tmp_path / "x")], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert proc.returncode == 2 and "MLE-XYZ" in proc.stderr
    assert not (tmp_path / "x").exists()
