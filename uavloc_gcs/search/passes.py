"""Another pass over the cells below the POD target, while a vehicle's energy allows.

After the scans the achieved POD of every cell (:mod:`.coverage`, from the flown telemetry) may be
below the target; :func:`add_passes` gives the vehicles with energy left east-west lanes over those
cells (:func:`pass_lanes`, serpentine from south to north), flown after their looks and before
home, at most ``coverage.MAX_PASS_ROUNDS`` rounds; :func:`passes_wanted` says whether another round
may raise it. What no vehicle had the energy for stays below the target and is reported.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from . import coverage
from .coverage import Coverage, pod_target

LANE_FILL = 0.9  # pass lanes are this fraction of two hearing ranges apart


@dataclass(frozen=True)
class PassPlan:
    """Pass lanes per vehicle {vehicle id: (k, 2) waypoints, flown after its looks, before home},
    and the lanes no vehicle had the energy for (count; their cells stay below the target)."""

    waypoints: dict
    lanes: int
    unassigned: int
    below_target_m2: float


def pass_lanes(cov: Coverage, target: float) -> list[np.ndarray]:
    """East-west lanes (each (2, 2): west end, east end) over the cells whose live POD is below
    ``target``, LANE_FILL x 2 hearing ranges apart, serpentine from south to north."""
    pod = cov.pod(1)
    low = pod < target
    if not np.any(low):
        return []
    xy = cov.grid.xy_m[low]
    h = cov.grid.cell_m / 2
    spacing = max(cov.grid.cell_m, 2.0 * LANE_FILL * cov.sc.horizontal_range_m)
    y0, y1 = float(xy[:, 1].min()), float(xy[:, 1].max())
    n = max(1, math.ceil((y1 - y0 + 2 * h) / spacing))
    ys = np.linspace(y0, y1, n) if n > 1 else np.array([(y0 + y1) / 2])
    lanes = []
    for i, y in enumerate(ys):
        band = xy[np.abs(xy[:, 1] - y) <= max(spacing / 2, h) + 1e-6]
        if not len(band):
            continue
        a, b = float(band[:, 0].min()) - h, float(band[:, 0].max()) + h
        lane = np.array([[a, y], [b, y]]) if i % 2 == 0 else np.array([[b, y], [a, y]])
        lanes.append(lane)
    return lanes


def plan_passes(cov: Coverage, tasks: list, vehicles: list, *, speed_m_s: float, power, target: float) -> PassPlan:
    """Give the lanes of :func:`pass_lanes` to the vehicles with the energy for them: lane by lane,
    the vehicle whose route grows least, if the route (its looks, the passes so far, the lane, then
    home) stays within its usable energy. ``tasks``: the looks planned for each vehicle
    (``policy.VehicleTask``: waypoints ending with home); ``vehicles``: ``planning.VehicleState``."""
    lanes = pass_lanes(cov, target)
    below = float(np.sum(cov.pod(1) < target) * cov.grid.cell_area_m2)
    if not lanes:
        return PassPlan({}, 0, 0, below)
    state = {str(v.id): v for v in vehicles}
    routes, ends, used = {}, {}, {}
    for task in tasks:
        v = state.get(str(task.vehicle_id))
        if v is None:
            continue
        pts = np.vstack([np.asarray(v.start_xy_m, float).reshape(1, 2),
                         np.asarray(task.waypoints_xy_m, float).reshape(-1, 2)[:-1]])
        routes[v.id] = []
        ends[v.id] = pts[-1]
        used[v.id] = float(power.leg_energy_j(_length(pts), speed_m_s))
    home = {v.id: np.asarray(v.home_xy_m, float).reshape(2) for v in vehicles}
    unassigned = 0
    for lane in lanes:
        best = None
        for vid, end in ends.items():
            for seg in (lane, lane[::-1]):
                extra = np.linalg.norm(seg[0] - end) + _length(seg)
                total = used[vid] + float(power.leg_energy_j(extra + np.linalg.norm(seg[-1] - home[vid]), speed_m_s))
                if total <= state[vid].energy_j and (best is None or extra < best[0]):
                    best = (extra, vid, seg)
        if best is None:
            unassigned += 1
            continue
        extra, vid, seg = best
        routes[vid].append(seg)
        used[vid] += float(power.leg_energy_j(extra, speed_m_s))
        ends[vid] = seg[-1]
    waypoints = {vid: np.vstack(segs) for vid, segs in routes.items() if segs}
    return PassPlan(waypoints, len(lanes), unassigned, below)


def _length(pts: np.ndarray) -> float:
    pts = np.asarray(pts, float).reshape(-1, 2)
    return float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1))) if len(pts) > 1 else 0.0


def passes_wanted(policy) -> bool:
    """Whether ``policy``'s coverage has cells below the POD target that another pass may still
    raise (fewer than coverage.MAX_PASS_ROUNDS rounds planned, the last one not refused for energy)."""
    cov = getattr(policy, "coverage", None)
    if cov is None or cov.passes_exhausted or cov.pass_rounds >= coverage.MAX_PASS_ROUNDS:
        return False
    return bool(np.any(cov.pod_recent() < pod_target(cov.sc)))


def add_passes(policy, t_s: float, vehicles: list, plan):
    """``plan`` (policy.SearchPlan) with passes over the cells below the POD target appended to the
    vehicles' looks, where their energy allows (:func:`plan_passes`); unchanged when none are
    wanted. A round that can give no lane to any vehicle ends the passes (``passes_exhausted``)."""
    if not passes_wanted(policy):
        return plan
    cov = policy.coverage
    sc = policy.scenario
    speed = policy.speed_m_s
    target = pod_target(sc)
    pp = plan_passes(cov, list(plan.tasks), vehicles, speed_m_s=speed, power=sc.power_model, target=target)
    cov.last_passes = pp
    if not pp.waypoints:
        cov.passes_exhausted = pp.lanes > 0
        return plan
    # a round counts once its passes should have been flown (the last round's ETA is past): the
    # replans while a vehicle flies its passes (a report, a look done, a late upload) re-plan the
    # same round instead of using up the cap -- under load there are many of them
    new_round = cov._round_end_s is None or t_s >= cov._round_end_s
    if new_round:
        cov.pass_rounds += 1
    tasks = []
    for task in plan.tasks:
        lanes = pp.waypoints.get(str(task.vehicle_id))
        if lanes is None:
            tasks.append(task)
            continue
        pts = np.asarray(task.waypoints_xy_m, float).reshape(-1, 2)
        route = np.vstack([pts[:-1], lanes, pts[-1:]])
        start = next((np.asarray(v.start_xy_m, float) for v in vehicles if str(v.id) == str(task.vehicle_id)),
                     pts[0])
        eta = t_s + _length(np.vstack([start.reshape(1, 2), route])) / speed
        extra = {}
        if getattr(task, "orbits", None) is not None:  # one per look point (search/orbit.py): passes fly none
            extra["orbits"] = tuple(task.orbits) + (None,) * len(lanes)
        tasks.append(replace(task, waypoints_xy_m=route, eta_s=max(task.eta_s, eta), **extra))
    if new_round:  # fixed when the round is planned: replans within it never push its end (else a
        # search replanning every few seconds would never reach the next round, nor its end)
        cov._round_end_s = max((task.eta_s for task in tasks if str(task.vehicle_id) in pp.waypoints), default=t_s)
    makespan = max((task.eta_s for task in tasks), default=t_s) - t_s
    return replace(plan, tasks=tuple(tasks), makespan_s=makespan)


