"""Targets with a service time (orbit looks): the makespan, the later access times and the energy
count it; without services the plan is what it was."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from uavloc_gcs.errors import ConfigError, InfeasibleError
from uavloc_gcs.planning import RoutingProblem, Target, VehicleState, solve
from uavloc_gcs.planning.problem import check_reachable, validate

from .helpers import random_problem


def _line(service_s=0.0, service_j=0.0, energy_j=1e6):
    """One vehicle, two static targets east of home on a line: the route is fixed."""
    v = (VehicleState("1", (0.0, 0.0), (0.0, 0.0), energy_j),)
    t = (Target("a", (250.0, 0.0), (0.0, 0.0), 0.0, service_s, service_j),
         Target("b", (500.0, 0.0), (0.0, 0.0), 0.0))
    return RoutingProblem(v, t, 25.0)


def test_service_adds_to_makespan_later_access_times_and_energy():
    base = solve(_line(), method="epso", rng=np.random.default_rng(0), max_iter=20, time_limit_s=5).plan
    p = _line(120.0, 15_000.0)
    plan = solve(p, method="epso", rng=np.random.default_rng(0), max_iter=20, time_limit_s=5).plan
    assert base.makespan_s == pytest.approx(1000 / 25.0)
    assert plan.makespan_s == pytest.approx(1000 / 25.0 + 120.0)
    r0, r = base.routes[0], plan.routes[0]
    assert r.target_ids == ("a", "b")
    assert r.access_times_s[0] == pytest.approx(r0.access_times_s[0])  # arrival at the orbit itself
    assert r.access_times_s[1] == pytest.approx(r0.access_times_s[1] + 120.0)  # after it
    assert r.energy_j == pytest.approx(r0.energy_j + 15_000.0)


def test_service_energy_counts_in_the_energy_check():
    e_flight = _line().energy_per_m_j * 1000.0
    p = _line(120.0, 15_000.0, energy_j=e_flight + 10_000.0)  # enough to fly, not to orbit
    with pytest.raises(InfeasibleError, match="120 s look"):
        check_reachable(p)
    res = solve(_line(120.0, 15_000.0, energy_j=e_flight + 16_000.0), method="epso",
                rng=np.random.default_rng(0), max_iter=20, time_limit_s=5)
    assert res.success


def test_services_move_the_assignment_and_zero_service_changes_nothing():
    p = random_problem(8, 2, seed=3)
    a = solve(p, method="epso", rng=np.random.default_rng(1), max_iter=30, time_limit_s=5).plan
    same = replace(p, targets=tuple(replace(t, service_s=0.0) for t in p.targets))
    b = solve(same, method="epso", rng=np.random.default_rng(1), max_iter=30, time_limit_s=5).plan
    assert a.makespan_s == pytest.approx(b.makespan_s)
    heavy = replace(p, targets=tuple(replace(t, service_s=200.0 if i < 2 else 0.0) for i, t in enumerate(p.targets)))
    c = solve(heavy, method="epso", rng=np.random.default_rng(1), max_iter=60, time_limit_s=5).plan
    owner = {tid: r.vehicle_id for r in c.routes for tid in r.target_ids}
    assert owner["p0"] != owner["p1"]  # the two long looks are shared out, not stacked on one vehicle
    for r in c.routes:
        svc = sum(200.0 for tid in r.target_ids if tid in ("p0", "p1"))
        assert r.duration_s <= c.makespan_s + 1e-6
        assert r.duration_s >= svc


def test_negative_service_is_refused():
    with pytest.raises(ConfigError, match="service time"):
        validate(_line(-1.0))
