"""``uavloc bench [NAME [OPTIONS]]``: run benchmarks from the ``benchmarks`` package.

Each benchmark module ``benchmarks/<name>.py`` defines ``add_arguments(parser)`` and
``main(args) -> int``; it measures against its named anchors in the same run and prints ratios.
Benchmark modules are imported only when ``bench`` runs, so other commands start quickly.
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
    "looks": "look-planning rules on and off on paired worlds (located, inside radius, time vs clairvoyant)",
    "identity": "linking addresses into people vs truth (people reported, bursts on the wrong person, splits, merges)",
    "sense": "Wi-Fi and BLE capture parsers vs dpkt and scapy dissectors (frames/s on one core, fields agreeing)",
    "field": "the search for real phones vs the paper's plan, a lawnmower and the clairvoyant (located, time, energy, POD)",
    "demos": "uavloc demo run N times: people located and given up, the reasons, given up near the truth",
    "altitude": "what altitude costs and buys under the air-to-ground channel (hearing distance, share heard, range error)",
    "low_orbit": "one low orbit over a trapped phone of the field world: how long until its 95 % radius is small enough",
    "sorties": "the POD the scan planner reaches with 1, 2, 3 packs per vehicle and the time it needs, swaps included",
}


def _available() -> dict[str, str]:
    return {k: v for k, v in BENCHMARKS.items() if importlib.util.find_spec(f"benchmarks.{k}") is not None}


def register(sub: argparse._SubParsersAction) -> None:
    listing = "\n".join(f"  {k:<14} {v}" for k, v in BENCHMARKS.items())
    p = sub.add_parser(
        "bench",
        help="benchmarks against external anchors",
        description="Run a benchmark (or all of them, quick settings, when no NAME is given). "
        "'uavloc bench NAME --help' lists its options.",
        epilog="benchmarks:\n" + listing,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("benchmark", nargs="?", metavar="NAME", choices=list(BENCHMARKS), help="which benchmark")
    p.add_argument("options", nargs=argparse.REMAINDER, help="options of that benchmark")
    p.set_defaults(func=run)


def _parser_for(name: str, module) -> argparse.ArgumentParser:
    from . import _Parser  # one-sentence flag errors, as every command

    bp = _Parser(prog=f"uavloc bench {name}", description=BENCHMARKS[name])
    module.add_arguments(bp)
    return bp


def run(args: argparse.Namespace) -> int:
    names = [args.benchmark] if args.benchmark else list(_available())
    rc = 0
    for name in names:
        module = importlib.import_module(f"benchmarks.{name}")
        try:
            bargs = _parser_for(name, module).parse_args(args.options if args.benchmark else [])
        except SystemExit as done:  # --help, or a bad option (its sentence is printed)
            return done.code if isinstance(done.code, int) else 0
        if not args.benchmark:
            print(f"\n=== uavloc bench {name} ===", flush=True)
        rc = max(rc, int(module.main(bargs) or 0))
    return rc
