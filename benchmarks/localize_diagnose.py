"""Where the estimator's excess error for walking people comes from (issue 12).

``python -m benchmarks.localize_diagnose [RUNS] [FAMILY ...]`` flies the families of
:mod:`benchmarks.localize` (default: two parallel / crossing legs and the lawnmower at y = 130 m,
moving people) and estimates every run with one suspect switched off or replaced at a time: the
maneuver noise (pure CV), the optimizer starts (an extra start at the truth), the reference time
(mid-data instead of the last slot, against the bound at that time), the velocity prior (0.5, 0.8,
2 v_max) and the hearing evidence (the legs' silences). Per variant: RMSE, "near" (to the nearer
mirror candidate), the per-run efficiency sqrt(mean((e_k / CRB_k)^2)) with the reported and the
mirror-resolved error, the median and 90th percentile of e_k / CRB_k, coverage and ambiguity.
"""

from __future__ import annotations

import math
import sys

import numpy as np

import uavloc_gcs.estimation.fit as fit
from benchmarks import localize as bench
from uavloc_gcs.estimation import Estimate, data_information, estimate_emitter, position_rmse_bound_m
from uavloc_gcs.estimation import prior_information
from uavloc_gcs.estimation.model import ChannelModel
from uavloc_gcs.observations import SlotBatch
from uavloc_gcs.examples import scenario_path
from uavloc_gcs.scenario import load_scenario


def _default(slots, ch, vmax, truth, vel, t_last, legs):
    return estimate_emitter(slots, ch, max_speed_m_s=vmax)


def _cv(slots, ch, vmax, truth, vel, t_last, legs):
    return estimate_emitter(slots, ch, max_speed_m_s=vmax, maneuver_time_s=math.inf)


def _truth_start(slots, ch, vmax, truth, vel, t_last, legs):
    return estimate_emitter(slots, ch, max_speed_m_s=vmax, previous=Estimate(1, "ok", t_last, truth, vel, np.eye(4)))


def _mid(slots, ch, vmax, truth, vel, t_last, legs):
    return estimate_emitter(slots, ch, max_speed_m_s=vmax, t_ref_s=float(np.median(slots.t_s)))


def _prior(fraction):
    def run(slots, ch, vmax, truth, vel, t_last, legs):
        old = fit.VELOCITY_PRIOR_FRACTION
        fit.VELOCITY_PRIOR_FRACTION = fraction
        try:
            return estimate_emitter(slots, ch, max_speed_m_s=vmax)
        finally:
            fit.VELOCITY_PRIOR_FRACTION = old
    return run


def _silence(slots, ch, vmax, truth, vel, t_last, legs):
    return estimate_emitter(slots, ch, max_speed_m_s=vmax, silence=bench._silence(legs, slots, 0.025))


VARIANTS = {"estimator": _default, "pure CV": _cv, "start at truth": _truth_start, "t_ref mid-data": _mid,
            "prior 0.5": _prior(0.5), "prior 0.8": _prior(0.8), "prior 2.0": _prior(2.0), "silences": _silence}
DEFAULT_FAMILIES = ("two parallel, moving", "crossing, moving", "lawnmower y=130, moving")


def run(family: str, runs: int, seed: int = 7) -> None:
    sc = load_scenario(scenario_path("paper"))
    fam = next(f for f in bench.FAMILIES if f.name == family)
    sc = sc.replace(simulation={"correlated_shadowing": fam.correlated, "shadowing_decorrelation_m": 20.0})
    ch = ChannelModel.from_scenario(sc)
    vmax, reach = sc.people.max_speed_m_s, sc.horizontal_range_m
    prior = prior_information(ch, max_speed_m_s=vmax)
    rng = np.random.default_rng(seed)
    rows = {k: [] for k in VARIANTS}
    for k in range(runs):
        vel, start = np.zeros(2), bench.CENTER
        if fam.target_y_m is not None:
            vel, start = bench.LAWNMOWER_VELOCITY, np.array([600.0, fam.target_y_m])
        elif fam.moving:
            ang, rad = rng.uniform(0, 2 * np.pi), vmax * math.sqrt(rng.uniform())
            vel = rad * np.array([math.cos(ang), math.sin(ang)])
        world = bench.World.with_people(sc, [start], [vel], seed=seed * 100_003 + k)
        legs = bench._legs(fam.geometry, rng, reach, sc)
        slots = SlotBatch.concat([world.hear_track(1, t, x) for t, x in legs])
        if len(slots) < 3:
            continue
        t_last = float(slots.t_s.max())
        truth, tvel = world.positions(t_last)[0], world.velocities(t_last)[0]
        for name, variant in VARIANTS.items():
            est = variant(slots, ch, vmax, truth, tvel, t_last, legs)
            tr = world.positions(est.t_ref_s)[0]
            crb = position_rmse_bound_m(data_information(slots, ch, tr, tvel, est.t_ref_s) + prior)
            e = float(np.linalg.norm(est.position_xy_m - tr))
            near = min(e, float(np.linalg.norm(est.mirror.position_xy_m - tr))) if est.mirror else e
            rows[name].append((e, near, crb, est.radius95_m, est.ambiguous))
    print(f"{family}: {runs} runs, seed {seed}")
    print(f"  {'variant':16s} {'RMSE':>6s} {'near':>6s} {'eff':>5s} {'effN':>5s} {'med':>5s} {'p90':>5s} {'cov':>5s} {'ambig':>5s}")
    for name, a in rows.items():
        a = np.array(a)
        e, near, c = a[:, 0], a[:, 1], a[:, 2]
        print(f"  {name:16s} {np.sqrt(np.mean(e ** 2)):6.2f} {np.sqrt(np.mean(near ** 2)):6.2f} "
              f"{np.sqrt(np.mean((e / c) ** 2)):5.2f} {np.sqrt(np.mean((near / c) ** 2)):5.2f} "
              f"{np.median(e / c):5.2f} {np.percentile(e / c, 90):5.2f} {np.mean(e <= a[:, 3]):5.2f} {np.mean(a[:, 4]):5.2f}")


def main(argv: list[str]) -> int:
    runs = int(argv[0]) if argv else 60
    for family in argv[1:] or DEFAULT_FAMILIES:
        run(family, runs)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
