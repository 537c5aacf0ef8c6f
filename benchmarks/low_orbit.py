"""``uavloc bench low_orbit``: what one low orbit can learn of a trapped person in the field world.

One vehicle orbits a static phone of ``examples/field.toml`` (its air-to-ground channel, bursts and
receiver) at ``--alt`` metres, radius = altitude (the radius that maximises a burst's information
about the horizontal position for a range error proportional to the distance), 8 m/s, starting
from a centre ``--offset`` metres off the truth (where the scan put the person) and re-centred on the
grid posterior's mean after each burst (search/orbit.py ADAPTIVE_ORBITS; ``--fixed``: never). The
estimate is the field world's own (estimation/burst_grid.py, A2GBursts). Printed per run: when the
95 % radius first fell to the required accuracy (located), the error and radius at the end, the
bursts heard; then the share located, the share inside their circle and the median radius at the
end. The question it answers: how long a look must dwell, at which height, before the radius is
small enough -- the physics behind ``uavloc bench field``'s figures.

Example::

    uavloc bench low_orbit --alt 30 --minutes 20 --runs 6
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from uavloc_gcs.cli._inputs import number


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--alt", type=number(float, min=5.0, max=300.0), default=30.0, help="orbit height [m] (default 30)")
    p.add_argument("--minutes", type=number(float, min=1.0, max=240.0), default=20.0, help="longest dwell (default 20)")
    p.add_argument("--runs", type=number(int, min=1, max=500), default=6, help="worlds (default 6)")
    p.add_argument("--offset", type=number(float, min=0.0, max=500.0), default=60.0,
                   help="std of the first centre's error [m] (default 60)")
    p.add_argument("--elicitation", type=number(float, min=0.0, max=1000.0), default=0.0, metavar="HZ",
                   help="an on-board access point at HZ (default 0: probe bursts only)")
    p.add_argument("--fixed", action="store_true", help="never re-centre the orbit")
    p.add_argument("--ble", action="store_true",
                   help="the phone also sends Find My BLE beacons; estimate from its current BLE identity alone")


def main(args: argparse.Namespace) -> int:
    from sim_link.world import World
    from uavloc_gcs.estimation.burst_grid import BurstGridEstimator, bursts_from_slots, missed_beacons
    from uavloc_gcs.estimation.burst_models import A2GBursts
    from uavloc_gcs.examples import scenario_path
    from uavloc_gcs.observations import SlotBatch
    from uavloc_gcs.scenario import load_scenario
    from uavloc_gcs.search.phones import channel_share, frames_prior

    from uavloc_gcs.radios import ble_view, is_ble

    sc = load_scenario(scenario_path("field")).replace(people={"max_speed_m_s": 0.0},
                                                       emission={"elicitation_rate_hz": float(args.elicitation),
                                                                 "findmy_share": 1.0 if args.ble else 0.0})
    if args.ble:  # the policy's BLE identity estimate (search/policy.py _grid_spec): one beacon per unit
        pmf = np.array([0.0, 1.0])
        model = A2GBursts.from_scenario(ble_view(sc), pmf, 1.0)
    else:
        fp = np.asarray(frames_prior(sc).p, float)
        pmf = np.concatenate([[0.0], fp / fp.sum()])
        model = A2GBursts.from_scenario(sc, pmf, channel_share(sc))
    est = BurstGridEstimator(model, pmf, area_xy_m=sc.area_xy_m(), area_margin_m=100.0)
    need = float(sc.people.required_accuracy_m)
    rng = np.random.default_rng(0)
    alt, speed = float(args.alt), 8.0
    rows = []
    cpu0 = time.process_time()
    print(f"one vehicle orbiting a trapped phone of 'field' at {alt:g} m (radius {alt:g} m, {speed:g} m/s), first centre "
          f"~{args.offset:g} m off, {'fixed' if args.fixed else 're-centred on the posterior'}, at most "
          f"{args.minutes:g} min" + (f", access point {args.elicitation:g} Hz" if args.elicitation else "")
          + (", from its Find My BLE beacons" if args.ble else ""))
    print(f"{'run':>3} {'located at s':>12} {'error m':>8} {'r95 m':>7} {'bursts':>6}")
    for run in range(args.runs):
        person = np.array([300.0 + 500 * rng.random(), 150 + 340 * rng.random()])
        world = World.with_people(sc, [person], seed=100 + run)
        centre = person + rng.normal(0, args.offset, 2)
        t0, ang0, parts, t_loc, post, bursts = 0.0, 0.0, [], None, None, []
        track_t, track_xyz = [], []
        while t0 < args.minutes * 60.0:
            t = np.arange(t0, t0 + 10.0, sc.channel.slot_s)
            ang = ang0 + speed * (t - t0) / alt
            xyz = np.column_stack([centre[0] + alt * np.cos(ang), centre[1] + alt * np.sin(ang), np.full(len(t), alt)])
            heard = world.hear_track(1, t, xyz)
            track_t.append(t[::20])
            track_xyz.append(xyz[::20])
            if args.ble:  # the identity alive now: the last BLE address heard
                heard = heard.take(is_ble(heard))
                if len(heard) and parts and len(parts[-1]) and heard.address[-1] != parts[-1].address[-1]:
                    parts = [p.take(p.address == heard.address[-1]) for p in parts]  # its key rotated
            parts.append(heard)
            t0, ang0 = t0 + 10.0, float(ang[-1] + speed * sc.channel.slot_s / alt)
            if len(parts[-1]):
                if args.ble:  # the identity's beacons heard, and the events it sent that were missed
                    allp = SlotBatch.concat(parts)
                    heard_b = bursts_from_slots(allp.take(allp.address == parts[-1].address[-1]))
                    bursts = heard_b + missed_beacons(heard_b, sc.emission.ble_interval_s,
                                                      {1: (np.concatenate(track_t), np.vstack(track_xyz))})
                else:
                    bursts = bursts_from_slots(SlotBatch.concat(parts))
                post = est.posterior(bursts, float(t[-1]))
                if not args.fixed:
                    centre = post.mean_xy_m
                if post.radius_about(post.mean_xy_m) <= need:
                    t_loc = t0
                    break
        if post is None:
            rows.append((None, np.nan, np.nan, 0))
            print(f"{run:>3} {'-':>12} {'nothing heard':>16}")
            continue
        r = post.radius_about(post.mean_xy_m)
        e = float(np.hypot(*(post.mean_xy_m - person)))
        rows.append((t_loc, e, r, sum(not b.silent for b in bursts)))
        print(f"{run:>3} {('-' if t_loc is None else f'{t_loc:.0f}'):>12} {e:8.1f} {r:7.1f} {len(bursts):6d}", flush=True)
    loc = [x for x in rows if x[0] is not None]
    est_rows = [x for x in rows if np.isfinite(x[2])]
    print(f"located (95 % radius <= {need:g} m): {len(loc)} of {len(rows)}"
          + (f", median at {np.median([x[0] for x in loc]):.0f} s" if loc else "")
          + f"; inside their 95 % circle at the end: {sum(x[1] <= x[2] for x in est_rows)} of {len(est_rows)}"
          + (f"; median radius at the end {np.median([x[2] for x in est_rows]):.1f} m" if est_rows else "")
          + f"; {time.process_time() - cpu0:.0f} s of CPU")
    return 0


if __name__ == "__main__":  # pragma: no cover
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_arguments(ap)
    raise SystemExit(main(ap.parse_args()))
