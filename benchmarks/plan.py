"""``uavloc bench plan``: the route planner against OR-Tools, PyVRP and the lower bound.

Instances are generated in the run (seeded): 4 vehicles in the paper's 1120 m x 640 m area,
families

* ``paper``: vehicles start where the scan left them (random in the area), home at the launch
  corner, 5-50 people, access radii 20-80 m;
* ``clustered``: 30 people in 4 groups (sigma 60 m), radii 20-80 m, all start at the launch;
* ``uniform``: 30 people uniform, radii 20-80 m, all start at the launch;
* ``mtsp``: 30 people, radius 0, start = home = launch (classic min-max mTSP);
* ``moving``: 30 people walking at 1.5 m/s in random directions, radii 20-80 m.

Per instance: EPSO with local search, OR-Tools and PyVRP at the same time budget (the anchors on
the disk centres, then the same edge-access refinement), the lower bound, and the paper's plain
EPSO, PSO and GA (no local search, no seeding) at the same budget. Printed per family: geometric
means of the makespan ratios (and the worst instance), and mean runtimes.
"""

from __future__ import annotations

from uavloc_gcs.cli._inputs import choice_list, number, number_list
import argparse
import math
import time

import numpy as np

from uavloc_gcs.planning import RoutingProblem, Target, VehicleState, lower_bound_s, solve

from ._progress import Progress

AREA_M = (1120.0, 640.0)
FAMILIES = ("paper", "clustered", "uniform", "mtsp", "moving")
ENERGY_J = 250e3  # generous: ~25 km at 25 m/s; the energy constraint is tested elsewhere


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--families", type=choice_list(FAMILIES), default=",".join(FAMILIES),
                        help=f"comma-separated subset of {', '.join(FAMILIES)}")
    parser.add_argument("--paper-sizes", type=number_list(int, min=1, max=2000), default="10,20,50",
                        help="people per paper-like instance (default 10,20,50; the paper used 5-50)")
    parser.add_argument("--size", type=number(int, min=1, max=2000), default=30, help="people in the other families (default 30)")
    parser.add_argument("--seeds", type=number(int, min=1), default=2, help="instances per family and size (default 2)")
    parser.add_argument("--time-limit", type=number(float, above=0, unit="s"), default=1.0, help="budget per solver run [s] (default 1)")
    parser.add_argument("--vehicles", type=number(int, min=1, max=64), help="vehicles (default 4, or the scenario's)")
    parser.add_argument("--scenario", metavar="FILE.toml",
                        help="take area size, vehicles and speed from this scenario (or a shipped one: "
                             "paper, small); default: the paper's 1120 m x 640 m, 4 vehicles, 25 m/s")
    parser.add_argument("--no-anchors", action="store_true", help="skip OR-Tools and PyVRP")
    parser.add_argument("--no-baselines", action="store_true", help="skip plain EPSO/PSO/GA")
    parser.add_argument("--plain-iters", type=number(int, min=0), default=0, metavar="N",
                        help="run the plain EPSO/PSO/GA for N iterations of 40 particles (equal evaluation "
                             "counts, as in the paper) instead of the time budget")
    parser.add_argument("--verbose", action="store_true", help="one line per instance")


def make_instance(family: str, n: int, m: int, seed: int, area_m=AREA_M, speed_m_s: float = 25.0,
                  energy_j: float = ENERGY_J) -> RoutingProblem:
    rng = np.random.default_rng([FAMILIES.index(family), n, seed])
    w, h = area_m
    launch = (0.0, 0.0)
    radii = rng.uniform(20.0, 80.0, n)
    vel = np.zeros((n, 2))
    starts = np.zeros((m, 2))
    if family == "paper":
        xy = rng.uniform((0, 0), (w, h), (n, 2))
        starts = rng.uniform((0, 0), (w, h), (m, 2))
    elif family == "clustered":
        centres = rng.uniform((150, 150), (w - 150, h - 150), (4, 2))
        xy = centres[rng.integers(0, 4, n)] + rng.normal(0, 60.0, (n, 2))
    elif family == "uniform":
        xy = rng.uniform((0, 0), (w, h), (n, 2))
    elif family == "mtsp":
        xy = rng.uniform((0, 0), (w, h), (n, 2))
        radii[:] = 0.0
    elif family == "moving":
        xy = rng.uniform((0, 0), (w, h), (n, 2))
        ang = rng.uniform(0, 2 * np.pi, n)
        vel = 1.5 * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    else:
        raise ValueError(f"unknown family {family!r}")
    vehicles = tuple(VehicleState(f"uav{k + 1}", (float(starts[k, 0]), float(starts[k, 1])), launch, energy_j)
                     for k in range(m))
    targets = tuple(Target(f"p{i + 1}", (float(xy[i, 0]), float(xy[i, 1])),
                           (float(vel[i, 0]), float(vel[i, 1])), float(radii[i])) for i in range(n))
    return RoutingProblem(vehicles, targets, float(speed_m_s))


def _gmean(x) -> float:
    x = [v for v in x if v is not None and math.isfinite(v)]
    return float(np.exp(np.mean(np.log(x)))) if x else float("nan")


def _run_instance(p: RoutingProblem, args, seed: int) -> dict:
    T = args.time_limit
    row: dict[str, float] = {"lb": lower_bound_s(p)}
    runs = [("epso", "epso", True)]
    if not args.no_anchors:
        runs += [("ortools", "ortools", True), ("pyvrp", "pyvrp", True)]
    if not args.no_baselines:
        runs += [("epso_plain", "epso", False), ("pso_plain", "pso", False), ("ga_plain", "ga", False)]
    for name, method, ls in runs:
        t = time.perf_counter()
        c = time.process_time()
        if not ls and args.plain_iters:
            res = solve(p, method=method, rng=seed, time_limit_s=1e6, max_iter=args.plain_iters,
                        local_search=False)
        else:
            res = solve(p, method=method, rng=seed, time_limit_s=T, local_search=ls)
        row[name] = res.fun if res.success else float("inf")
        row[name + "_t"] = time.perf_counter() - t
        row[name + "_cpu"] = time.process_time() - c
    return row


def _world(args: argparse.Namespace):
    """(area (w, h) [m], vehicles, speed [m/s], energy [J]) from --scenario, else the paper's."""
    if not args.scenario:
        return AREA_M, args.vehicles or 4, 25.0, ENERGY_J
    from uavloc_gcs.examples import scenario_path
    from uavloc_gcs.scenario import load_scenario

    sc = load_scenario(scenario_path(args.scenario))
    xy = np.asarray(sc.area_xy_m())
    area = tuple(float(v) for v in np.ptp(xy, axis=0))
    return area, args.vehicles or sc.fleet.vehicles, sc.fleet.speed_m_s, max(ENERGY_J, sc.fleet.energy_budget_j)


def main(args: argparse.Namespace) -> int:
    families = list(args.families)
    sizes = list(args.paper_sizes)
    plain = (f"{args.plain_iters} iterations x 40" if args.plain_iters else f"{args.time_limit:g} s")
    area, args.vehicles, speed, energy = _world(args)
    print(f"uavloc bench plan: {args.vehicles} vehicles at {speed:g} m/s, area {area[0]:.0f} m x {area[1]:.0f} m, "
          f"budget {args.time_limit:g} s per solver run (plain EPSO/PSO/GA: {plain}), {args.seeds} seed(s)")
    bar = Progress(sum(len(sizes) if f == "paper" else 1 for f in families) * args.seeds)
    t_all = time.perf_counter()
    table = []
    for fam in families:
        rows = []
        ns = sizes if fam == "paper" else [args.size]
        for n in ns:
            for seed in range(args.seeds):
                p = make_instance(fam, n, args.vehicles, seed, area, speed, energy)
                row = _run_instance(p, args, seed)
                bar.step(f"{fam} n={n} seed={seed}")
                row["n"] = n
                rows.append(row)
                if args.verbose:
                    print(f"  {fam:9s} n={n:3d} seed={seed}: " + ", ".join(
                        f"{k}={v:.2f}" for k, v in row.items() if not k.endswith(("_t", "_cpu")) and k != "n"),
                        flush=True)
        table.append((fam, ns, rows))

    def ratio(rows, a, b):
        vals = [r[a] / r[b] for r in rows if a in r and b in r and r[b] > 0]
        return _gmean(vals), (max(vals) if vals else float("nan"))

    print()
    hdr = (f"{'family':10s} {'n':>9s} {'inst':>4s} | {'EPSO/ORT':>15s} {'EPSO/PyVRP':>15s} {'EPSO/LB':>7s} | "
           f"{'plain EPSO/PSO':>14s} {'plain EPSO/GA':>13s} | {'t EPSO':>6s} {'t ORT':>6s} {'t PyVRP':>7s}")
    print(hdr)
    print("-" * len(hdr))
    plain_t = []
    for fam, ns, rows in table:
        o, omax = ratio(rows, "epso", "ortools")
        v, vmax = ratio(rows, "epso", "pyvrp")
        lb, _ = ratio(rows, "epso", "lb")
        pp, _ = ratio(rows, "epso_plain", "pso_plain")
        pg, _ = ratio(rows, "epso_plain", "ga_plain")
        t = {k: np.mean([r[k] for r in rows]) if rows and k in rows[0] else float("nan")
             for k in ("epso_t", "ortools_t", "pyvrp_t", "epso_plain_t", "pso_plain_t", "ga_plain_t")}
        plain_t.append(t)
        nstr = ",".join(map(str, ns))
        print(f"{fam:10s} {nstr:>9s} {len(rows):4d} | {o:6.3f} (max {omax:5.3f}) {v:6.3f} (max {vmax:5.3f}) "
              f"{lb:7.3f} | {pp:14.3f} {pg:13.3f} | {t['epso_t']:6.2f} {t['ortools_t']:6.2f} {t['pyvrp_t']:7.2f}")
    if not args.no_baselines and plain_t:
        print("plain runtimes [s] (EPSO/PSO/GA): " + "; ".join(
            f"{fam} {t['epso_plain_t']:.2f}/{t['pso_plain_t']:.2f}/{t['ga_plain_t']:.2f}"
            for (fam, _, _), t in zip(table, plain_t)))
    big = [r for _, _, rows in table for r in rows if r["n"] >= 50]
    if big:
        print(f"\nEPSO runtime at 50 people / {args.vehicles} vehicles: max {max(r['epso_t'] for r in big):.2f} s "
              f"wall, {max(r['epso_cpu'] for r in big):.2f} s CPU (budget {args.time_limit:g} s, one thread)")
    print(f"ratios are geometric means over instances (< 1: EPSO better); total {time.perf_counter() - t_all:.0f} s")
    return 0


if __name__ == "__main__":  # pragma: no cover
    ap = argparse.ArgumentParser()
    add_arguments(ap)
    raise SystemExit(main(ap.parse_args()))
