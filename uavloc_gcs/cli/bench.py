"""``uavloc bench [NAME ...]``: run benchmarks from the ``benchmarks`` package.

Each benchmark module ``benchmarks/<name>.py`` defines ``add_arguments(parser)`` and
``main(args) -> int``; it measures against its named anchors in the same run and prints ratios.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util

BENCHMARKS = {
    "localize": "estimator vs the Bayesian Cramér-Rao bound (RMSE ratio, 95 % coverage, solve time)",
    "plan": "route planner vs OR-Tools, PyVRP and the lower bound (makespan ratios, runtimes)",
    "link": "mission upload vs MAVSDK, replanning latency, RSSI ingestion rate",
    "scan_coverage": "full adaptive mission with double vs single lane coverage (time, accuracy)",
}


def _available() -> dict[str, str]:
    return {k: v for k, v in BENCHMARKS.items() if importlib.util.find_spec(f"benchmarks.{k}") is not None}


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "bench",
        help="benchmarks against external anchors",
        description="Run benchmarks. "
        + "; ".join(f"{k}: {v}" for k, v in BENCHMARKS.items()).replace("%", "%%"),
    )
    bsub = p.add_subparsers(dest="benchmark", metavar="NAME")
    for name, text in _available().items():
        safe = text.replace("%", "%%")  # argparse %-formats help strings
        bp = bsub.add_parser(name, help=safe, description=safe)
        importlib.import_module(f"benchmarks.{name}").add_arguments(bp)
        bp.set_defaults(func=_runner(name))
    p.set_defaults(func=_run_all)


def _runner(name: str):
    def run(args: argparse.Namespace) -> int:
        return int(importlib.import_module(f"benchmarks.{name}").main(args) or 0)

    return run


def _run_all(args: argparse.Namespace) -> int:
    """``uavloc bench`` with no name: every benchmark with its default (quick) settings."""
    rc = 0
    for name in _available():
        mod = importlib.import_module(f"benchmarks.{name}")
        parser = argparse.ArgumentParser()
        mod.add_arguments(parser)
        print(f"\n=== uavloc bench {name} ===")
        rc = max(rc, int(mod.main(parser.parse_args([])) or 0))
    return rc
