"""Instance builders and a plan checker shared by the planner tests."""

from __future__ import annotations

import numpy as np

from uavloc_gcs.planning import Plan, RoutingProblem, Target, VehicleState


def random_problem(n: int, m: int = 2, *, seed: int = 0, r_range=(20.0, 80.0), speed_person=0.0,
                   energy_j: float = 1e6, size=(1120.0, 640.0)) -> RoutingProblem:
    rng = np.random.default_rng(seed)
    half = np.array(size) / 2
    xy = rng.uniform(-half, half, (n, 2))
    ang = rng.uniform(0, 2 * np.pi, n)
    targets = tuple(
        Target(f"p{i}", (float(xy[i, 0]), float(xy[i, 1])),
               (float(speed_person * np.cos(ang[i])), float(speed_person * np.sin(ang[i]))),
               float(rng.uniform(*r_range)))
        for i in range(n))
    vehicles = tuple(VehicleState(f"uav{k}", (0.0, 0.0), (0.0, 0.0), energy_j) for k in range(m))
    return RoutingProblem(vehicles, targets, 25.0)


def check_plan(problem: RoutingProblem, plan: Plan, *, tol_m: float = 1e-6) -> None:
    """Every target once; access points in their (moving) disks at the access times; durations
    and energies consistent with the polyline; energy within budget; makespan >= lower bound."""
    ids = sorted(t for r in plan.routes for t in r.target_ids)
    assert ids == sorted(t.id for t in problem.targets)
    tmap = {t.id: t for t in problem.targets}
    vmap = {v.id: v for v in problem.vehicles}
    assert sorted(r.vehicle_id for r in plan.routes) == sorted(vmap)
    for r in plan.routes:
        v = vmap[r.vehicle_id]
        pts = np.asarray(r.access_points_xy_m).reshape(-1, 2)
        line = np.vstack([v.start_xy_m, pts, v.home_xy_m])
        seg = np.linalg.norm(np.diff(line, axis=0), axis=1)
        length = seg.sum()
        assert abs(r.duration_s - length / problem.speed_m_s) < 1e-6
        t = problem.t0_s + np.cumsum(seg)[:-1] / problem.speed_m_s
        np.testing.assert_allclose(r.access_times_s, t, atol=1e-6)
        for tid, q, ts in zip(r.target_ids, pts, t):
            tg = tmap[tid]
            c = np.array(tg.xy_m) + np.array(tg.velocity_m_s) * (ts - problem.t0_s)
            assert np.linalg.norm(q - c) <= tg.radius_m + tol_m, (tid, np.linalg.norm(q - c), tg.radius_m)
        assert r.energy_j <= v.energy_j * (1 + 1e-9)
        assert abs(r.energy_j - problem.power.leg_energy_j(length, problem.speed_m_s)) < 1e-6 * max(1, r.energy_j)
    assert abs(plan.makespan_s - max(r.duration_s for r in plan.routes)) < 1e-9
    assert plan.makespan_s >= plan.lower_bound_s - 1e-9
