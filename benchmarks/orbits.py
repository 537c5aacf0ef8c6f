"""Orbit looks against fly-by looks on the same worlds (issue 25 item 2).

    .venv/bin/python -m benchmarks.orbits [--runs 10] [--people 20] [--scenario field] [--look orbit,flyby]

Flies the MLE-EPSO (M) mission (``sim_link.experiments.missionsim``: scan, estimate, replan, look,
home) on paired worlds of the scenario, once with orbit looks (``search.orbit.ORBIT_LOOKS``, the
shipped behaviour in the burst world: a person heard gets a circle of the information radius for
long enough to catch 2 bursts with probability 0.5) and once with fly-by looks (the switch off:
pass-through looks, a person given up after two). Printed per look kind: people present, heard
and located, the located ones inside their own 95 % circle, the mission's completion time and the
fleet's energy (means with 95 % CIs), and the paired differences against fly-bys.
"""

from __future__ import annotations

import argparse
import math
import sys
from concurrent.futures import ProcessPoolExecutor

import numpy as np

LOOKS = ("orbit", "flyby")


def _fly(job):
    look, scenario_file, people, seed, run = job
    from sim_link.experiments.paper import REFERENCE, ExperimentConfig, Task, run_task, world_seed
    from uavloc_gcs.scenario import load_scenario
    from uavloc_gcs.search import orbit

    orbit.ORBIT_LOOKS = look == "orbit"
    cfg = ExperimentConfig(load_scenario(scenario_file), people=(people,), runs=run + 1, seed=seed,
                           methods=(REFERENCE,), error_people=0)
    res = run_task(cfg, Task(REFERENCE, people, run, world_seed(seed, people, run)))
    heard = [p for p in res.persons if p.heard]
    located = [p for p in heard if p.located]
    inside = [p for p in located if p.error_m <= p.claimed_radius_m]
    return (look, run, len(res.persons), len(heard), len(located), len(inside), res.completion_time_s,
            float(sum(res.energy_j)))


def main(argv=None) -> int:
    from sim_link.experiments import mean_ci95
    from uavloc_gcs.examples import scenario_path

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--people", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--scenario", default="field")
    ap.add_argument("--look", default="orbit,flyby", help="comma-separated of orbit, flyby")
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args(argv)
    looks = [x.strip() for x in a.look.split(",") if x.strip()]
    bad = [x for x in looks if x not in LOOKS]
    if bad or a.runs < 1 or a.people < 1:
        print(f"benchmarks.orbits: --look takes orbit and/or flyby (got {bad[0]!r})" if bad
              else "benchmarks.orbits: --runs and --people must be at least 1", file=sys.stderr)
        return 2
    scenario_file = str(scenario_path(a.scenario))
    jobs = [(look, scenario_file, a.people, a.seed, r) for r in range(a.runs) for look in looks]
    with ProcessPoolExecutor(max(1, a.jobs)) as pool:
        rows = list(pool.map(_fly, jobs))
    print(f"orbit vs fly-by looks on '{a.scenario}', MLE-EPSO (M), {a.people} people, {a.runs} paired worlds "
          f"(seed {a.seed})")
    head = (f"{'look':6s} {'heard/present':>14s} {'located/present':>16s} {'inside r95':>10s} "
            f"{'completion s':>16s} {'energy kJ':>16s} {'vs flyby s':>14s} {'vs flyby kJ':>14s}")
    print(head)
    print("-" * len(head))
    by = {x: sorted((r for r in rows if r[0] == x), key=lambda r: r[1]) for x in looks}
    for x in looks:
        rs = by[x]
        present, heard, located, inside = (sum(r[k] for r in rs) for k in (2, 3, 4, 5))
        t, tci, _ = mean_ci95([r[6] for r in rs])
        e, eci, _ = mean_ci95([r[7] / 1e3 for r in rs])
        dt = de = ""
        if x != "flyby" and "flyby" in by:
            d, dci, _ = mean_ci95([p[6] - q[6] for p, q in zip(rs, by["flyby"])])
            f, fci, _ = mean_ci95([(p[7] - q[7]) / 1e3 for p, q in zip(rs, by["flyby"])])
            dt, de = f"{d:+7.0f} ± {dci:4.0f}", f"{f:+7.0f} ± {fci:4.0f}"
        print(f"{x:6s} {heard:6d}/{present:<7d} {located:6d}/{present:<9d} {inside / max(located, 1):10.2f} "
              f"{t:8.0f} ± {tci:5.0f} {e:8.0f} ± {eci:5.0f} {dt:>14s} {de:>14s}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
