"""What a mission file shows on a map, in local metres: the route through its real positions,
home, fences and rally points. Shared by the terminal picture and the PNG of ``uavloc preview``.

Only real positions are drawn. Mission Planner and ArduPilot write lat/lon 0, 0 on takeoff, DO_*
and RTL items to mean "here"; such an item is no place: a takeoff climbs at home, a land without
a position lands where the vehicle is, RTL flies back to home, DO_* items are not on the map. A
plan whose home is 0, 0 (or null) has no home to draw.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..geo import LocalFrame
from ..mission import NAV_RETURN_TO_LAUNCH, ROUTE_COMMANDS, TAKEOFF_COMMANDS, MissionPlan

__all__ = ["MissionView", "mission_view", "circle_ring"]


@dataclass
class MissionView:
    origin: tuple[float, float] | None  # lat, lon of (0, 0): home, else the first position drawn
    has_home: bool
    route_xy: np.ndarray  # (N, 2) the flight path, home first when known
    points_xy: np.ndarray  # (M, 2) the items that are places, in order
    marks: tuple[str, ...]  # one character per point: T takeoff, L land, o other
    positions: int  # route items (waypoints, loiters, land, takeoff) with a real position
    placeholders: int  # items with the 0, 0 "here" placeholder in a global frame
    fences: list = field(default_factory=list)  # (inclusion, (K, 2) ring)
    circles: list = field(default_factory=list)  # (inclusion, (x, y), radius_m)
    rally_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))


def circle_ring(centre_xy, radius_m: float, n: int = 48) -> np.ndarray:
    a = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    return np.column_stack([centre_xy[0] + radius_m * np.cos(a), centre_xy[1] + radius_m * np.sin(a)])


def mission_view(plan: MissionPlan) -> MissionView:
    has_home = not (math.isnan(plan.home_lat_deg) or math.isnan(plan.home_lon_deg)
                    or (plan.home_lat_deg == 0.0 and plan.home_lon_deg == 0.0))
    placed = [it for it in plan.items if it.has_position]
    placeholders = sum(1 for it in plan.items if it.is_positional and it.lat_deg == 0.0 and it.lon_deg == 0.0)
    candidates = ([(plan.home_lat_deg, plan.home_lon_deg)] if has_home else []) \
        + [(it.lat_deg, it.lon_deg) for it in placed] \
        + [ring[0] for _, ring in plan.geofence_polygons if ring] \
        + [c for _, c, _ in plan.geofence_circles] + [(p[0], p[1]) for p in plan.rally_points]
    if not candidates:
        return MissionView(None, False, np.zeros((0, 2)), np.zeros((0, 2)), (), 0, placeholders)
    origin = candidates[0]
    frame = LocalFrame(*origin)

    def local(latlon) -> np.ndarray:
        arr = np.asarray(latlon, dtype=float).reshape(-1, 2)
        return frame.to_local_xy(arr) if len(arr) else np.zeros((0, 2))

    route, points, marks, real = ([np.zeros(2)] if has_home else []), [], [], 0
    for it in plan.items:
        if it.has_position and (it.command in ROUTE_COMMANDS or it.command in TAKEOFF_COMMANDS):
            real += 1
            xy = local([(it.lat_deg, it.lon_deg)])[0]
            route.append(xy)
            points.append(xy)
            marks.append("T" if it.command in TAKEOFF_COMMANDS else "L" if it.command in (21, 85) else "o")
        elif it.command in TAKEOFF_COMMANDS and has_home:
            points.append(np.zeros(2))  # takes off at home
            marks.append("T")
        elif it.command == NAV_RETURN_TO_LAUNCH and has_home:
            route.append(np.zeros(2))
    return MissionView(
        origin, has_home,
        np.array(route).reshape(-1, 2), np.array(points).reshape(-1, 2), tuple(marks), real, placeholders,
        fences=[(inc, local(ring)) for inc, ring in plan.geofence_polygons],
        circles=[(inc, tuple(local([c])[0]), r) for inc, c, r in plan.geofence_circles],
        rally_xy=local([(p[0], p[1]) for p in plan.rally_points]),
    )
