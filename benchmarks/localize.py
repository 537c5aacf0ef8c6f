"""``uavloc bench localize``: the estimator against the Bayesian Cramer-Rao bound.

Monte Carlo over flight geometries (one leg, two parallel legs 100 m apart flown as a
boustrophedon, two crossing legs), lateral offsets uniform from 0 to R, static and moving phones
(velocity uniform over the disk |v| <= v_max) and i.i.d. or correlated (Gudmundson, 20 m)
shadowing, all heard through ``sim_link.World`` with the paper's channel; plus the fixed
lawnmower geometry of science.md §2 (legs at y = 80 and 240 m, person at y = 100/130/160 m moving
at (1, 0.5) m/s), whose CRB table the information code reproduces (tests/uavloc_gcs/estimation). For each family it
prints, measured in the same run:

- RMSE of the position at the last slot's time; "near": the error to the nearer of the estimate
  and its mirror candidate (what is left once the flagged ambiguity is resolved);
- BCRB: the Bayesian (Van Trees) Cramer-Rao bound of the family: the Fisher information at the
  truth averaged over the runs, plus the estimator's velocity prior, inverted; under correlated
  shadowing the information is that of the simulated AR(1) shadowing, not the i.i.d. model;
  "ratio" = RMSE / BCRB. Because the geometry varies between runs this bound is loose (the inverse
  of an average is below the average of inverses), so "eff" adds the per-run efficiency
  sqrt(mean((e_k / CRB_k)^2)) with e_k the "near" error and CRB_k the bound of run k's own
  geometry and truth (1.0 = efficient); "effE" the same with the reported estimate's error (mirror
  confusions included), "p90E" the 90th percentile of e_k / CRB_k;
- coverage: the fraction of runs whose truth lies inside the calibrated 95 % radius, and inside
  the paper's annulus bound (an empty ring intersection counts as a miss);
- the fraction flagged ambiguous, the median radius / RMSE, the median radius / ideal radius
  ("r/ideal": the ideal is the 95 % circle of the Gaussian with run k's own bound as covariance,
  what an efficient estimator that knew its own accuracy would report; mirror spans included),
  and the solve time per emitter; "need": the 95th percentile of error / radius, the factor by which
  every radius of the family would have to be scaled to cover exactly 95 % (above 1 too small,
  below 1 larger than needed);

plus the solve time for exactly 1,000 slots.

For the walker families under i.i.d. shadowing a second table says where the error beyond the bound
is: the share of runs whose walker ends within ``LAST_TRACK_M`` of the track of the last pass that
heard them, their share of the squared error, and RMSE / BCRB over the other runs. Near that track
the range fixes little more than the squared cross-track offset, so the bound (the information at
the truth) promises metres where the posterior is tens of metres wide. ``--mmse`` adds the
attainable floor on the same runs: the RMSE of the posterior mean of the RSSI alone, the
Bayes-optimal estimator of the slots heard (:mod:`benchmarks.posterior`), with MMSE / BCRB (how far
above the bound any estimator of the RSSI must be) and RMSE / MMSE (the estimator, which also uses
where the phone was not heard, against that floor).

The last table ("maneuvering people") uses ``random_waypoint`` people (they turn, pause and change
speed; |v| <= v_max) over a realistic mission geometry: two scan lanes of 600 m at a spacing
uniform in [0.5 R, R] (the person between them, passes 0-50 s apart), then a look pass
30-180 s later through the two-lane estimate's predicted position (random heading, offset uniform
in [0, 0.5 R]); reference time = each estimate's last slot. It reports the coverage of radius95
and of ``Estimate.predict`` 30 and 60 s later, with the median radii, for the default estimator and
for the pure constant-velocity model (``maneuver_time_s = inf``, the estimator before the
maneuver process noise), and "need": the 95th percentile of error / radius, the factor by which
every radius of the family would have to be scaled to cover exactly 95 % (there is no bound for
a person who turns, so this stands in for r/ideal: above 1 the radii are too small, below 1
larger than needed). "small area" confines the walk to a 250 m square (a turn every few
minutes instead of every several). Times are the thread's CPU time (one core), so other
load on the machine does not inflate them. Targets (issues 3 and 12): RMSE <= 1.2 x bound with two
looks, coverage 0.93-0.97 (i.i.d.) and >= 0.85 (correlated), < 10 ms per emitter at 1,000 slots.
"""

from __future__ import annotations

from uavloc_gcs.cli._inputs import number
import argparse
import math
import sys
import time
from dataclasses import dataclass

import numpy as np

from sim_link.world import World
from uavloc_gcs.estimation import (
    ChannelModel,
    data_information,
    estimate_emitter,
    position_rmse_bound_m,
    prior_information,
    radius_of_probability,
    silence_from_track,
)
from uavloc_gcs.estimation.evidence import Silence
from uavloc_gcs.estimation.prepared import prepare
from uavloc_gcs.observations import SlotBatch
from uavloc_gcs.scenario import load_scenario

from ._progress import Progress
from .posterior import estimate_candidates, mmse_floor, rssi_posterior_mean
from .looks import SWITCHES

# the estimator's switches of bench looks' variants: name -> (estimate module attribute, value)
ESTIMATOR_SWITCHES = {k: (attr, value) for k, (module, attr, value) in SWITCHES.items() if module == "estimate"}

CENTER = np.array([560.0, 320.0])
LANE_SPACING_M = 100.0
TURN_S = 5.0
# a walker who ends closer than this to the track of the last pass that heard them: heard there at
# a range that fixes little more than the squared cross-track offset (benchmarks.posterior)
LAST_TRACK_M = 30.0


@dataclass(frozen=True)
class Family:
    name: str
    geometry: str  # one_leg | parallel | crossing | lawnmower
    moving: bool
    correlated: bool = False
    model_motion: bool = True
    target_y_m: float | None = None  # lawnmower: the person's fixed north coordinate
    tx_spread_db: float = 0.0  # phones' transmit power offsets ~ N(0, spread^2)
    estimate_tx: bool = False


# science.md §2's reference: legs at y = 80 and 240 m joined by a turn, person at x = 600 m moving
# at (1, 0.5) m/s; its CRB table (10 samples/slot) is 9.7 / 6.1 / 9.8 m at the mission start
LAWNMOWER_VELOCITY = np.array([1.0, 0.5])

FAMILIES = [
    Family("one leg, static", "one_leg", False),
    Family("one leg, moving", "one_leg", True),
    Family("two parallel, static", "parallel", False),
    Family("two parallel, static, NM", "parallel", False, model_motion=False),
    Family("two parallel, moving", "parallel", True),
    Family("crossing, static", "crossing", False),
    Family("crossing, moving", "crossing", True),
    Family("lawnmower y=100, moving", "lawnmower", True, target_y_m=100.0),
    Family("lawnmower y=130, moving", "lawnmower", True, target_y_m=130.0),
    Family("lawnmower y=160, moving", "lawnmower", True, target_y_m=160.0),
    Family("crossing, moving, tx 3 dB, est.", "crossing", True, tx_spread_db=3.0, estimate_tx=True),
    Family("crossing, moving, tx 3 dB, nominal", "crossing", True, tx_spread_db=3.0),
    Family("one leg, moving, corr.", "one_leg", True, True),
    Family("two parallel, moving, corr.", "parallel", True, True),
    Family("crossing, moving, corr.", "crossing", True, True),
]


@dataclass(frozen=True)
class ManeuverFamily:
    name: str
    stage: str  # "lanes" (two scan lanes) | "look" (lanes + a later look pass)
    area_m: tuple[float, float] | None = None  # a smaller rectangle than the paper's


MANEUVER_FAMILIES = [
    ManeuverFamily("rwp, two lanes", "lanes"),
    ManeuverFamily("rwp, two lanes + look", "look"),
    ManeuverFamily("rwp, small area, two lanes", "lanes", (250.0, 250.0)),
    ManeuverFamily("rwp, small area, lanes + look", "look", (250.0, 250.0)),
]
MISSION_LANE_M = 600.0
PREDICT_S = (30.0, 60.0)


def _some_family(chosen: list, families: list, wanted: list[str] | None) -> None:
    """--family that matches no family's name is bad input, not an empty table."""
    if not chosen:
        from uavloc_gcs.errors import ConfigError

        raise ConfigError(f"--family {' '.join(wanted or [])}: no family's name contains it; the families are "
                          + "; ".join(repr(f.name) for f in families))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--runs", type=number(int, min=1), default=60, help="Monte Carlo runs per family (default 60)")
    parser.add_argument("--seed", type=number(int, min=0), default=1, help="base seed (default 1)")
    parser.add_argument("--family", action="append", help="only families whose name contains this text")
    parser.add_argument("--evidence", choices=("all", "heard", "none"), default="all",
                        help="hearing as evidence (estimate_emitter(silence=)): 'all' (slots heard and the silences "
                             "of the legs, the default), 'heard' (the slots heard only), 'none' (off: the "
                             "estimator's default)")
    parser.add_argument("--scenario", default="paper", metavar="FILE.toml",
                        help="channel and fleet of this scenario (or a shipped one: paper, small; default paper)")
    parser.add_argument("--maneuver-time", type=number(float, min=0, unit="s"), default=None, metavar="S",
                        help="the estimator's maneuver time for every family (default: its own, "
                             "uavloc_gcs.estimation.maneuver.MANEUVER_TIME_S; inf: the pure constant-velocity "
                             "model, without the turn models)")
    parser.add_argument("--mmse", action="store_true",
                        help="also the attainable floor of the walker families: the RMSE of the Bayes-optimal "
                             "estimator of the RSSI alone (the posterior mean by importance sampling; under a "
                             "minute per 200 runs and family)")
    parser.add_argument("--emission", choices=("continuous", "bursts"), default="continuous",
                        help="the phones' emission: 'continuous' (the paper's world, the default) or 'bursts' (the "
                             "field world: probe-request bursts heard above a receiver sensitivity; its own families, "
                             "benchmarks/localize_bursts.py; --family, --runs, --seed and --mmse apply)")
    parser.add_argument("--frames-prior", choices=("world", "none"), default="world",
                        help="--emission bursts: the estimator is told the world's frames-per-burst distribution and "
                             "uses every listening vehicle's hearing counts ('world', the default), or only the "
                             "silences with a conservative frame count ('none')")
    parser.add_argument("--no-exposure", action="store_true",
                        help="--emission bursts: leave out the bursts nobody heard (estimation.evidence.Exposure), "
                             "as the estimator did before 2026-11-28, to compare")
    parser.add_argument("--switch", choices=sorted(ESTIMATOR_SWITCHES), action="append", default=[],
                        help="run with this estimator switch of `uavloc bench looks --variants` turned on "
                             "(give it again for another)")


def _leg(start, end, t0, speed, slot_s, alt):
    start, end = np.asarray(start, float), np.asarray(end, float)
    length = float(np.linalg.norm(end - start))
    t = np.arange(0.0, length / speed, slot_s)
    xy = start + np.outer(t * speed / length, end - start)
    return t0 + t, np.column_stack([xy, np.full(len(t), alt)])


def _legs(geometry: str, rng: np.random.Generator, reach: float, sc):
    """Vehicle legs for one run; the person starts at CENTER (lawnmower: the fixed reference)."""
    v, slot, alt = sc.fleet.speed_m_s, sc.channel.slot_s, sc.fleet.altitude_m
    half = reach + 60.0
    if geometry == "lawnmower":
        out, t0 = [], 0.0
        for a, b in [((0, 80), (1120, 80)), ((1120, 80), (1120, 240)), ((1120, 240), (0, 240))]:
            t, x = _leg(a, b, t0, v, slot, alt)
            out.append((t, x))
            t0 = t[-1] + slot
        return out
    if geometry == "one_leg":
        y = CENTER[1] - rng.uniform(0.0, reach)
        return [_leg([CENTER[0] - half, y], [CENTER[0] + half, y], 0.0, v, slot, alt)]
    if geometry == "parallel":
        y = CENTER[1] - rng.uniform(0.0, LANE_SPACING_M)
        t1, x1 = _leg([CENTER[0] - half, y], [CENTER[0] + half, y], 0.0, v, slot, alt)
        t2, x2 = _leg([CENTER[0] + half, y + LANE_SPACING_M], [CENTER[0] - half, y + LANE_SPACING_M],
                      t1[-1] + TURN_S, v, slot, alt)
        return [(t1, x1), (t2, x2)]
    y = CENTER[1] - rng.uniform(0.0, 0.8 * reach)
    x = CENTER[0] - rng.uniform(0.0, 0.8 * reach)
    t1, x1 = _leg([CENTER[0] - half, y], [CENTER[0] + half, y], 0.0, v, slot, alt)
    t2, x2 = _leg([x, CENTER[1] - half], [x, CENTER[1] + half], t1[-1] + TURN_S, v, slot, alt)
    return [(t1, x1), (t2, x2)]


def correlated_information(slots: SlotBatch, channel: ChannelModel, truth, vel, t_ref: float,
                           decorrelation_m: float, samples: int) -> np.ndarray:
    """Fisher information about (x, y, vx, vy) under the simulated Gudmundson shadowing: slot means
    of one vehicle form an AR(1) sequence with rho = exp(-distance moved / decorrelation); the rows
    of the Jacobian are whitened accordingly (each slot's mean has ~ the full per-sample variance)."""
    order = np.lexsort((slots.t_s, slots.vehicle))
    s = slots.take(order)
    tau = s.t_s - t_ref
    g = truth + np.outer(tau, vel) - s.xyz_m[:, :2]
    d2 = np.sum(g * g, axis=1) + s.xyz_m[:, 2] ** 2
    jac = np.column_stack([g / d2[:, None], tau[:, None] * g / d2[:, None]])
    moved = np.r_[np.inf, np.linalg.norm(np.diff(s.xyz_m, axis=0), axis=1) + np.hypot(*vel) * np.diff(s.t_s)]
    moved[np.r_[True, s.vehicle[1:] != s.vehicle[:-1]]] = np.inf
    rho = np.exp(-moved / decorrelation_m)
    within = np.exp(-np.abs(np.subtract.outer(np.arange(samples), np.arange(samples))) *
                    np.median(moved[np.isfinite(moved)]) / samples / decorrelation_m).mean()
    sd = channel.log_range_sigma * math.sqrt(within)
    prev = np.vstack([np.zeros((1, 4)), jac[:-1]])
    white = (jac - rho[:, None] * prev) / (sd * np.sqrt(1.0 - rho**2))[:, None]
    return white.T @ white


def _silence(legs, slots: SlotBatch, slot_s: float) -> Silence:
    """The slots of the legs at which the phone was not heard."""
    t = np.concatenate([t for t, _ in legs])
    x = np.vstack([x for _, x in legs])
    return silence_from_track(t, x, slots.t_s, slot_s=slot_s)


def mmse_applies(fam: Family) -> bool:
    """Whether the posterior-mean floor is computed for the family: walkers under i.i.d.
    shadowing, nominal power, the motion model on (see :mod:`benchmarks.posterior`)."""
    return fam.moving and fam.model_motion and not fam.correlated and not fam.tx_spread_db and fam.geometry != "one_leg"


def run_family(fam: Family, runs: int, seed: int, sc, evidence: str = "all", bar=None, mmse: bool = False,
               maneuver_time_s: float | None = None) -> dict:
    sc = sc.replace(simulation={"correlated_shadowing": fam.correlated, "shadowing_decorrelation_m": 20.0,
                                "tx_power_spread_db": fam.tx_spread_db})
    channel = ChannelModel.from_scenario(sc)
    vmax, reach = sc.people.max_speed_m_s, sc.horizontal_range_m
    prior = prior_information(channel, max_speed_m_s=vmax, model_motion=fam.model_motion,
                              estimate_tx_power=fam.estimate_tx)
    rng = np.random.default_rng(seed)
    err, near, r95, bound, amb, ms, infos, crb2, ideal = [], [], [], [], [], [], [], [], []
    floor_err, floor_ess, track = [], [], []
    mmse = mmse and mmse_applies(fam)
    for k in range(runs):
        if bar is not None:
            bar.step(f"{fam.name} run {k + 1}")
        vel, start = np.zeros(2), CENTER
        if fam.target_y_m is not None:
            vel, start = LAWNMOWER_VELOCITY, np.array([600.0, fam.target_y_m])
        elif fam.moving:
            ang, rad = rng.uniform(0, 2 * np.pi), vmax * math.sqrt(rng.uniform())
            vel = rad * np.array([math.cos(ang), math.sin(ang)])
        world = World.with_people(sc, [start], [vel], seed=seed * 100_003 + k)
        legs = _legs(fam.geometry, rng, reach, sc)
        slots = SlotBatch.concat([world.hear_track(1, t, x) for t, x in legs])
        if len(slots) < 3:
            continue
        quiet = {"all": _silence(legs, slots, sc.channel.slot_s), "heard": Silence.empty()}.get(evidence)
        t0 = time.thread_time()
        opts = {} if maneuver_time_s is None else {"maneuver_time_s": maneuver_time_s}
        est = estimate_emitter(slots, channel, max_speed_m_s=vmax, model_motion=fam.model_motion,
                               estimate_tx_power=fam.estimate_tx, silence=quiet, **opts)
        ms.append(1e3 * (time.thread_time() - t0))
        truth, tvel = world.positions(est.t_ref_s)[0], world.velocities(est.t_ref_s)[0]
        e = float(np.linalg.norm(est.position_xy_m - truth))
        err.append(e)
        near.append(min(e, float(np.linalg.norm(est.mirror.position_xy_m - truth))) if est.mirror else e)
        r95.append(est.radius95_m)
        bound.append(est.annulus_bound_m)
        amb.append(est.ambiguous)
        if fam.correlated:
            info = correlated_information(slots, channel, truth, tvel, est.t_ref_s, 20.0, sc.channel.samples_per_slot)
        else:
            info = data_information(slots, channel, truth, tvel, est.t_ref_s, model_motion=fam.model_motion,
                                    estimate_tx_power=fam.estimate_tx)
        infos.append(info)
        crb2.append(position_rmse_bound_m(info + prior) ** 2)
        ideal.append(_ideal_radius(info + prior))
        # the track of the last pass that heard the phone (the leg flown at the last slot heard)
        x_last = next(x for t, x in reversed(legs) if t[0] <= est.t_ref_s)
        track.append(_distance_to_line(truth, x_last[0, :2], x_last[-1, :2]))
        if mmse:
            pm, ess = rssi_posterior_mean(prepare(slots, channel), est.t_ref_s, estimate_candidates(est), vmax,
                                          np.random.default_rng([seed, k]))
            floor_err.append(float(np.linalg.norm(pm - truth)))
            floor_ess.append(ess)
    err, near, r95, bound = np.array(err), np.array(near), np.array(r95), np.array(bound)
    rmse = float(np.sqrt(np.mean(err**2)))
    vt = position_rmse_bound_m(np.mean(infos, axis=0) + prior)
    under = np.array(track) < LAST_TRACK_M
    away = ~under
    return {
        "family": fam.name, "runs": len(err), "rmse": rmse, "rmse_near": float(np.sqrt(np.mean(near**2))),
        "vt": vt, "ratio": rmse / vt, "eff": float(np.sqrt(np.mean(near**2 / np.array(crb2)))),
        "eff_e": float(np.sqrt(np.mean(err**2 / np.array(crb2)))),
        "p90_e": float(np.percentile(err / np.sqrt(crb2), 90)),
        "r_ideal": float(np.median(r95 / np.array(ideal))),
        "cover95": float(np.mean(err <= r95)), "cover_annulus": float(np.mean(np.nan_to_num(bound, nan=-1) >= err)),
        "ambiguous": float(np.mean(amb)), "median_r95_over_rmse": float(np.median(r95) / rmse),
        "ms": float(np.mean(ms)),
        "need": float(np.quantile(err / np.maximum(r95, 1e-9), 0.95)),
        "mmse": mmse_floor(floor_err) if mmse else math.nan, "ess_min": min(floor_ess, default=math.nan),
        # the walkers who end near the last pass's track (see LAST_TRACK_M) and the others
        "under_share": float(np.mean(under)),
        "under_mse_share": float(np.sum(err[under] ** 2) / max(np.sum(err**2), 1e-12)),
        "ratio_away": float(np.sqrt(np.mean(err[away] ** 2)) / position_rmse_bound_m(
            np.mean(np.array(infos)[away], axis=0) + prior)) if np.any(away) else math.nan,
    }


def _distance_to_line(p, a, b) -> float:
    """Distance of the point p from the line through a and b."""
    u = (b - a) / max(float(np.linalg.norm(b - a)), 1e-9)
    d = p - a
    return float(abs(d[0] * u[1] - d[1] * u[0]))


def _ideal_radius(information: np.ndarray) -> float:
    """The 95 % radius an efficient estimator would report: the circle holding 95 % of the Gaussian
    with the run's own bound (inverse information at the truth) as covariance."""
    try:
        cov = np.linalg.inv(0.5 * (information + information.T))
    except np.linalg.LinAlgError:
        return math.inf
    return radius_of_probability(cov[:2, :2])


def time_1000_slots(sc, repeats: int = 30) -> float:
    """Median solve time [ms] for one moving emitter heard in exactly 1,000 slots (two looks)."""
    channel = ChannelModel.from_scenario(sc)
    world = World.with_people(sc, [CENTER], [[1.0, 0.5]], seed=5)
    legs = _legs("parallel", np.random.default_rng(3), sc.horizontal_range_m, sc)
    slots = SlotBatch.concat([world.hear_track(1, t, x) for t, x in legs])
    slots = SlotBatch.concat([slots, slots]).take(np.arange(1000)) if len(slots) < 1000 else slots.take(np.arange(1000))
    times = []
    for _ in range(repeats):
        t0 = time.thread_time()
        estimate_emitter(slots, channel, max_speed_m_s=sc.people.max_speed_m_s)
        times.append(1e3 * (time.thread_time() - t0))
    return float(np.median(times))


def _maneuver_slots(fam: ManeuverFamily, world: World, rng: np.random.Generator, sc, channel, vmax,
                    evidence: str = "none"):
    """Slots of one maneuver run: two scan lanes around the person, optionally a look pass."""
    v, slot, alt, reach = sc.fleet.speed_m_s, sc.channel.slot_s, sc.fleet.altitude_m, sc.horizontal_range_m
    t0 = rng.uniform(0.0, 600.0)  # the walk's phase
    p0 = world.positions(t0)[0]
    spacing = rng.uniform(0.5, 1.0) * reach
    y1 = p0[1] - rng.uniform(0.0, spacing)
    x0 = p0[0] - rng.uniform(0.0, MISSION_LANE_M)
    t1, x1 = _leg([x0, y1], [x0 + MISSION_LANE_M, y1], t0, v, slot, alt)
    t2, x2 = _leg([x0 + MISSION_LANE_M, y1 + spacing], [x0, y1 + spacing], t1[-1] + TURN_S + spacing / v, v, slot, alt)
    slots = SlotBatch.concat([world.hear_track(1, t1, x1), world.hear_track(1, t2, x2)])
    tracks = [(1, t1, x1), (1, t2, x2)]
    if fam.stage == "lanes" or len(slots) < 3:
        return slots, tracks
    first = estimate_emitter(slots, channel, max_speed_m_s=vmax,
                             silence=_track_silence(tracks, slots, sc.channel.slot_s) if evidence == "all" else
                             (Silence.empty() if evidence == "heard" else None))
    t_look = float(slots.t_s.max()) + rng.uniform(30.0, 180.0)
    aim, _ = first.predict(t_look)
    psi = rng.uniform(0.0, 2 * np.pi)
    u, n = np.array([math.cos(psi), math.sin(psi)]), np.array([-math.sin(psi), math.cos(psi)])
    mid = aim + n * rng.uniform(0.0, 0.5 * reach)
    half = reach + 60.0
    t3, x3 = _leg(mid - half * u, mid + half * u, t_look - half / v, v, slot, alt)
    return SlotBatch.concat([slots, world.hear_track(2, t3, x3)]), tracks + [(2, t3, x3)]  # another vehicle looks


def _track_silence(tracks, slots: SlotBatch, slot_s: float) -> Silence:
    """Silences of (vehicle, times, positions) tracks, each vehicle against its own slots heard."""
    parts = [silence_from_track(t, x, slots.t_s[slots.vehicle == v], slot_s=slot_s) for v, t, x in tracks]
    return Silence(np.concatenate([p.t_s for p in parts]), np.vstack([p.xyz_m for p in parts]))


def run_maneuver_family(fam: ManeuverFamily, runs: int, seed: int, sc, bar=None, evidence: str = "none",
                        maneuver_time_s: float | None = None) -> dict:
    if fam.area_m is not None:
        sc = sc.replace(area={"width_m": fam.area_m[0], "height_m": fam.area_m[1]})
    channel = ChannelModel.from_scenario(sc)
    vmax = sc.people.max_speed_m_s
    rng = np.random.default_rng(seed)
    rows = {"new": [], "cv": []}
    span = []
    for k in range(runs):
        if bar is not None:
            bar.step(f"{fam.name} run {k + 1}")
        world = World(sc, seed=seed * 100_003 + k, people=1, motion="random_waypoint", horizon_s=1800.0)
        slots, tracks = _maneuver_slots(fam, world, rng, sc, channel, vmax, evidence)
        if len(slots) < 3:
            continue
        quiet = {"all": _track_silence(tracks, slots, sc.channel.slot_s), "heard": Silence.empty()}.get(evidence)
        span.append(float(slots.t_s.max() - slots.t_s.min()))
        for key, tm in (("new", maneuver_time_s), ("cv", math.inf)):
            opts = {} if tm is None else {"maneuver_time_s": tm}
            est = estimate_emitter(slots, channel, max_speed_m_s=vmax, silence=quiet, **opts)
            out = [float(np.linalg.norm(est.position_xy_m - world.positions(est.t_ref_s)[0])), est.radius95_m,
                   float(est.ambiguous)]
            for dt in PREDICT_S:
                p, r = est.predict(est.t_ref_s + dt)
                out += [float(np.linalg.norm(p - world.positions(est.t_ref_s + dt)[0])), r]
            rows[key].append(out)
    res = {"family": fam.name, "runs": len(span), "span": float(np.median(span))}
    for key, a in rows.items():
        a = np.array(a)
        res[key] = {
            "rmse": float(np.sqrt(np.mean(a[:, 0] ** 2))), "median_err": float(np.median(a[:, 0])),
            "ambiguous": float(np.mean(a[:, 2])),
            "cover": [float(np.mean(a[:, c] <= a[:, c + 1])) for c in (0, 3, 5)],
            "median_r": [float(np.median(a[:, c + 1])) for c in (0, 3, 5)],
            # the factor the radii would need for exactly 95 % coverage (1 = calibrated, above 1:
            # too small, below 1: larger than needed)
            "need": float(np.quantile(a[:, 0] / np.maximum(a[:, 1], 1e-9), 0.95)),
        }
    return res


def _print_floors(rows: list[dict], mmse: bool) -> None:
    print(f"\nwalkers under i.i.d. shadowing: where the error beyond the bound is. 'last track': the runs whose walker "
          f"ends within {LAST_TRACK_M:g} m of the track of the last pass that heard them (share of runs, share of "
          f"the squared error); "
          f"'ratio away': RMSE / BCRB over the other runs. " +
          ("'MMSE': the RMSE of the posterior mean of the RSSI alone on the same runs, the least any estimator of "
           "the RSSI can reach (velocity uniform over |v| <= v_max as drawn, position flat, no hearing evidence; "
           "benchmarks/posterior.py)" if mmse else "(--mmse adds the RSSI alone's attainable floor)"))
    head = (f"{'family':34s} {'runs':>4s} {'RMSE m':>7s} {'BCRB m':>7s} {'ratio':>6s} {'last track':>11s} "
            f"{'ratio away':>10s}")
    if mmse:
        head += f" {'MMSE m':>7s} {'MMSE/BCRB':>9s} {'RMSE/MMSE':>9s} {'ESS min':>7s}"
    print(head)
    print("-" * len(head))
    for r in rows:
        line = (f"{r['family']:34s} {r['runs']:4d} {r['rmse']:7.2f} {r['vt']:7.2f} {r['ratio']:6.2f} "
                f"{r['under_share']:5.2f} {r['under_mse_share']:5.2f} {r['ratio_away']:10.2f}")
        if mmse:
            line += (f" {r['mmse']:7.2f} {r['mmse'] / r['vt']:9.2f} {r['rmse'] / r['mmse']:9.2f} "
                     f"{r['ess_min']:7.0f}")
        print(line)


def main(args: argparse.Namespace) -> int:
    from uavloc_gcs.estimation import estimate as estimate_module
    from uavloc_gcs.examples import scenario_path

    if args.maneuver_time is not None and not args.maneuver_time > 0:
        print(f"uavloc bench localize: --maneuver-time must be a positive number of seconds, got {args.maneuver_time}",
              file=sys.stderr)
        return 2
    for name in args.switch:
        setattr(estimate_module, *ESTIMATOR_SWITCHES[name])
        print(f"estimator switch {name}: estimate.{ESTIMATOR_SWITCHES[name][0]} = {ESTIMATOR_SWITCHES[name][1]!r}")
    if args.emission == "bursts":
        from .localize_bursts import BURST_FAMILIES, print_burst_table

        bfams = [f for f in BURST_FAMILIES if not args.family or any(s in f.name for s in args.family)]
        _some_family(bfams, BURST_FAMILIES, args.family)
        print(f"uavloc bench localize --emission bursts: {args.runs} runs per family")
        print_burst_table(bfams, args.runs, args.seed, Progress(args.runs * len(bfams)), args.mmse,
                          args.frames_prior == "world", exposure=not args.no_exposure)
        return 0
    sc = load_scenario(scenario_path(args.scenario))
    fams = [f for f in FAMILIES if not args.family or any(s in f.name for s in args.family)]
    mfams = [f for f in MANEUVER_FAMILIES if not args.family or any(s in f.name for s in args.family)]
    _some_family(fams + mfams, FAMILIES + MANEUVER_FAMILIES, args.family)
    bar = Progress(args.runs * (len(fams) + len(mfams)))
    print(f"uavloc bench localize: {args.runs} runs per family, paper channel (eta 2, sigma 4 dB, 10 samples/slot), "
          f"h {sc.fleet.altitude_m:g} m, R {sc.horizontal_range_m:.1f} m, v_max {sc.people.max_speed_m_s} m/s")
    if fams:
        head = f"{'family':34s} {'runs':>4s} {'RMSE m':>7s} {'near m':>7s} {'BCRB m':>7s} {'ratio':>6s} " \
               f"{'eff':>6s} {'effE':>5s} {'p90E':>5s} {'cov95':>6s} {'covAnn':>6s} {'ambig':>6s} " \
               f"{'r95/RMSE':>8s} {'r/ideal':>7s} {'need':>5s} {'ms':>6s}"
        print(head)
        print("-" * len(head))
        floors = []
        for fam in fams:
            r = run_family(fam, args.runs, args.seed + 1000 * FAMILIES.index(fam), sc, args.evidence, bar, args.mmse,
                           args.maneuver_time)
            if mmse_applies(fam):
                floors.append(r)
            print(f"{r['family']:34s} {r['runs']:4d} {r['rmse']:7.2f} {r['rmse_near']:7.2f} {r['vt']:7.2f} "
                  f"{r['ratio']:6.2f} {r['eff']:6.2f} {r['eff_e']:5.2f} {r['p90_e']:5.2f} "
                  f"{r['cover95']:6.2f} {r['cover_annulus']:6.2f} {r['ambiguous']:6.2f} "
                  f"{r['median_r95_over_rmse']:8.2f} {r['r_ideal']:7.2f} {r['need']:5.2f} {r['ms']:6.1f}")
        if floors:
            _print_floors(floors, args.mmse)
    if mfams:
        print("\nmaneuvering people (random_waypoint); coverage / median radius [m] at the last slot, "
              "and predicted +30 s, +60 s; 'need' = the factor the radii need for 95 % coverage "
              "(the 95th percentile of error / radius: 1 calibrated, below 1 larger than needed); "
              "'CV' = pure constant-velocity model")
        head = f"{'family':30s} {'runs':>4s} {'span s':>6s} {'RMSE m':>7s} {'med e':>6s} {'ambig':>5s} {'cov':>5s} {'r95':>6s} " \
               f"{'need':>5s} {'cov30':>5s} {'r30':>6s} {'cov60':>5s} {'r60':>6s} | {'CV RMSE':>7s} {'cov':>5s} {'r95':>5s} " \
               f"{'cov30':>5s} {'cov60':>5s}"
        print(head)
        print("-" * len(head))
        for fam in mfams:
            r = run_maneuver_family(fam, args.runs, args.seed + 5000 + 1000 * MANEUVER_FAMILIES.index(fam), sc, bar,
                                    args.evidence, args.maneuver_time)
            n, c = r["new"], r["cv"]
            print(f"{r['family']:30s} {r['runs']:4d} {r['span']:6.0f} {n['rmse']:7.2f} {n['median_err']:6.2f} {n['ambiguous']:5.2f} "
                  f"{n['cover'][0]:5.2f} {n['median_r'][0]:6.1f} {n['need']:5.2f} {n['cover'][1]:5.2f} {n['median_r'][1]:6.1f} "
                  f"{n['cover'][2]:5.2f} {n['median_r'][2]:6.1f} | {c['rmse']:7.2f} {c['cover'][0]:5.2f} "
                  f"{c['median_r'][0]:5.1f} {c['cover'][1]:5.2f} {c['cover'][2]:5.2f}")
    if not args.family:
        print(f"\nsolve time, one emitter, 1,000 slots: {time_1000_slots(sc):.1f} ms (median of 30)")
    return 0
