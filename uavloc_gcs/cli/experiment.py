"""``uavloc experiment paper``: reproduce the paper's comparison (figures, CSVs, summary).

    uavloc experiment paper --runs 20 --out results/paper [--jobs 4] [--people 5,10,20] [--seed 0]

Runs MLE-EPSO (M and NM), MLE-PSO, MLE-GA and RL-NM over the same simulated people, in parallel,
deterministically per seed; writes ``runs.csv``, one CSV and one PNG per figure and
``summary.md`` (all-or-nothing) and prints the summary.
"""

from __future__ import annotations

import argparse
import shlex
import sys
import time
from pathlib import Path

from ..errors import ConfigError

from ._inputs import number

DEFAULT_SCENARIO = "paper"  # the shipped examples/paper.toml (uavloc_gcs.examples)


def _int_list(text: str) -> tuple[int, ...]:
    try:
        values = tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated whole numbers, got {text!r}") from None
    if values and max(values) > 1000:
        raise argparse.ArgumentTypeError(f"people counts above 1000 are not simulated, got {max(values)}")
    if not values or min(values) < 1:
        raise argparse.ArgumentTypeError(f"people counts must be positive whole numbers, got {text!r}")
    return values


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("experiment", help="reproduce the paper's comparison (figures + CSV)",
                       description="Reproduce the paper's experiments in the fast in-process simulator.")
    esub = p.add_subparsers(dest="experiment", metavar="NAME")
    pp = esub.add_parser("paper", help="MLE-EPSO vs PSO, GA and RL-NM, 5 to 50 people",
                         description="Figures (a) completion time, (b) run time vs people, (c) maximum "
                                     "error vs time for 10 people, with 95 % confidence intervals.")
    pp.add_argument("--runs", type=number(int, min=1), default=3, help="runs (random worlds) per point (default 3)")
    pp.add_argument("--out", default="results/paper", help="output directory (default results/paper)")
    pp.add_argument("--jobs", type=number(int, min=1, max=256), default=None, help="parallel processes (default: all cores)")
    pp.add_argument("--people", type=_int_list, default=None,
                    help="comma-separated people counts (default 5,10,...,50)")
    pp.add_argument("--seed", type=number(int, min=0), default=0, help="experiment seed (default 0)")
    pp.add_argument("--methods", default=None,
                    help="comma-separated subset of: MLE-EPSO (M), MLE-EPSO (NM), MLE-PSO, MLE-GA, RL-NM")
    pp.add_argument("--iterations", type=number(int, min=1, max=100000), default=40, help="planner iterations per replan (default 40)")
    pp.add_argument("--error-people", type=number(int, min=0, max=1000), default=10,
                    help="people in figure (c) (default 10; 0 to skip)")
    pp.add_argument("--scenario", default=DEFAULT_SCENARIO,
                    help="scenario TOML, or a shipped one by name: paper, small (default: paper)")
    pp.add_argument("--plain", action="store_true",
                    help="the paper's plain optimizers: no local search, no warm start (default: both on, "
                         "as the scenario says)")
    pp.add_argument("--coverage", choices=("single", "double"), default=None,
                    help="override the scan coverage (the paper's grid is 'single'; default: the scenario's)")
    pp.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    pp.set_defaults(func=run)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])


class _Bar:
    """A one-line progress bar on stderr."""

    def __init__(self, enabled: bool):
        self.enabled = enabled
        self.t0 = time.monotonic()

    def __call__(self, done: int, total: int, task) -> None:
        if not self.enabled:
            return
        width = 30
        fill = int(width * done / total)
        el = time.monotonic() - self.t0
        eta = el / done * (total - done) if done else 0.0
        sys.stderr.write(f"\r[{'#' * fill}{'.' * (width - fill)}] {done}/{total} "
                         f"{task.method} n={task.people} run {task.run}  {el:.0f} s, ~{eta:.0f} s left   ")
        if done == total:
            sys.stderr.write("\n")
        sys.stderr.flush()


def run(args: argparse.Namespace) -> int:
    from sim_link.experiments import (
        ALL_METHODS,
        DEFAULT_PEOPLE,
        ExperimentConfig,
        run_experiment,
        summary_text,
        write_outputs,
    )

    from ..examples import scenario_path
    from ..scenario import load_scenario
    from ._inputs import override
    from ._output import atomic_output_dir, check_output_dir

    check_output_dir(args.out, "--out")  # before the runs: a directory that cannot be written
    if args.runs < 1:
        raise ConfigError(f"--runs must be at least 1, got {args.runs}")
    if args.jobs is not None and args.jobs < 1:
        raise ConfigError(f"--jobs must be at least 1, got {args.jobs}")
    if args.iterations < 1:
        raise ConfigError(f"--iterations must be at least 1, got {args.iterations}")
    methods = ALL_METHODS
    if args.methods is not None:
        methods = tuple(m.strip() for m in args.methods.split(",") if m.strip())
        if not methods:  # ran nothing and wrote empty figures
            raise ConfigError(f"--methods {args.methods!r} names no method; choose from {', '.join(ALL_METHODS)}")
        bad = [m for m in methods if m not in ALL_METHODS]
        if bad:
            raise ConfigError(f"--methods: unknown method {bad[0]!r}; choose from {', '.join(ALL_METHODS)}")
    sc = load_scenario(scenario_path(args.scenario))
    if args.coverage:
        sc = override(sc, "--coverage", scan={"coverage": args.coverage})
    if args.plain:
        sc = sc.replace(planner={"local_search": False, "warm_start": False})
    cfg = ExperimentConfig(sc, people=args.people or DEFAULT_PEOPLE, runs=args.runs, seed=args.seed,
                           methods=methods, iterations=args.iterations, error_people=max(0, args.error_people))
    command = "uavloc experiment paper " + " ".join(shlex.quote(a) for a in sys.argv[3:]) if len(sys.argv) > 3 else \
        "uavloc experiment paper"
    result = run_experiment(cfg, jobs=args.jobs, progress=_Bar(not args.no_progress))
    with atomic_output_dir(args.out) as tmp:
        written = [Path(p).name for p in write_outputs(result, tmp, command)]
    print(summary_text(result, command))
    print(f"wrote {Path(args.out)}/: {', '.join(written)}")
    return 0
