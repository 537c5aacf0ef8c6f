"""``python -m benchmarks.scan_coverage``: which initial-scan lane spacing should be the default?

Flies the whole adaptive mission (``sim_link.experiments.missionsim.simulate_mission``: scan, MLE, EPSO
replanning, return) on the same simulated worlds (paired seeds) with the two scan layouts of
``uavloc_gcs.scan``:

- ``double``: lanes <= R apart, every point within R of two lanes (SPEC §3.1: a moving person
  seen from one straight leg is not observable);
- ``single``: the paper's coverage spacing (sqrt(2) R, spread evenly), every point within R of
  one lane.

Printed per layout: scan time, mission completion time (mean and 95 % CI), the paired difference
of completion times, the fraction of people located, the fraction located *within the required
accuracy* of the truth, the fraction whose truth lies outside the method's own claimed radius
(false confidence), and the median / worst final error. The default of ``scan.coverage`` is the
layout that is not slower and is more often right.
"""

from __future__ import annotations

from uavloc_gcs.cli._inputs import number
import argparse
import math
import time

import numpy as np

from ._progress import Progress



def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--runs", type=number(int, min=1), default=6, help="simulated worlds per layout (default 6; 20 for the README)")
    parser.add_argument("--seed", type=number(int, min=0), default=100, help="first world seed (default 100)")
    parser.add_argument("--scenario", default="paper",
                        help="scenario file, or a shipped one by name: paper, small (default paper)")
    parser.add_argument("--time-limit", type=number(float, above=0, unit="s"), default=0.3, help="planner time limit per replan, s (default 0.3)")


def run_layout(sc, coverage: str, seeds: list[int], time_limit_s: float, bar=None) -> list:
    from sim_link.experiments.missionsim import simulate_mission
    from sim_link.world import World

    scx = sc.replace(scan={"coverage": coverage})
    out = []
    for k, s in enumerate(seeds):
        out.append(simulate_mission(scx, World(scx, seed=s), seed=k, time_limit_s=time_limit_s))
        if bar is not None:
            bar.step(f"{coverage} world {k + 1}")
    return out


def summarize(results: list, required_accuracy_m: float) -> dict:
    from sim_link.experiments import mean_ci95

    persons = [p for r in results for p in r.persons]
    located = [p for p in persons if p.located]
    errors = np.array([p.error_m for p in located]) if located else np.zeros(0)
    return {
        "scan_s": float(np.mean([r.scan_time_s for r in results])),
        "mission": mean_ci95([r.completion_time_s for r in results]),
        "located": len(located) / max(len(persons), 1),
        "accurate": float(np.mean([p.located and p.error_m <= required_accuracy_m for p in persons])) if persons else 1.0,
        "false_conf": float(np.mean([p.error_m > p.claimed_radius_m for p in located])) if located else 0.0,
        "median_err": float(np.median(errors)) if len(errors) else math.nan,
        "worst_err": float(np.max(errors)) if len(errors) else math.nan,
    }


def main(args: argparse.Namespace) -> int:
    from sim_link.experiments import mean_ci95
    from uavloc_gcs.scan import plan_scan
    from uavloc_gcs.scenario import load_scenario

    from uavloc_gcs.examples import scenario_path

    sc = load_scenario(scenario_path(args.scenario))
    seeds = [args.seed + k for k in range(args.runs)]
    e_th = sc.people.required_accuracy_m
    print(f"scan layouts on '{sc.name}': {args.runs} paired worlds ({sc.simulation.people} people, "
          f"{sc.simulation.motion}), {sc.fleet.vehicles} vehicles, R = {sc.horizontal_range_m:.1f} m, "
          f"e_th = {e_th:g} m")
    head = (f"{'layout':7s} {'spacing m':>9s} {'scan s':>7s} {'mission s':>14s} {'located':>8s} "
            f"{'<= e_th':>8s} {'false conf':>10s} {'median err m':>12s} {'worst err m':>11s} {'cpu s':>6s}")
    print(head)
    print("-" * len(head))
    res = {}
    bar = Progress(2 * len(seeds))
    for cov in ("double", "single"):
        t0 = time.process_time()
        res[cov] = run_layout(sc, cov, seeds, args.time_limit, bar)
        s = summarize(res[cov], e_th)
        spacing = plan_scan(sc.replace(scan={"coverage": cov})).lane_spacing_m
        m, ci, _ = s["mission"]
        print(f"{cov:7s} {spacing:9.1f} {s['scan_s']:7.1f} {m:8.1f} ± {ci:4.1f} {s['located']:8.3f} "
              f"{s['accurate']:8.3f} {s['false_conf']:10.3f} {s['median_err']:12.1f} {s['worst_err']:11.1f} "
              f"{time.process_time() - t0:6.1f}")
    diff = [a.completion_time_s - b.completion_time_s for a, b in zip(res["double"], res["single"])]
    d, dci, n = mean_ci95(diff)
    print(f"\npaired mission time, double - single: {d:+.1f} ± {dci:.1f} s over {n} worlds "
          "(negative: double coverage finishes sooner)")
    return 0


if __name__ == "__main__":  # pragma: no cover
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_arguments(p)
    raise SystemExit(main(p.parse_args()))
