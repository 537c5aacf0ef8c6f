"""The coverage loop in the in-process simulator: missions with and without the passes over cells
below the POD target (uavloc_gcs/search/coverage.py), on the end-to-end tests' small scenario
(400 m x 250 m, 2 vehicles at 60 m, 15 m/s, 3 static people) in the paper world and in the field
world (probe bursts, receiver threshold).

    python -m benchmarks.coverage_loop [--seeds 1,2,3]

Prints, per world and mode, the mean completion time, people located/heard, achieved POD (the
accumulator's, over the area), pass rounds and energy.
"""

from __future__ import annotations

import argparse

import numpy as np


def main(argv=None) -> int:
    from sim_link.experiments.missionsim import simulate_mission
    from sim_link.world import World
    from tests.e2e_helpers import FIELD, small_scenario

    ap = argparse.ArgumentParser(prog="python -m benchmarks.coverage_loop")
    ap.add_argument("--seeds", default="1,2,3")
    args = ap.parse_args(argv)
    seeds = [int(s) for s in args.seeds.split(",")]
    print("world  passes  done [s]  located/heard  POD   rounds  energy [kJ]")
    for world, extra in (("paper", ""), ("field", FIELD)):
        for cov in (False, True):
            rows = []
            for seed in seeds:
                sc = small_scenario(seed=seed, extra=extra)
                r = simulate_mission(sc, World(sc, seed=seed), seed=seed, time_limit_s=0.2, max_iter=30,
                                     coverage=cov)
                rows.append((r.completion_time_s, sum(p.located for p in r.persons), sum(p.heard for p in r.persons),
                             r.pod_overall, r.pass_rounds, sum(r.energy_j) / 1e3))
            a = np.array(rows, float)
            m = a.mean(axis=0)
            pod = "-" if not cov else f"{m[3]:.2f}"
            print(f"{world:<6} {'on' if cov else 'off':<7} {m[0]:8.0f}  {m[1]:4.1f}/{m[2]:.1f}        {pod:<5} "
                  f"{m[4]:6.1f}  {m[5]:8.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
