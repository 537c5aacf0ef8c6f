"""The paper's comparison (SPEC §2.4): MLE-EPSO (M/NM), MLE-PSO, MLE-GA and RL-NM on the same people.

One *task* is one mission: (method, number of people, run). All methods of one (people, run) pair
fly over the same :class:`World` (same seed: same people, same motion, same channel draws for the
same flight), under the same energy model and the same required accuracy. Tasks run in parallel
(``multiprocessing``), results are collected by key, so the output is the same for any ``jobs``.

Outputs (:func:`write_outputs`): ``runs.csv`` (one row per mission), ``fig_a_completion_time.csv``,
``fig_b_runtime.csv``, ``fig_c_error_vs_time.csv``, the three PNG figures and ``summary.md``.
Means come with 95 % confidence half-widths (Student t over runs).
"""

from __future__ import annotations

import csv
import io
import math
import multiprocessing
import os
from dataclasses import dataclass, field
from pathlib import Path
from collections.abc import Callable

import numpy as np

from uavloc_gcs.scenario import Scenario

from .missionsim import METHODS as MLE_METHODS
from .missionsim import MissionResult, simulate_mission
from .rl_baseline import METHOD as RL_METHOD
from .rl_baseline import simulate_rl
from ..world import World

ALL_METHODS = (*MLE_METHODS, RL_METHOD)
REFERENCE = "MLE-EPSO (M)"
PAPER_REDUCTION = 0.287  # completion-time reduction the paper reports against its comparison scheme
DEFAULT_PEOPLE = (5, 10, 15, 20, 25, 30, 35, 40, 45, 50)
ERROR_CURVE_STEP_S = 5.0


@dataclass(frozen=True)
class ExperimentConfig:
    scenario: Scenario
    people: tuple[int, ...] = DEFAULT_PEOPLE
    runs: int = 3
    seed: int = 0
    methods: tuple[str, ...] = ALL_METHODS
    iterations: int = 40  # planner iterations per replan (a long time limit keeps runs deterministic)
    planner_time_limit_s: float = 60.0
    error_people: int = 10  # figure (c)

    def __post_init__(self) -> None:
        bad = [m for m in self.methods if m not in ALL_METHODS]
        if bad:
            raise ValueError(f"unknown method {bad[0]!r}; expected one of {', '.join(ALL_METHODS)}")
        if self.runs < 1:
            raise ValueError(f"runs must be at least 1, got {self.runs}")
        if not self.people or min(self.people) < 1:
            raise ValueError(f"people counts must be positive, got {self.people}")


@dataclass(frozen=True)
class Task:
    method: str
    people: int
    run: int
    world_seed: int


@dataclass
class ExperimentResult:
    config: ExperimentConfig
    results: dict = field(default_factory=dict)  # (method, people, run) -> MissionResult

    def of(self, method: str, people: int) -> list[MissionResult]:
        return [self.results[k] for k in sorted(self.results) if k[0] == method and k[1] == people]


def world_seed(seed: int, people: int, run: int) -> int:
    """The World seed of one (people, run) pair, shared by every method."""
    return int(np.random.SeedSequence([seed, people, run]).generate_state(1)[0])


def make_tasks(cfg: ExperimentConfig) -> list[Task]:
    counts = sorted(set(cfg.people) | ({cfg.error_people} if cfg.error_people else set()))
    return [Task(m, n, r, world_seed(cfg.seed, n, r)) for n in counts for r in range(cfg.runs) for m in cfg.methods]


def run_task(cfg: ExperimentConfig, task: Task) -> MissionResult:
    """Fly one mission (a pure function of the config and the task)."""
    world = World(cfg.scenario, seed=task.world_seed, people=task.people)
    if task.method == RL_METHOD:
        return simulate_rl(cfg.scenario, world, seed=task.world_seed)
    return simulate_mission(cfg.scenario, world, task.method, seed=task.world_seed,
                            time_limit_s=cfg.planner_time_limit_s, max_iter=cfg.iterations,
                            oracle=task.method == REFERENCE)


def _worker(args):
    cfg, task = args
    return task, run_task(cfg, task)


def _quiet_worker() -> None:
    """Workers leave Ctrl-C to the parent (which stops them) and die silently when terminated:
    no "Process ForkPoolWorker-2:" traceback on the terminal."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def run_experiment(cfg: ExperimentConfig, *, jobs: int | None = None,
                   progress: Callable[[int, int, Task], None] | None = None) -> ExperimentResult:
    """Run every task, ``jobs`` in parallel (default: all cores). ``progress(done, total, task)``."""
    tasks = make_tasks(cfg)
    jobs = max(1, min(jobs or os.cpu_count() or 1, len(tasks)))
    order = sorted(tasks, key=lambda t: (-t.people, t.method == RL_METHOD, t.run))  # big ones first
    out = ExperimentResult(cfg)
    if jobs == 1:
        it = map(_worker, [(cfg, t) for t in order])
        pool = None
    else:
        pool = multiprocessing.get_context("fork").Pool(jobs, initializer=_quiet_worker)
        it = pool.imap_unordered(_worker, [(cfg, t) for t in order], chunksize=1)
    try:
        for k, (task, res) in enumerate(it, 1):
            out.results[(task.method, task.people, task.run)] = res
            if progress:
                progress(k, len(tasks), task)
        if pool is not None:
            pool.close()  # every task is done: the workers end on their own
    finally:
        if pool is not None:
            pool.terminate()
            pool.join()
    return out


# ---------------------------------------------------------------------------------------------
# Statistics


def mean_ci95(values) -> tuple[float, float, int]:
    """Mean, 95 % confidence half-width (Student t) and count of the finite values."""
    from scipy.stats import t as student

    v = np.asarray([x for x in values if x is not None and math.isfinite(x)], dtype=float)
    if len(v) == 0:
        return math.nan, math.nan, 0
    if len(v) == 1:
        return float(v[0]), math.nan, 1
    half = float(student.ppf(0.975, len(v) - 1) * v.std(ddof=1) / math.sqrt(len(v)))
    return float(v.mean()), half, len(v)


def error_curve(res: MissionResult, grid_s: np.ndarray) -> np.ndarray:
    """The mission's max-error history sampled on ``grid_s`` (held after the mission ends)."""
    t, e = res.error_times_s, res.max_error_m
    out = np.full(len(grid_s), math.nan)
    if len(t) == 0:
        return out
    idx = np.searchsorted(t, grid_s, side="right") - 1
    ok = idx >= 0
    out[ok] = e[idx[ok]]
    return out


def table_a(er: ExperimentResult) -> list[dict]:
    rows = []
    for m in er.config.methods:
        for n in sorted(er.config.people):
            runs = er.of(m, n)
            mean, ci, k = mean_ci95([r.completion_time_s for r in runs])
            loc, _, _ = mean_ci95([r.located_fraction for r in runs])
            err, _, _ = mean_ci95([r.max_final_error_m for r in runs])
            oracle, oracle_ci, _ = mean_ci95([r.oracle_completion_time_s for r in runs])
            heard = sum(p.heard for r in runs for p in r.persons)
            located = [p for r in runs for p in r.persons if p.located]
            rows.append({"method": m, "people": n, "runs": k, "completion_time_mean_s": mean,
                         "completion_time_ci95_s": ci, "located_fraction_mean": loc, "max_error_mean_m": err,
                         "located_of_heard": len(located) / heard if heard else math.nan,
                         "covered_of_located": (sum(p.error_m <= p.claimed_radius_m for p in located) / len(located)
                                                if located else math.nan),
                         "oracle_completion_time_mean_s": oracle, "oracle_completion_time_ci95_s": oracle_ci})
    return rows


def table_b(er: ExperimentResult) -> list[dict]:
    rows = []
    for m in er.config.methods:
        for n in sorted(er.config.people):
            runs = er.of(m, n)
            mean, ci, k = mean_ci95([r.planner_runtime_s for r in runs])
            est, est_ci, _ = mean_ci95([r.estimator_runtime_s for r in runs])
            rows.append({"method": m, "people": n, "runs": k, "runtime_mean_s": mean, "runtime_ci95_s": ci,
                         "estimator_runtime_mean_s": est, "estimator_runtime_ci95_s": est_ci})
    return rows


def table_c(er: ExperimentResult) -> list[dict]:
    n = er.config.error_people
    if not n:
        return []
    t_max = max((r.completion_time_s for k, r in er.results.items() if k[1] == n), default=0.0)
    grid = np.arange(0.0, t_max + ERROR_CURVE_STEP_S, ERROR_CURVE_STEP_S)
    rows = []
    for m in er.config.methods:
        curves = np.array([error_curve(r, grid) for r in er.of(m, n)])
        for j, t in enumerate(grid):
            mean, ci, k = mean_ci95(curves[:, j]) if len(curves) else (math.nan, math.nan, 0)
            rows.append({"method": m, "people": n, "t_s": float(t), "runs": k, "max_error_mean_m": mean,
                         "max_error_ci95_m": ci})
    return rows


def runs_table(er: ExperimentResult) -> list[dict]:
    rows = []
    for (m, n, r), res in sorted(er.results.items(), key=lambda kv: (kv[0][1], kv[0][2], kv[0][0])):
        rows.append({"method": m, "people": n, "run": r, "world_seed": world_seed(er.config.seed, n, r),
                     "completion_time_s": res.completion_time_s, "scan_time_s": res.scan_time_s,
                     "runtime_s": res.planner_runtime_s, "estimator_runtime_s": res.estimator_runtime_s,
                     "oracle_completion_time_s": res.oracle_completion_time_s,
                     "replans": res.replans, "located_fraction": res.located_fraction,
                     "max_error_m": res.max_final_error_m,
                     "mean_error_m": float(np.nanmean([p.error_m for p in res.persons])) if res.persons else 0.0,
                     "energy_max_j": max(res.energy_j) if res.energy_j else 0.0})
    return rows


def reductions(er: ExperimentResult) -> dict[str, tuple[float, list[float]]]:
    """Completion-time reduction of MLE-EPSO (M) against each other method: overall (ratio of the
    grand means over all people counts) and per people count."""
    out = {}
    if REFERENCE not in er.config.methods:
        return out
    counts = sorted(er.config.people)
    ref = [mean_ci95([r.completion_time_s for r in er.of(REFERENCE, n)])[0] for n in counts]
    for m in er.config.methods:
        if m == REFERENCE:
            continue
        other = [mean_ci95([r.completion_time_s for r in er.of(m, n)])[0] for n in counts]
        per = [1.0 - a / b if b > 0 else math.nan for a, b in zip(ref, other)]
        out[m] = (1.0 - float(np.nansum(ref)) / float(np.nansum(other)), per)
    return out


# ---------------------------------------------------------------------------------------------
# Output


def _csv(rows: list[dict]) -> str:
    buf = io.StringIO()
    if not rows:
        return ""
    w = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
    w.writeheader()
    for row in rows:
        w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in row.items()})
    return buf.getvalue()


def summary_text(er: ExperimentResult, command: str = "") -> str:
    cfg = er.config
    lines = ["# Paper experiment: summary", ""]
    if command:
        lines += [f"Command: `{command}`", ""]
    pl = cfg.scenario.planner
    onoff = {True: "on", False: "off"}
    lines += [f"Scenario `{cfg.scenario.name}`, {cfg.runs} run(s) per point, people {list(cfg.people)}, "
              f"seed {cfg.seed}, scan coverage `{cfg.scenario.scan.coverage}`, planner {cfg.iterations} "
              f"iterations per replan (local search {onoff[pl.local_search]}, warm start {onoff[pl.warm_start]}), "
              f"required accuracy {cfg.scenario.people.required_accuracy_m:g} m, "
              f"motion `{cfg.scenario.simulation.motion}`.", ""]
    lines += ["| method | people | completion time [s] | clairvoyant [s] | algorithm run time [s] | located | "
              "located of heard | in radius | max error [m] |",
              "|---|---|---|---|---|---|---|---|---|"]
    b = {(r["method"], r["people"]): r for r in table_b(er)}
    for r in table_a(er):
        rb = b[(r["method"], r["people"])]
        oracle = r["oracle_completion_time_mean_s"]
        lines.append(f"| {r['method']} | {r['people']} | {r['completion_time_mean_s']:.1f} ± "
                     f"{_ci(r['completion_time_ci95_s'])} | "
                     f"{'-' if not math.isfinite(oracle) else f'{oracle:.1f}'} | {rb['runtime_mean_s']:.2f} ± "
                     f"{_ci(rb['runtime_ci95_s'], 2)} | "
                     f"{100 * r['located_fraction_mean']:.0f} % | {_pct(r['located_of_heard'])} | "
                     f"{_pct(r['covered_of_located'])} | {r['max_error_mean_m']:.1f} |")
    lines += ["", f"Completion-time reduction of {REFERENCE} (the paper reports "
              f"{100 * PAPER_REDUCTION:.1f} % against its comparison scheme):", ""]
    for m, (overall, per) in reductions(er).items():
        per_txt = ", ".join(f"{n}: {100 * p:+.1f} %" for n, p in zip(sorted(cfg.people), per))
        lines.append(f"- vs {m}: {100 * overall:+.1f} % overall (per people count: {per_txt})")
    return "\n".join(lines) + "\n"


def _pct(x: float) -> str:
    return "-" if not math.isfinite(x) else f"{100 * x:.1f} %"


def _ci(x: float, digits: int = 1) -> str:
    return "n/a" if not math.isfinite(x) else f"{x:.{digits}f}"


def write_outputs(er: ExperimentResult, out_dir: Path, command: str = "") -> list[Path]:
    """CSV per figure, raw runs, PNG figures and summary.md into ``out_dir``."""
    from . import plots as experiment_plots

    out_dir = Path(out_dir)
    files = {
        "runs.csv": _csv(runs_table(er)),
        "fig_a_completion_time.csv": _csv(table_a(er)),
        "fig_b_runtime.csv": _csv(table_b(er)),
        "fig_c_error_vs_time.csv": _csv(table_c(er)),
        "summary.md": summary_text(er, command),
    }
    if not table_c(er):  # --error-people 0: no figure (c), so no empty CSV announcing one
        del files["fig_c_error_vs_time.csv"]
    written = []
    for name, text in files.items():
        (out_dir / name).write_text(text, encoding="utf-8")
        written.append(out_dir / name)
    written += experiment_plots.plot_all(table_a(er), table_b(er), table_c(er), out_dir,
                                         er.config.scenario.people.required_accuracy_m)
    return written
