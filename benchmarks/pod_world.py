"""``python -m benchmarks.pod_world``: the POD model (uavloc_gcs/search/pod.py) against the simulated
field world.

One vehicle flies straight passes (25 m/s, at ``--altitude``: 100 m by default, a comma list for
several) over a 600 x 1000 m strip of static phones of ``examples/field.toml``'s world (its urban
air-to-ground channel: the model looks hearing up at the flight's height); the fraction of phones with at least one / two distinct bursts heard
is compared with ``pod_from_tracks``'s area POD for the same tracks. Two starting times:

- ``steady``: three hours into the phones' lives, where their burst processes (and long silences)
  are in the steady state the model assumes -- a search starts at a random moment of a phone's life;
- ``cold``: at t = 0 of the simulated world, whose phones all start in a short gap (none in a long
  silence), so the world hears more than a real search would.

Prints per case: predicted POD1/POD2, simulated fractions with their binomial standard errors.
"""

from __future__ import annotations

import argparse
import math

import numpy as np


def _strip(sc0):
    frame = sc0.frame
    xy = np.array([[-300, -500], [300, -500], [300, 500], [-300, 500]], float)
    ll = frame.to_wgs84_latlon(xy)
    launch = frame.to_wgs84_latlon(np.zeros((1, 2)))[0]
    return sc0.replace(
        area={"polygon_deg": [list(map(float, p)) for p in ll], "origin_lat_deg": None, "origin_lon_deg": None,
              "width_m": None, "height_m": None},
        launch={"lat_deg": float(launch[0]), "lon_deg": float(launch[1])}, simulation={"motion": "static"})


def _pass(t_start, x0, x1, slot_s, speed=25.0, alt=100.0):
    t = np.arange(0.0, abs(x1 - x0) / speed, slot_s)
    x = x0 + np.sign(x1 - x0) * speed * t
    return t_start + t, np.column_stack([x, np.zeros_like(x), np.full_like(x, alt)])


def heard_bursts(world, tracks) -> np.ndarray:
    """Distinct bursts heard per person along the tracks (one vehicle)."""
    from uavloc_gcs.observations import SlotBatch

    heard = SlotBatch.concat([world.hear_track(1, t, xyz) for t, xyz in tracks])
    person = world.person_of(heard.address)
    all_t = np.concatenate([t for t, _ in tracks])
    f = world.emission.frames(all_t[0] - 1.0, all_t[-1] + 1.0)
    slot = all_t[np.maximum(np.searchsorted(all_t, f.t_s, side="right") - 1, 0)]
    burst_of = {(int(p), int(a), round(float(s), 6)): int(b) for p, a, s, b in zip(f.person, f.address, slot, f.burst)}
    b = np.array([burst_of.get((int(p), int(a), round(float(t), 6)), -1)
                  for p, a, t in zip(person, heard.address, heard.t_s)], dtype=int)
    out = np.zeros(len(world), dtype=int)
    for i in range(len(world)):
        mine = person == i
        runs = np.sort(heard.t_s[mine & (b < 0)])  # elicited frames: runs more than 10 s apart
        out[i] = len(np.unique(b[mine & (b >= 0)])) + (0 if runs.size == 0 else 1 + int(np.sum(np.diff(runs) > 10.0)))
    return out


def main(argv=None) -> int:
    from sim_link.world import World
    from uavloc_gcs.scenario import load_scenario
    from uavloc_gcs.search import pod

    ap = argparse.ArgumentParser(prog="python -m benchmarks.pod_world", description=__doc__.splitlines()[0])
    ap.add_argument("--people", type=int, default=400)
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--elicitation", type=float, default=0.0, help="emission.elicitation_rate_hz [Hz]")
    ap.add_argument("--join", choices=("scan", "in-reach"), default="scan",
                    help="emission.elicitation_join: a phone joins at a burst within reach (scan, default) or "
                         "answers from the moment it is within reach (in-reach)")
    ap.add_argument("--cases", default="steady,cold", help="steady, cold or both (default)")
    ap.add_argument("--altitude", default="100", help="flight height(s) above the phones [m], comma-separated")
    args = ap.parse_args(argv)
    sc = _strip(load_scenario("examples/field.toml"))
    if args.elicitation:
        sc = sc.replace(emission={"elicitation_rate_hz": args.elicitation, "elicitation_join": args.join})
    slot = sc.channel.slot_s
    alts = [float(a) for a in args.altitude.split(",")]
    print(f"{args.people} static phones x {args.seeds} worlds, field.toml ({sc.channel.environment or 'log-distance'}"
          f" channel), one vehicle at 25 m/s, {', '.join(f'{a:g}' for a in alts)} m"
          + (f", elicitation {args.elicitation:g} Hz ({args.join})" if args.elicitation else ""))
    print(f"{'case':<40} {'POD1 model':>10} {'heard>=1':>14} {'POD2 model':>10} {'heard>=2':>14}")
    for alt, (start_name, t0) in ((a, c) for a in alts for c in (("steady", 3 * 3600.0), ("cold", 0.0))):
        if start_name not in args.cases.split(","):
            continue
        for passes, sep in ((1, 0.0), (2, 30.0), (2, 600.0), (3, 600.0)):
            tracks = [_pass(t0, -1500.0, 1500.0, slot, alt=alt)]
            for k in range(1, passes):
                end = tracks[-1][0][-1]
                tracks.append(_pass(end + sep, 1500.0, -1500.0, slot, alt=alt) if k % 2
                              else _pass(end + sep, -1500.0, 1500.0, slot, alt=alt))
            g = pod.pod_from_tracks(sc, [(t[::40], x[::40]) for t, x in tracks], pod.grid_for(sc, 40.0))
            counts = np.concatenate([heard_bursts(World(sc, seed=s, people=args.people), tracks)
                                     for s in range(1, args.seeds + 1)])
            n = len(counts)
            f1, f2 = np.mean(counts >= 1), np.mean(counts >= 2)
            se1, se2 = math.sqrt(f1 * (1 - f1) / n), math.sqrt(f2 * (1 - f2) / n)
            case = (f"{alt:g} m, {start_name}, {passes} pass{'es' if passes > 1 else ''}"
                    + (f", {sep:g} s apart" if passes > 1 else ""))
            print(f"{case:<40} {g.overall(1):>10.3f} {f1:>8.3f}+-{se1:.3f} {g.overall(2):>10.3f} {f2:>8.3f}+-{se2:.3f}",
                  flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
