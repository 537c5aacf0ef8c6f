"""The mission of a vehicle's looks: fly-bys and orbits (search/orbit.py), each at its own height.

A look flies at its height (``OrbitLook.alt_m``, or ``look_alts_m`` per look; None: the transit
altitude ``alt_m``, the survey's): the vehicle arrives at the look's entry point at the transit
altitude, goes straight down there, flies the look (a fly-by's point, an orbit's ring or
NAV_LOITER_TURNS) at its height, and goes straight back up where the look ended before transiting
on (mission.at_look_height / climb_back; uavloc_gcs/heights.py says what that costs). A look below
``floor_m`` is refused (without a floor, below the transit altitude). With no heights asked the
mission is item for item what it was before heights existed.

Moved here from search/orbit.py (which re-exports it) so that a look's legs and heights are one
module's concern.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..errors import InfeasibleError
from ..mission import (FRAME_GLOBAL_RELATIVE_ALT, MissionEncodingError, MissionItem, MissionPlan, at_look_height,
                       change_speed, check_point_alts, climb_back, pass_through_waypoint, return_to_launch, takeoff)

NAV_LOITER_TURNS = 18
# A vehicle within these of a look's first point and height (``start_xy_m``, ``start_alt_m``) goes
# on with it where it is (a replan in the middle of a low orbit does not climb out and back in);
# one lower than the transit altitude by more than the height tolerance climbs straight up first.
CONTINUE_XY_M = 10.0
CONTINUE_ALT_M = 5.0


@dataclass(frozen=True)
class LookMission:
    """A look mission and, per look, the point [m] where it counts as flown (a fly-by's waypoint,
    an orbit's entry on the circle), the index in ``plan.items`` of the item that reaches it (the
    waypoint, the ring's first waypoint, or the NAV_LOITER_TURNS item; for a look at its own
    height the arrival above its entry at the transit altitude, before the descent) and the height
    [m] it flies at: a look is reported when it begins, and judged after its service (the descent,
    the orbit's dwell, the climb; search/policy.py)."""

    plan: MissionPlan
    look_xy_m: np.ndarray  # (k, 2)
    look_items: tuple[int, ...]
    look_alt_m: tuple[float, ...] = ()

    def look_seqs(self, home_at_seq0: bool) -> tuple[int, ...]:
        """The wire seq of each look's item (ArduPilot's home is seq 0)."""
        return tuple(i + (1 if home_at_seq0 else 0) for i in self.look_items)


def look_heights(points_n: int, orbits, look_alts_m) -> list:
    """Per look: its height [m] or None (the transit altitude) -- an orbit's own ``alt_m`` first,
    then ``look_alts_m``."""
    alts = list(look_alts_m) if look_alts_m is not None else []
    out = []
    for k in range(points_n):
        orb = orbits[k] if k < len(orbits) else None
        a = getattr(orb, "alt_m", None) if orb is not None else None
        out.append(a if a is not None else (alts[k] if k < len(alts) else None))
    return out


def look_mission(frame, points_xy_m, targets, orbits, *, alt_m: float, speed_m_s: float, autopilot: str,
                 home_latlon_deg, start_xy_m=None, include_takeoff: bool = True, fence=None,
                 home_xy_m=(0.0, 0.0), look_alts_m=None, floor_m: float | None = None,
                 start_alt_m: float | None = None) -> LookMission:
    """The mission for looks at ``points_xy_m`` (access points, local metres of ``frame``; points
    after the looks, e.g. coverage passes' lanes, are flown through) with ``orbits`` (None or an
    OrbitLook per look): takeoff (``include_takeoff``), speed, per look a pass-through waypoint or
    the orbit in the autopilot's form, each at its height (module doc), RTL. ``alt_m`` is the
    transit altitude [m]; ``look_alts_m``: a height per look for those without an orbit's own
    (None: the transit altitude); ``floor_m``: the least height a look may fly (heights.look_floor_m).
    ``start_xy_m``: where the vehicle is (an orbit's entry is the circle point nearest the previous
    point); ``start_alt_m``: its height there, when airborne (see CONTINUE_XY_M). ``fence``: the
    scenario's geofence (``uavloc_gcs.geofence.Geofence``) or None; with one every point is moved
    inside it, detour waypoints go around its corners (also on the way to ``home_xy_m`` before the
    RTL), and a mission that would still leave it raises InfeasibleError. A height below the floor
    raises InfeasibleError."""
    pts = np.asarray(points_xy_m, float).reshape(-1, 2)
    if fence is not None and len(pts):
        pts = fence.clip(pts)
    orbits = list(orbits) if orbits is not None else [None] * len(pts)
    try:
        heights = check_point_alts(look_heights(len(pts), orbits, look_alts_m), len(pts), alt_m, floor_m)
    except MissionEncodingError as exc:
        raise InfeasibleError(str(exc).replace("point ", "look ", 1)) from None
    items: list[MissionItem] = []
    if include_takeoff:
        items.append(takeoff(alt_m, *home_latlon_deg))
    items.append(change_speed(speed_m_s))
    xy_out, idx_out, alt_out = [], [], []
    prev = np.zeros(2) if start_xy_m is None else np.asarray(start_xy_m, float)[:2]

    def ll(xy):
        lat, lon = frame.to_wgs84_latlon(np.asarray(xy, float).reshape(-1, 2))[0]
        return float(lat), float(lon)

    flown = [prev.copy()]  # every point the vehicle flies through, for the fence's final check
    ends = (prev.copy(), np.asarray(home_xy_m, float)[:2])
    low_start = (not include_takeoff and start_alt_m is not None and math.isfinite(start_alt_m)
                 and start_alt_m < alt_m - CONTINUE_ALT_M)

    def around(to_xy, h):  # detour corners before flying to ``to_xy`` at ``h`` (none without a fence)
        if fence is None:
            return
        for c in fence.detour(flown[-1], to_xy, ends=ends):
            items.append(pass_through_waypoint(*ll(c), h))
            flown.append(np.asarray(c, float))

    def arrive(k, xy, h):  # the items that bring the vehicle to ``xy`` at ``h``; the first is the look's
        nonlocal low_start
        if k == 0 and low_start and h is not None and abs(start_alt_m - h) <= CONTINUE_ALT_M \
                and float(np.hypot(*(np.asarray(xy) - prev))) <= CONTINUE_XY_M:
            low_start = False  # already there, at the look's height: go on with it
            return [pass_through_waypoint(*ll(xy), float(h))]
        return at_look_height(*ll(xy), h, alt_m)

    targets = tuple(targets)
    for k, q in enumerate(pts):  # points beyond the looks (coverage passes' lanes) are fly-throughs
        orb = orbits[k] if k < len(orbits) else None
        h = heights[k]
        fly_h = alt_m if h is None else float(h)
        if orb is not None and fence is not None and not _circle_inside(fence, orb):
            orb = replace(orb, form="ring")  # its ring points are moved inside below
        entry = q if orb is None else orb.entry_xy_m(prev)
        if orb is not None and fence is not None:
            entry = fence.clip(entry)[0]
        if k == 0 and low_start and not (h is not None and abs(start_alt_m - h) <= CONTINUE_ALT_M
                                         and float(np.hypot(*(entry - prev))) <= CONTINUE_XY_M):
            items.append(pass_through_waypoint(*ll(prev), alt_m))  # up to the transit altitude first
            low_start = False
        xy_out.append(entry)
        alt_out.append(fly_h)
        around(entry, alt_m)
        if orb is None:
            idx_out.append(len(items))
            items += arrive(k, q, h) + climb_back(*ll(q), h, alt_m)
            flown.append(q)
            prev = q
            continue
        if orb.form == "loiter-turns" and autopilot == "ardupilot":
            # NAV_LOITER_TURNS: turns, (heading-required), radius (positive: clockwise), xtrack;
            # ArduCopter joins the circle at its point nearest to where it comes from (measured)
            down = arrive(k, entry, h) if h is not None and abs(fly_h - alt_m) > 0.5 else []
            idx_out.append(len(items))
            items += down
            items.append(MissionItem(NAV_LOITER_TURNS, FRAME_GLOBAL_RELATIVE_ALT,
                                     (float(orb.turns), 0.0, float(orb.radius_m), 0.0), *ll(orb.centre_xy_m), fly_h))
            if down:
                items += climb_back(*ll(entry), h, alt_m)  # it leaves the circle about where it joined
            flown.append(entry)
        else:
            ring = orb.ring_xy_m(entry)
            if fence is not None:
                ring = fence.clip(ring)
            idx_out.append(len(items))
            items += arrive(k, ring[0], h)  # to the entry at cruise speed, then down
            flown.append(np.asarray(ring[0], float))
            slow = orb.speed_m_s < speed_m_s - 0.5
            if slow:
                items.append(change_speed(orb.speed_m_s))
            for r in ring[1:]:
                around(r, fly_h)
                items.append(pass_through_waypoint(*ll(r), fly_h))
                flown.append(np.asarray(r, float))
            if slow:
                items.append(change_speed(speed_m_s))
            items += climb_back(*ll(ring[-1]), h, alt_m)
        prev = entry
    if low_start:  # a mission of no looks from low down: up first
        items.append(pass_through_waypoint(*ll(prev), alt_m))
    around(np.asarray(home_xy_m, float)[:2], alt_m)  # RTL flies straight home from the last point
    if fence is not None:
        flown.append(np.asarray(home_xy_m, float)[:2])
        bad = fence.outside_legs(np.asarray(flown), ends=ends)
        if bad:
            k = bad[0]
            raise InfeasibleError(
                f"the look mission would leave the geofence between ({flown[k][0]:.0f}, {flown[k][1]:.0f}) m and "
                f"({flown[k + 1][0]:.0f}, {flown[k + 1][1]:.0f}) m (east, north of the launch point); not flown")
    items.append(return_to_launch())
    plan = MissionPlan(tuple(items), float(home_latlon_deg[0]), float(home_latlon_deg[1]), autopilot=autopilot,
                       cruise_speed_m_s=speed_m_s, hover_speed_m_s=5.0)
    return LookMission(plan, np.asarray(xy_out, float).reshape(-1, 2), tuple(idx_out), tuple(alt_out))


def _circle_inside(fence, orb) -> bool:
    """Whether the orbit's circle lies inside the fence's margin (its centre was clipped for it)."""
    from shapely.geometry import Point

    return bool(fence.inner(0.0).buffer(0.5).covers(Point(orb.centre_xy_m).buffer(orb.radius_m, 16)))
