"""``python -m benchmarks.altitude``: what altitude costs and buys under the air-to-ground channel.

For every environment of :mod:`uavloc_gcs.a2g` (and the log-distance channel of the field world
before issue 41, ``before``) at 100, 60, 40 and 30 m above the phones, on ``examples/field.toml``
(its link budget, phones and receiver; only ``[channel] environment`` changes):

- **frame 50 %** / **burst 50 %**: the horizontal distance [m] out to which one frame / one burst of
  the population's frames law (on the listened channels) is heard with probability 1/2 -- the
  model's functions (the world agrees: tests/sim_link/world/test_airground.py);
- **heard**: the share of people with at least one burst heard when the paper's scan (the lanes
  ``uavloc plan`` lays out, 4 vehicles at 25 m/s, launch -> lanes -> launch) is flown at that height
  in the simulated world: ``--people`` x ``--seeds`` worlds, mean and range over seeds;
- **range error**: over the bursts heard in those scans, the median of |d_hat - d| / d and of
  |d_hat - d| [m], d the true 3-D distance at the burst's first heard slot and d_hat the maximum of
  the burst's likelihood (``A2GChannel.burst_log_likelihood_unknown_sent``, the scenario's frames
  law, the phone taken at nominal power while the world spreads phones by 3 dB) over distances at
  the known height; for ``before``, the mean RSSI of the burst inverted by the log-distance law.

Example::

    python -m benchmarks.altitude --people 50 --seeds 10
"""

from __future__ import annotations

import argparse
import math

import numpy as np

ALTITUDES_M = (100.0, 60.0, 40.0, 30.0)
BEFORE = "before"  # the log-distance channel of field.toml before issue 41


def scenario_for(base, environment: str):
    """field.toml with ``environment``, or (``before``) its channel before issue 41."""
    if environment == BEFORE:
        return base.replace(channel={"environment": None, "path_loss_exponent": 2.3, "reference_power_dbm": -40.0})
    return base.replace(channel={"environment": environment})


def hearing_distances_m(sc, height_m: float) -> tuple[float, float]:
    """(frame, burst) 50 % horizontal hearing distances [m] at ``height_m`` for a phone at nominal power."""
    from uavloc_gcs.a2g import A2GChannel
    from uavloc_gcs.search import phones, pod
    from uavloc_gcs.search.phones import frames_prior

    a2g = A2GChannel.from_scenario(sc)
    pmf = np.concatenate([[0.0], np.asarray(frames_prior(sc).p, float)])
    share = phones.channel_share(sc)
    if a2g is not None:
        return (a2g.hearing_distance_m(height_m),
                a2g.hearing_distance_m(height_m, frames=("pmf", pmf), channel_share=share))
    ch = sc.channel
    margin = ch.reference_power_dbm - ch.receiver_sensitivity_dbm
    slant = ch.reference_distance_m * 10 ** (margin / (10 * ch.path_loss_exponent))
    frame = math.sqrt(max(slant * slant - height_m * height_m, 0.0))
    h = np.arange(0.0, 3000.5, 0.5)
    p = pod.p_burst_heard(sc.replace(simulation={"tx_power_spread_db": 0.0}), h, height_m)
    above = np.nonzero(p >= 0.5)[0]
    return frame, float(h[above[-1]]) if len(above) else 0.0


def _bursts_heard(world, heard, t_end: float):
    """Heard slots grouped into bursts: per burst (person, rows of ``heard``)."""
    slot_s = world.scenario.channel.slot_s
    f = world.emission.frames(0.0, t_end + slot_s)
    slot_t = np.floor(f.t_s / slot_s + 1e-9)
    lookup = {(int(p), int(a), int(s)): int(b) for p, a, s, b in zip(f.person, f.address, slot_t, f.burst)}
    person = world.person_of(heard.address)
    keys = [(int(p), lookup.get((int(p), int(a), int(round(t / slot_s))), -1))
            for p, a, t in zip(person, heard.address, heard.t_s)]
    groups: dict = {}
    for row, key in enumerate(keys):
        if key[1] >= 0:
            groups.setdefault(key, []).append(row)
    return groups


def range_errors(world, heard, t_end: float, height_m: float) -> np.ndarray:
    """(relative, metres) range error of every burst heard (see the module docstring), (B, 2)."""
    from uavloc_gcs.a2g import A2GChannel
    from uavloc_gcs.search import phones
    from uavloc_gcs.search.phones import frames_prior

    sc = world.scenario
    a2g = A2GChannel.from_scenario(sc)
    pmf = np.concatenate([[0.0], np.asarray(frames_prior(sc).p, float)])
    share = phones.channel_share(sc)
    grid = np.arange(0.0, 1500.0, 1.0)
    out = []
    for (person, _), rows in _bursts_heard(world, heard, t_end).items():
        rows = np.asarray(rows)
        first = rows[np.argmin(heard.t_s[rows])]
        truth_xy = world.positions(float(heard.t_s[first]))[person]
        d = float(np.hypot(np.linalg.norm(truth_xy - heard.xyz_m[first, :2]), height_m))
        if a2g is not None:
            ll = a2g.burst_log_likelihood_unknown_sent(heard.rssi_dbm[rows], pmf, grid, height_m,
                                                       counts=heard.n_samples[rows], channel_share=share)
            d_hat = float(np.hypot(grid[int(np.argmax(ll))], height_m))
        else:
            ch = sc.channel
            mean = float(np.average(heard.rssi_dbm[rows], weights=heard.n_samples[rows]))
            d_hat = ch.reference_distance_m * 10 ** ((ch.reference_power_dbm - mean) / (10 * ch.path_loss_exponent))
        out.append((abs(d_hat - d) / d, abs(d_hat - d)))
    return np.asarray(out).reshape(-1, 2)


def measure(environment: str, height_m: float, people: int, seeds: int, base=None) -> dict:
    from sim_link.world import World
    from sim_link.world.measure import fly_scan, scan_coverage
    from uavloc_gcs.examples import scenario_path
    from uavloc_gcs.scenario import load_scenario

    sc = scenario_for(base if base is not None else load_scenario(scenario_path("field")), environment)
    frame, burst = hearing_distances_m(sc, height_m)
    once, errs = [], []
    for seed in range(1, seeds + 1):
        once.append(scan_coverage(World(sc, seed=seed, people=people), altitude_m=height_m).once)
        world = World(sc, seed=seed, people=people)
        heard, t_end = fly_scan(world, altitude_m=height_m)
        errs.append(range_errors(world, heard, t_end, height_m))
    err = np.vstack(errs)
    return {"environment": environment, "altitude_m": height_m, "frame_m": frame, "burst_m": burst,
            "heard": float(np.mean(once)), "heard_min": float(np.min(once)), "heard_max": float(np.max(once)),
            "bursts": len(err), "rel_error": float(np.median(err[:, 0])) if len(err) else math.nan,
            "error_m": float(np.median(err[:, 1])) if len(err) else math.nan}


def add_arguments(ap: argparse.ArgumentParser) -> None:
    from uavloc_gcs.a2g import ENVIRONMENTS

    ap.add_argument("--people", type=int, default=50)
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--environments", default=",".join([*ENVIRONMENTS, BEFORE]),
                    help=f"comma list of {', '.join([*ENVIRONMENTS, BEFORE])}")
    ap.add_argument("--altitudes", default=",".join(f"{a:g}" for a in ALTITUDES_M), help="heights [m], comma list")


def main(args: argparse.Namespace | list[str] | None = None) -> int:
    from uavloc_gcs.a2g import ENVIRONMENTS

    if not isinstance(args, argparse.Namespace):
        ap = argparse.ArgumentParser(prog="python -m benchmarks.altitude", description=__doc__.splitlines()[0])
        add_arguments(ap)
        args = ap.parse_args(args)
    envs = [e.strip() for e in args.environments.split(",") if e.strip()]
    for e in envs:
        if e not in ENVIRONMENTS and e != BEFORE:
            print(f"uavloc bench altitude: unknown environment {e!r}; choose from {', '.join([*ENVIRONMENTS, BEFORE])}")
            return 2
    alts = [float(a) for a in args.altitudes.split(",")]
    print(f"examples/field.toml, the paper's scan flown at each height, {args.people} people x {args.seeds} worlds")
    print(f"{'environment':<12} {'alt m':>5} {'frame 50% m':>11} {'burst 50% m':>11} {'heard (seeds)':>16} "
          f"{'bursts':>6} {'range err':>9} {'err m':>6}")
    for env in envs:
        for alt in alts:
            r = measure(env, alt, args.people, args.seeds)
            print(f"{env:<12} {alt:>5.0f} {r['frame_m']:>11.0f} {r['burst_m']:>11.0f} "
                  f"{100 * r['heard']:>5.0f}% ({100 * r['heard_min']:.0f}-{100 * r['heard_max']:.0f}) "
                  f"{r['bursts']:>6d} {100 * r['rel_error']:>8.0f}% {r['error_m']:>6.1f}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
