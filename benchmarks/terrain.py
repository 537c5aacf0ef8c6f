"""``python -m benchmarks.terrain [--people N] [--walkers N]``: what terrain does to the missions and
the estimator (docs/science/terrain.md).

1. The scan of ``examples/mountains.toml`` (Mount Washington's west flank, SRTM3): per vehicle the
   waypoints before and after ``terrain_safe``, the least and median height above the DEM along the
   flown legs (sampled at a quarter DEM cell), the climb energy; and the flat plan's least height
   above the same ground (what the scan at 100 m above the launch point would have done).
2. People placed uniformly over the area, heard by the simulated world on the ground's surface
   from two terrain-following passes 70-80 m either side: the static estimator's RMSE with everyone
   at the launch point's height (the flat model) and with the person's height from the DEM, and
   what the terrain fit costs (estimator fits and CPU seconds), first and on a later update.
3. Walkers (1.4 m/s, any heading; world seeds 0..N-1) heard from two pairs of terrain-following
   passes 200 s apart, as in ``tests/terrain/test_people_on_terrain.py``: how many end inside
   their 95 % circle, the RMSE, and the CPU the terrain fit took.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.terrain", description=__doc__.splitlines()[0])
    ap.add_argument("--people", type=int, default=20, help="people for the estimator part (default 20)")
    ap.add_argument("--walkers", type=int, default=24, help="walkers for the third part (default 24; 0: none)")
    ap.add_argument("--verbose", action="store_true", help="one line per person")
    args = ap.parse_args(argv)

    from sim_link.world import World
    from uavloc_gcs.estimation import estimate_emitter
    from uavloc_gcs.estimation.model import ChannelModel
    from uavloc_gcs.estimation.terrain_fit import estimate_on_terrain
    from uavloc_gcs.scan import plan_scan, scan_missions
    from uavloc_gcs.scenario import load_scenario
    from uavloc_gcs.terrain_missions import clearance_along, climb_energy_j, terrain_safe

    sc = load_scenario(Path(__file__).resolve().parents[1] / "uavloc_gcs" / "examples" / "mountains.toml")
    dem = sc.dem
    xy = sc.area_xy_m()
    g = dem.height_xy(xy)
    print(f"{sc.name}: ground {g.min():.0f}..{g.max():.0f} m at the area's corners, DEM cells {dem.resolution_m:.0f} m; "
          f"scan {sc.fleet.altitude_m:g} m above the ground, min clearance {sc.terrain.min_clearance_m:g} m")
    print("vehicle  waypoints flat->safe  least/median height above ground [m]  flat plan's least [m]  climb kJ")
    plan = plan_scan(sc)
    for v, m in zip(plan.vehicles, scan_missions(sc, plan)):
        safe = terrain_safe(m, sc, name=f"uav{v.index + 1}")
        c = clearance_along(safe, sc, step_m=dem.resolution_m / 4)
        cf = clearance_along(m, sc, step_m=dem.resolution_m / 4)
        print(f"uav{v.index + 1}     {len(m.waypoints()):>4} -> {len(safe.waypoints()):<4}          "
              f"{c.min():7.1f} / {np.median(c):6.1f}                        {cf.min():8.1f}       "
              f"{climb_energy_j(safe, sc) / 1000:6.1f}")

    ch = ChannelModel.from_scenario(sc)
    home = dem.height_at(0.0, 0.0)
    flat_err, ter_err, heights, both = [], [], [], []
    fits, cost = [0], [np.zeros(2), np.zeros(2)]  # fits and CPU seconds: first estimates, updates

    def counted(*a, **k):
        fits[0] += 1
        return estimate_emitter(*a, **k)

    rng = np.random.default_rng(2026)
    lo, hi = xy.min(axis=0) + 100.0, xy.max(axis=0) - 100.0
    for k in range(args.people):
        person = rng.uniform(lo, hi)
        w = World.with_people(sc, person[None], seed=k)
        t, pts, tt = [], [], 0.0
        for dy in (-80.0, 70.0):
            for x in np.arange(person[0] - 300.0, person[0] + 300.0, 1.5):
                p = np.array([x, person[1] + dy])
                t.append(tt)
                pts.append([p[0], p[1], dem.height_at(*p) - home + sc.fleet.altitude_m])
                tt += 0.1
            tt += 20.0
        slots = w.hear_track(1, np.array(t), np.array(pts))
        flat = estimate_emitter(slots, ch, max_speed_m_s=0.0, model_motion=False)
        c0, w0 = fits[0], time.process_time()
        ter = estimate_on_terrain(slots, ch, dem, estimate=counted, max_speed_m_s=0.0, model_motion=False)
        c1, w1 = fits[0], time.process_time()
        # the daemon's next update of the same person: the same slots, the last estimate given
        estimate_on_terrain(slots, ch, dem, estimate=counted, max_speed_m_s=0.0, model_motion=False, previous=ter)
        cost[0] += [c1 - c0, w1 - w0]
        cost[1] += [fits[0] - c1, time.process_time() - w1]
        flat_err.append(float(np.linalg.norm(flat.position_xy_m - person)))
        ter_err.append(float(np.linalg.norm(ter.position_xy_m - person)))
        heights.append(dem.height_at(*person) - home)
        both.append(len(np.unique(np.round(slots.xyz_m[:, 1], 3))) == 2)  # heard from both passes
        if args.verbose:
            print(f"  person {k}: ground {heights[-1]:.0f} m above launch, {len(slots)} slots, error flat {flat_err[-1]:.1f} m, "
                  f"terrain {ter_err[-1]:.1f} m (95 % radius {ter.radius95_m:.1f} m)")
    rm = lambda e: float(np.sqrt(np.mean(np.square(e)))) if len(e) else float("nan")  # noqa: E731
    b = np.array(both)
    fe, te = np.array(flat_err), np.array(ter_err)
    print(f"\n{args.people} people {min(heights):.0f}..{max(heights):.0f} m above the launch point, two passes each; "
          f"{b.sum()} heard from both passes: RMSE {rm(fe[b]):.1f} m with everyone at the launch point's height, "
          f"{rm(te[b]):.1f} m with the person's height from the DEM (median {np.median(fe[b]):.1f} / "
          f"{np.median(te[b]):.1f} m)")
    print(f"estimator over terrain: {cost[0][0]:.0f} fits in {cost[0][1]:.1f} s CPU for the first estimates, "
          f"{cost[1][0]:.0f} fits in {cost[1][1]:.1f} s CPU to update them with the previous estimate given")
    if (~b).any():
        print(f"{(~b).sum()} heard from one pass only (the ground there put the other pass beyond "
              f"{sc.fleet.comm_range_m:g} m): a pass's mirror ambiguity, errors flat "
              f"{', '.join(f'{e:.0f}' for e in fe[~b])} m, terrain {', '.join(f'{e:.0f}' for e in te[~b])} m")
    if args.walkers > 0:
        _walkers(sc, ch, args.walkers, args.verbose)
    return 0


def _passes(sc, centre, t0_s: float, offsets_m) -> tuple[np.ndarray, np.ndarray]:
    """Terrain-following passes along x at ``offsets_m`` north of ``centre``, 100 m above the ground."""
    dem, home = sc.dem, sc.dem.height_at(0.0, 0.0)
    t, xyz, tt = [], [], float(t0_s)
    for dy in offsets_m:
        for x in np.arange(centre[0] - 300.0, centre[0] + 300.0, 1.5):
            t.append(tt)
            xyz.append([x, centre[1] + dy, dem.height_at(x, centre[1] + dy) - home + sc.fleet.altitude_m])
            tt += 0.1
        tt += 20.0
    return np.array(t), np.array(xyz)


def _walkers(sc, ch, n: int, verbose: bool) -> None:
    from sim_link.world import World
    from uavloc_gcs.estimation import estimate_emitter
    from uavloc_gcs.estimation.terrain_fit import estimate_on_terrain

    errors, radii, c0 = [], [], time.process_time()
    for seed in range(n):
        rng = np.random.default_rng(seed)
        start = np.array([rng.uniform(300, 800), rng.uniform(200, 450)])
        ang = rng.uniform(0, 2 * np.pi)
        w = World.with_people(sc, start[None], 1.4 * np.array([[np.cos(ang), np.sin(ang)]]), seed=seed)
        t1, x1 = _passes(sc, start, 0.0, (-80.0, 70.0))
        t2, x2 = _passes(sc, w.positions(200.0)[0], 200.0, (-60.0, 90.0))
        slots = w.hear_track(1, np.concatenate([t1, t2]), np.vstack([x1, x2]))
        t_ref = float(slots.t_s.max())
        est = estimate_on_terrain(slots, ch, sc.dem, estimate=estimate_emitter, max_speed_m_s=1.5, t_ref_s=t_ref)
        errors.append(float(np.linalg.norm(est.position_xy_m - w.positions(t_ref)[0])))
        radii.append(float(est.radius95_m))
        if verbose:
            print(f"  walker {seed}: error {errors[-1]:.1f} m, 95 % radius {radii[-1]:.1f} m")
    e, r = np.array(errors), np.array(radii)
    print(f"{n} walkers (1.4 m/s) heard from two pairs of passes 200 s apart: {int(np.sum(e <= r))} of {n} inside "
          f"their 95 % circle, RMSE {float(np.sqrt(np.mean(e * e))):.1f} m, median radius {float(np.median(r)):.0f} m, "
          f"{time.process_time() - c0:.1f} s CPU")


if __name__ == "__main__":
    raise SystemExit(main())
