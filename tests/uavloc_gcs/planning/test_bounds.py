"""The makespan lower bound: valid below every plan we can find, and tight where it should be."""

import numpy as np
import pytest

from uavloc_gcs.planning import RoutingProblem, Target, VehicleState, lower_bound_s, solve
from uavloc_gcs.planning.bounds import _prim_mst_m

from .helpers import random_problem


def test_single_target_bound_is_exact():
    # One vehicle, one disk: start -> disk edge -> home is the optimum and the bound.
    p = RoutingProblem((VehicleState("u", (0.0, 0.0), (0.0, 0.0), 1e6),),
                       (Target("a", (500.0, 0.0), (0.0, 0.0), 100.0),), 25.0)
    assert lower_bound_s(p) == pytest.approx(2 * 400 / 25)
    assert solve(p).fun == pytest.approx(lower_bound_s(p))


def test_mst_term_counts_gaps_between_disks():
    d = np.array([[0, 1, 4], [1, 0, 2], [4, 2, 0]], dtype=float)
    assert _prim_mst_m(d) == 3.0
    # 20 disks of radius 5 on a circle of radius 200 around the depot, one vehicle: the tree term
    # (19 gaps between neighbours + one depot link) beats the farthest round trip (390 m).
    ang = 2 * np.pi * np.arange(20) / 20
    tg = tuple(Target(f"t{i}", (200 * np.cos(a), 200 * np.sin(a)), (0.0, 0.0), 5.0) for i, a in enumerate(ang))
    p = RoutingProblem((VehicleState("u", (0.0, 0.0), (0.0, 0.0), 1e7),), tg, 20.0)
    gap = 2 * 200 * np.sin(np.pi / 20) - 10
    assert lower_bound_s(p) == pytest.approx((19 * gap + 195) / 20)
    assert solve(p, rng=0, time_limit_s=0.3).fun >= lower_bound_s(p)


@pytest.mark.parametrize("speed", [0.0, 1.5])
@pytest.mark.parametrize("seed", [1, 2])
def test_bound_below_found_plans(seed, speed):
    p = random_problem(15, 3, seed=seed, speed_person=speed)
    lb = lower_bound_s(p)
    res = solve(p, rng=0, time_limit_s=0.3)
    assert 0 < lb <= res.fun
    if speed:
        # Movement can only make the bound smaller (the disks may come closer).
        static = RoutingProblem(p.vehicles, tuple(Target(t.id, t.xy_m, (0.0, 0.0), t.radius_m)
                                                  for t in p.targets), p.speed_m_s)
        assert lb <= lower_bound_s(static)


@pytest.mark.parametrize("seed,speed", [(3, 0.5), (4, 1.5), (5, 8.0)])
def test_moving_bound_is_the_fixed_point_of_the_static_bound(seed, speed):
    """The per-term root search gives the fixed point T* = g(T*) of the whole static bound g
    (found here by plain bisection), from below, within its tolerance."""
    from uavloc_gcs.planning.bounds import _static_bound_s

    p = random_problem(30, 3, seed=seed, speed_person=speed)
    radii, v = p.radii_m, np.linalg.norm(p.velocities_m_s, axis=1)
    lo, hi = 0.0, _static_bound_s(p, radii)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _static_bound_s(p, radii + v * mid) > mid else (lo, mid)
    lb = lower_bound_s(p)
    assert lo - 1e-5 <= lb <= hi + 1e-9
    assert _static_bound_s(p, radii + v * lb) >= lb - 1e-9  # still a valid bound: T* >= lb
