"""How many people does the initial scan hear? ``python -m sim_link.world.measure SCENARIO``.

Flies the scan exactly as ``uavloc plan SCENARIO`` lays it out (launch -> pass-through waypoints ->
launch, every vehicle at ``fleet.speed_m_s`` from t = 0, listening every slot) over simulated worlds
and counts, per person, the distinct **bursts** heard by any vehicle (a burst heard by two vehicles
counts once; in the continuous world, and for elicited frames, a "burst" is a run of heard slots
with no gap over :data:`PASS_GAP_S`). Prints the fraction of people heard at least once and at
least twice, averaged over seeds, with the spread over seeds.

Examples::

    python -m sim_link.world.measure examples/paper.toml --emission probe-bursts
    python -m sim_link.world.measure examples/field.toml --speed 10
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass

import numpy as np

from uavloc_gcs.scan import plan_scan

from .world import World

PASS_GAP_S = 10.0  # heard slots further apart than this are separate looks (continuous/elicited)


@dataclass(frozen=True)
class Coverage:
    """Heard-burst counts of one world: ``bursts[i]`` distinct bursts heard from person i."""

    bursts: np.ndarray  # (S,) int
    scan_time_s: float

    @property
    def once(self) -> float:
        return float(np.mean(self.bursts >= 1)) if len(self.bursts) else math.nan

    @property
    def twice(self) -> float:
        return float(np.mean(self.bursts >= 2)) if len(self.bursts) else math.nan


def fly_scan(world: World, *, chunk_s: float = 60.0, altitude_m: float | None = None):
    """Hear the scenario's initial scan in ``world``; returns (SlotBatch of everything heard, scan
    duration [s]). ``altitude_m``: fly the same lanes at this height instead of the scenario's."""
    from uavloc_gcs.observations import SlotBatch

    sc = world.scenario
    plan = plan_scan(sc)
    speed, slot_s = sc.fleet.speed_m_s, sc.channel.slot_s
    h = sc.fleet.altitude_m if altitude_m is None else float(altitude_m)
    out, t_end = [], 0.0
    for vs in plan.vehicles:
        path = np.vstack([np.zeros((1, 2)), vs.waypoints_xy_m, np.zeros((1, 2))])
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
        duration = cum[-1] / speed
        t_end = max(t_end, duration)
        t_all = np.arange(0.0, duration, slot_s)
        for a in range(0, len(t_all), max(1, int(chunk_s / slot_s))):  # pieces: as the daemon hears
            t = t_all[a : a + int(chunk_s / slot_s)]
            s = t * speed
            xyz = np.column_stack([np.interp(s, cum, path[:, 0]), np.interp(s, cum, path[:, 1]), np.full(len(t), h)])
            out.append(world.hear_track(vs.index + 1, t, xyz))
    return SlotBatch.concat(out), t_end


def scan_coverage(world: World, *, altitude_m: float | None = None) -> Coverage:
    """Distinct bursts heard per person during the scan (see the module docstring); ``altitude_m``
    as for :func:`fly_scan`."""
    heard, t_end = fly_scan(world, altitude_m=altitude_m)
    person = world.person_of(heard.address)
    if world.emission is None:
        burst = np.full(len(heard), -1)
    else:
        lookup = _burst_lookup(world, t_end)
        burst = np.array([lookup.get((int(p), int(a), round(float(t), 6)), -1)
                          for p, a, t in zip(person, heard.address, heard.t_s)], dtype=int)
    counts = np.zeros(len(world), dtype=int)
    for i in range(len(world)):
        mine = person == i
        runs = np.sort(heard.t_s[mine & (burst < 0)])  # continuous or elicited: runs of heard slots
        n_runs = 0 if runs.size == 0 else 1 + int(np.sum(np.diff(runs) > PASS_GAP_S))
        counts[i] = len(np.unique(burst[mine & (burst >= 0)])) + n_runs
    return Coverage(counts, float(t_end))


def _burst_lookup(world: World, t_end_s: float) -> dict:
    """(person, address, slot start) -> burst index, for every frame sent during the scan."""
    slot_s = world.scenario.channel.slot_s
    f = world.emission.frames(0.0, t_end_s + slot_s)
    slot_t = np.floor(f.t_s / slot_s + 1e-9) * slot_s
    return {(int(p), int(a), round(float(s), 6)): int(b) for p, a, s, b in zip(f.person, f.address, slot_t, f.burst)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m sim_link.world.measure", description=__doc__.splitlines()[0])
    ap.add_argument("scenario")
    ap.add_argument("--emission", choices=["continuous", "probe-bursts"], help="override emission.model")
    ap.add_argument("--speed", type=float, help="override fleet.speed_m_s [m/s] (energy budget lifted)")
    ap.add_argument("--elicitation", type=float, help="override emission.elicitation_rate_hz [Hz]")
    ap.add_argument("--join", choices=("scan", "in-reach"), default="scan",
                    help="emission.elicitation_join with --elicitation (default scan)")
    ap.add_argument("--people", type=int, default=50)
    ap.add_argument("--seeds", type=int, default=20)
    args = ap.parse_args(argv)
    from uavloc_gcs.scenario import load_scenario

    sc = load_scenario(args.scenario)
    if args.emission:
        sc = sc.replace(emission={"model": args.emission})
    if args.elicitation is not None:
        sc = sc.replace(emission={"elicitation_rate_hz": args.elicitation, "elicitation_join": args.join})
    if args.speed:
        sc = sc.replace(fleet={"speed_m_s": args.speed, "energy_budget_j": 1e9})
    runs = [scan_coverage(World(sc, seed=s, people=args.people)) for s in range(1, args.seeds + 1)]
    once = np.array([r.once for r in runs])
    twice = np.array([r.twice for r in runs])
    print(f"{sc.name}: emission {sc.emission.model}, sensitivity {sc.channel.receiver_sensitivity_dbm} dBm, "
          f"{sc.fleet.vehicles} vehicles at {sc.fleet.speed_m_s:g} m/s, scan {runs[0].scan_time_s:.0f} s, "
          f"{args.people} people x {args.seeds} seeds")
    print(f"heard at least once:  {100 * once.mean():.1f} % (seeds {100 * once.min():.0f}-{100 * once.max():.0f} %)")
    print(f"heard at least twice: {100 * twice.mean():.1f} % (seeds {100 * twice.min():.0f}-{100 * twice.max():.0f} %)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
