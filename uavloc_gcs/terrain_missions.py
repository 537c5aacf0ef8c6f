"""Terrain-safe missions: a post-processing step from any uavloc mission plan to one that keeps
clear of the ground (issue 28 item 2).

:func:`terrain_safe` takes a :class:`~uavloc_gcs.mission.MissionPlan` as the scan, look or any other
mission builder made it (altitudes above the launch point over flat ground) and the scenario's DEM,
and returns the plan flown over the real ground:

* The whole route -- launch, every waypoint and the way back home -- is sampled at half the DEM's
  cell size (so every cell a leg crosses is seen, not only the waypoints).
* Along it the vehicle aims at each route item's own height above the ground (a look's, issue 41:
  uavloc_gcs/heights.py; the builders write it as the item's altitude over flat ground, which is
  ``fleet.altitude_m`` for a scan and a transit), never less than ``terrain.min_clearance_m`` above
  the ground plus ``terrain.obstacle_height_m`` (trees, buildings), and never above
  ``terrain.max_height_above_launch_m`` over the launch point when that is set.
* The profile is the lowest one above that aim whose slope stays within ``terrain.max_climb_m_s``
  and ``terrain.max_descent_m_s`` at the planned ground speed: it starts climbing before a rise and
  comes down after it (an upper envelope, two passes). A look's descent and climb are vertical legs
  (two items at one place): the vehicle changes height there, at the vertical rates, on the spot;
  their clearance is that of their lower end.
* A vehicle given a mission in the air at another height than the profile starts at
  (``start_alt_m``, e.g. low in a look) first goes straight up or down to it where it is.
* The profile is then cut into straight 3D legs -- the autopilots fly a straight line between two
  waypoints -- with a waypoint added wherever the straight leg would come nearer the ground than
  the clearance, or more than ``TRACK_TOLERANCE_M`` off the profile.
* The closing RTL is preceded by waypoints back to the launch point, as ArduPilot's and PX4's
  RTL fly home at one altitude, straight through any hill on the way.

Altitudes are written absolute (MAV_FRAME_GLOBAL, what PX4 and ArduPilot both accept) or, with
``terrain.altitude_frame = "relative"``, above the launch point from the DEM's height differences.
Every positional item carries the ground height under it (``MissionPlan.terrain_alt_m``) so that a
``.plan`` export can carry QGroundControl's terrain fields.

A mission that cannot keep the clearance (the ground is above the ceiling, or outside the DEM) is
refused with one sentence naming the vehicle, the leg and the ground's height.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from .errors import InfeasibleError
from .mission import (
    DO_CHANGE_SPEED,
    DO_JUMP,
    FRAME_GLOBAL,
    FRAME_GLOBAL_RELATIVE_ALT,
    NAV_RETURN_TO_LAUNCH,
    NAV_WAYPOINT,
    ROUTE_COMMANDS,
    TAKEOFF_COMMANDS,
    MissionItem,
    MissionPlan,
)

__all__ = ["terrain_safe", "TRACK_TOLERANCE_M", "route_profile", "Profile", "hearing_share", "contour_angle"]

TRACK_TOLERANCE_M = 10.0  # how far the flown straight legs may stray from the planned profile


class TerrainRefused(InfeasibleError):
    """A mission that cannot keep its clearance over the terrain."""


@dataclasses.dataclass(frozen=True)
class Profile:
    """The planned altitude along a route: ``s`` [m along it], ``xy`` (N, 2) local metres, ground
    height ``ground`` and altitude ``z`` [m, the DEM's datum]; ``vertex`` marks the route's own points."""

    s: np.ndarray
    xy: np.ndarray
    ground: np.ndarray
    z: np.ndarray
    vertex: np.ndarray  # index into s of each route point


def _leg_name(k: int, n_points: int, returns_home: bool, starts_home: bool) -> str:
    """Leg ``k`` (0-based, from route point k to k+1) as the operator knows it."""
    a = "launch" if (k == 0 and starts_home) else f"waypoint {k + (0 if starts_home else 1)}"
    last = n_points - 1
    if returns_home and k + 1 == last:
        return f"return leg ({a} to launch)"
    b = f"waypoint {k + 1 + (0 if starts_home else 1)}"
    return f"leg {k + 1} ({a} to {b})"


def route_profile(scenario, route_xy: np.ndarray, *, speed_m_s: float, name: str = "vehicle",
                  starts_home: bool = True, returns_home: bool = True, heights_m=None) -> Profile:
    """The terrain-following altitude profile along ``route_xy`` (local metres, launch first when
    ``starts_home``), aiming at ``heights_m`` above the ground at each route point (None:
    ``fleet.altitude_m`` everywhere; between two points the aim goes linearly from one to the
    other). Raises :class:`TerrainRefused` when the clearance cannot be kept."""
    dem = scenario.dem
    t = scenario.terrain
    alt = scenario.fleet.altitude_m
    step = max(1.0, 0.5 * dem.resolution_m)
    hv = None if heights_m is None else np.asarray(heights_m, dtype=float)
    pts = [route_xy[0]]
    vertex = [0]
    aim_h = [alt if hv is None else hv[0]]
    vertical = [False]  # the leg arriving at this sample is a change of height on the spot
    for k, (a, b) in enumerate(zip(route_xy[:-1], route_xy[1:])):
        n = max(1, int(math.ceil(np.linalg.norm(b - a) / step)))
        f = np.arange(1, n + 1)[:, None] / n
        pts.extend(a + f * (b - a))
        vertex.append(len(pts) - 1)
        if hv is None:
            aim_h.extend([alt] * n)
            vertical.extend([False] * n)
        else:
            aim_h.extend(hv[k] + f[:, 0] * (hv[k + 1] - hv[k]))
            vertical.extend([bool(np.linalg.norm(b - a) < 1e-6 and abs(hv[k + 1] - hv[k]) > 0.5)] * n)
    xy = np.asarray(pts, dtype=float)
    vertex = np.asarray(vertex)
    vertical = np.asarray(vertical)
    ds = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(ds)])
    g = dem.height_xy(xy)
    leg_of = np.searchsorted(vertex, np.arange(len(xy)), side="left") - 1
    leg_of = np.clip(leg_of, 0, len(route_xy) - 2)
    bad = np.flatnonzero(~np.isfinite(g))
    if bad.size:
        i = bad[0]
        lat, lon = dem.frame.to_wgs84_latlon(xy[i])[0]
        why = "leaves" if not dem.inside(xy[i])[0] else "crosses a void of"
        raise TerrainRefused(
            f"{name}: the {_leg_name(int(leg_of[i]), len(route_xy), returns_home, starts_home)} {why} the DEM "
            f"{Path(dem.source).name} at {lat:.5f}, {lon:.5f} ({dem.coverage_text()}), so its clearance "
            "cannot be checked; give a DEM that covers every leg")
    home_g = dem.height_at(0.0, 0.0)
    aim = g + np.asarray(aim_h, dtype=float)
    floor = g + t.obstacle_height_m + t.min_clearance_m
    aim = np.maximum(aim, floor)  # (the same aim whenever a height keeps the clearance, as every uavloc one does)
    if t.max_height_above_launch_m is not None:
        ceiling = home_g + t.max_height_above_launch_m
        aim = np.maximum(floor, np.minimum(aim, ceiling))
    z = aim.copy()
    if np.ndim(speed_m_s) == 0:
        up = np.full(len(z), t.max_climb_m_s / speed_m_s)
        down = np.full(len(z), t.max_descent_m_s / speed_m_s)
    else:  # one speed per leg (an orbit's ring is flown slower): the gradient of the leg arriving at each sample
        v = np.asarray(speed_m_s, dtype=float)[np.clip(leg_of, 0, len(route_xy) - 2)]
        up, down = t.max_climb_m_s / v, t.max_descent_m_s / v
    for i in range(1, len(z)):  # descending no faster than allowed (a look's descent is on the spot)
        if not vertical[i]:
            z[i] = max(z[i], z[i - 1] - down[i] * ds[i - 1])
    for i in range(len(z) - 2, -1, -1):  # climbing no faster than allowed, starting early enough
        if not vertical[i + 1]:
            z[i] = max(z[i], z[i + 1] - up[i + 1] * ds[i])
    if t.max_height_above_launch_m is not None:
        over = np.flatnonzero(z > ceiling + 1e-6)
        if over.size:
            k = int(leg_of[over[0]])
            on_leg = np.flatnonzero(leg_of == k)
            j = on_leg[np.argmax(g[on_leg])]
            lat, lon = dem.frame.to_wgs84_latlon(xy[j])[0]
            raise TerrainRefused(
                f"{name}: the {_leg_name(k, len(route_xy), returns_home, starts_home)} crosses ground "
                f"{g[j]:.0f} m above sea level at {lat:.5f}, {lon:.5f}, {g[j] - home_g:.0f} m above the launch point, "
                f"and keeping terrain.min_clearance_m = {t.min_clearance_m:g} m there (within the climb and descent "
                f"rates) needs {float(np.max(z[on_leg])) - home_g:.0f} m above the launch point, more than "
                f"terrain.max_height_above_launch_m = {t.max_height_above_launch_m:g} m")
    return Profile(s, xy, g, z, vertex)


def _breakpoints(p: Profile, clearance: float, tol: float) -> list[int]:
    """Indices of the profile to make waypoints of: the route's points plus every point where a
    straight 3D leg would come nearer the ground than ``clearance`` or stray more than ``tol``."""
    keep = set(int(v) for v in p.vertex)

    def split(a: int, b: int) -> None:
        if b - a < 2:
            return
        idx = np.arange(a + 1, b)
        chord = p.z[a] + (p.z[b] - p.z[a]) * (p.s[idx] - p.s[a]) / max(p.s[b] - p.s[a], 1e-9)
        viol = np.maximum.reduce([p.ground[idx] + clearance - chord, chord - p.z[idx] - tol,
                                  p.z[idx] - tol - chord, np.full(len(idx), -np.inf)])
        # a leg below the clearance is always split; otherwise only beyond the tolerance
        worst = int(np.argmax(viol))
        if viol[worst] > 1e-6:
            m = int(idx[worst])
            keep.add(m)
            split(a, m)
            split(m, b)

    for a, b in zip(p.vertex[:-1], p.vertex[1:]):
        split(int(a), int(b))
    return sorted(keep)


def terrain_safe(plan: MissionPlan, scenario, *, name: str = "vehicle",
                 start_xy_m: np.ndarray | None = None, start_alt_m: float | None = None) -> MissionPlan:
    """``plan`` flown over the scenario's terrain (see the module's doc); unchanged without a DEM.

    The route starts at the launch point when the plan takes off (or at ``start_xy_m``, where an
    airborne vehicle is, for a mission without a take-off; ``start_alt_m``: its height above the
    launch point there, as telemetry gives it) and ends at the launch point when it closes with an
    RTL. Each route item aims at its own altitude above the ground (relative-frame items, as
    uavloc's builders write them; ``fleet.altitude_m`` for the others). ``name`` is the vehicle,
    for messages.
    """
    dem = scenario.dem
    if dem is None:
        return plan
    frame = scenario.frame
    t = scenario.terrain
    items = list(plan.items)
    if any(it.command == DO_JUMP for it in items):
        raise TerrainRefused(f"{name}: the mission has a DO_JUMP, so its legs do not follow one another and their "
                             "clearance over the terrain cannot be planned leg by leg; remove the jump (uavloc's "
                             "own missions have none)")
    has_takeoff = any(it.command in TAKEOFF_COMMANDS for it in items)
    returns_home = bool(items) and items[-1].command == NAV_RETURN_TO_LAUNCH
    route_idx = [k for k, it in enumerate(items) if it.command in ROUTE_COMMANDS and it.has_position]
    if not route_idx:
        return plan
    route_ll = np.array([[items[k].lat_deg, items[k].lon_deg] for k in route_idx])
    route_xy = frame.to_local_xy(route_ll)
    starts_home = has_takeoff or start_xy_m is None
    start = np.zeros((1, 2)) if starts_home else np.asarray(start_xy_m, dtype=float).reshape(1, 2)
    pts = [start, route_xy] + ([np.zeros((1, 2))] if returns_home else [])
    full = np.vstack(pts)
    speed = _leg_speeds(plan, scenario, route_idx, returns_home)
    survey = scenario.fleet.altitude_m
    route_h = [items[k].alt_m if items[k].frame == FRAME_GLOBAL_RELATIVE_ALT else survey for k in route_idx]
    heights = None if all(h == survey for h in route_h) else np.array([survey, *route_h] + [survey] * returns_home)
    prof = route_profile(scenario, full, speed_m_s=speed, name=name, starts_home=starts_home,
                         returns_home=returns_home, heights_m=heights)
    cuts = _breakpoints(prof, t.min_clearance_m + t.obstacle_height_m, TRACK_TOLERANCE_M)
    home_g = dem.height_at(0.0, 0.0)
    relative = t.altitude_frame == "relative"
    fr = FRAME_GLOBAL_RELATIVE_ALT if relative else FRAME_GLOBAL

    def alt_of(z: float) -> float:
        return round(float(z - home_g) if relative else float(z), 2)

    def wp_at(i: int) -> MissionItem:
        lat, lon = frame.to_wgs84_latlon(prof.xy[i])[0]
        return MissionItem(NAV_WAYPOINT, fr, (0.0, 0.0, 0.0, math.nan), float(lat), float(lon), alt_of(prof.z[i]))

    # Which profile breakpoints fall inside each route leg (exclusive of its ends).
    vertex = list(prof.vertex)
    inner = {k: [c for c in cuts if vertex[k] < c < vertex[k + 1]] for k in range(len(vertex) - 1)}
    out: list[MissionItem] = []
    ground: list[float] = []
    route_pos = {k: j + 1 for j, k in enumerate(route_idx)}  # item index -> route point index in ``full``
    first_route = route_idx[0]
    for k, it in enumerate(items):
        if k == first_route and not starts_home and start_alt_m is not None and math.isfinite(start_alt_m) \
                and abs(home_g + float(start_alt_m) - prof.z[0]) > TRACK_TOLERANCE_M:
            out.append(wp_at(0))  # straight up (or down) where the vehicle is, to where its profile starts
            ground.append(float(prof.ground[0]))
        if it.command in TAKEOFF_COMMANDS:
            out.append(dataclasses.replace(it, alt_m=round(float(prof.z[0] - home_g), 2)))
            ground.append(float(prof.ground[0]))
            continue
        if k in route_pos:
            v = route_pos[k]
            for c in inner.get(v - 1, []):  # the waypoints added on the leg arriving here
                out.append(wp_at(c))
                ground.append(float(prof.ground[c]))
            i = vertex[v]
            out.append(dataclasses.replace(it, frame=fr, alt_m=alt_of(prof.z[i])))
            ground.append(float(prof.ground[i]))
            continue
        if it.command == NAV_RETURN_TO_LAUNCH and returns_home and k == len(items) - 1:
            last = len(vertex) - 2
            for c in inner.get(last, []):
                out.append(wp_at(c))
                ground.append(float(prof.ground[c]))
            # above the launch point at the profile's end, then the RTL lands there
            out.append(wp_at(vertex[-1]))
            ground.append(float(prof.ground[vertex[-1]]))
        out.append(it)
        ground.append(math.nan)
    return dataclasses.replace(plan, items=tuple(out), home_alt_m=round(float(home_g), 2),
                               terrain_alt_m=tuple(round(g, 2) if math.isfinite(g) else math.nan for g in ground))


def _leg_speeds(plan: MissionPlan, scenario, route_idx: list, returns_home: bool):
    """The ground speed [m/s] of each leg of the route (to each route item, then home): the last
    DO_CHANGE_SPEED before the item (an orbit's ring is asked slower), else :func:`_speed`; one
    number when every leg has the same."""
    v = _speed(plan, scenario)
    out, at = [], 0
    for k in route_idx:
        for it in plan.items[at:k]:
            if it.command == DO_CHANGE_SPEED and it.params[1] > 0:
                v = float(it.params[1])
        at = k
        out.append(v)
    if returns_home:
        out.append(out[-1] if out else v)
    return out[0] if len(set(out)) <= 1 else np.asarray(out, dtype=float)


def _speed(plan: MissionPlan, scenario) -> float:
    """The ground speed the climb gradients are planned at: the mission's DO_CHANGE_SPEED, else
    the plan's cruise speed, else the fleet's."""
    for it in plan.items:
        if it.command == DO_CHANGE_SPEED and it.params[1] > 0:
            return float(it.params[1])
    return float(plan.cruise_speed_m_s or scenario.fleet.speed_m_s)


def clearance_along(plan: MissionPlan, scenario, *, step_m: float | None = None) -> np.ndarray:
    """Height above the DEM [m] along the straight 3D legs of ``plan`` as the autopilot flies them
    (the take-off at the launch point, the route items, the RTL home at its altitude), sampled every ``step_m`` (default half a
    DEM cell): what a test or an operator checks the plan against."""
    dem = scenario.dem
    frame = scenario.frame
    home_g = dem.height_at(0.0, 0.0)
    rel = scenario.terrain.altitude_frame == "relative"
    pts = []
    for it in plan.items:
        if it.command in TAKEOFF_COMMANDS and not pts:  # climbs at the launch point
            pts.append((0.0, 0.0, home_g + it.alt_m))
        if it.command in ROUTE_COMMANDS and it.has_position:
            x, y = frame.to_local_xy(np.array([[it.lat_deg, it.lon_deg]]))[0]
            pts.append((x, y, it.alt_m + (home_g if rel or it.frame == FRAME_GLOBAL_RELATIVE_ALT else 0.0)))
    if plan.items and plan.items[-1].command == NAV_RETURN_TO_LAUNCH and pts:
        pts.append((0.0, 0.0, pts[-1][2]))  # RTL flies home at the altitude it has (above RTL_ALT here)
    p = np.array(pts)
    step = step_m or 0.5 * dem.resolution_m
    out = []
    for a, b in zip(p[:-1], p[1:]):
        n = max(1, int(math.ceil(np.linalg.norm(b[:2] - a[:2]) / step)))
        f = np.linspace(0.0, 1.0, n + 1)[:, None]
        q = a + f * (b - a)
        out.append(q[:, 2] - dem.height_xy(q[:, :2]))
    return np.concatenate(out) if out else np.zeros(0)


def point_seqs(wire_items, latlon_deg) -> tuple[int, ...]:
    """Wire seqs of the NAV_WAYPOINTs at ``latlon_deg`` (N, 2), in order: where a mission's own
    points (looks) went once :func:`terrain_safe` added waypoints between them."""
    from .mission import deg_to_e7

    want = [(deg_to_e7(float(a)), deg_to_e7(float(b))) for a, b in np.asarray(latlon_deg, dtype=float).reshape(-1, 2)]
    out, k = [], 0
    for it in wire_items:
        if k < len(want) and it.command == NAV_WAYPOINT and it.seq > 0 and (it.x, it.y) == want[k]:
            out.append(int(it.seq))
            k += 1
    return tuple(out)


def mission_heights_m(plan: MissionPlan, scenario) -> np.ndarray:
    """The altitudes [m, the DEM's datum] a mission flies through in order: the launch point's
    ground, the take-off altitude, every route item (absolute or relative altitudes alike)."""
    dem = scenario.dem
    home_g = dem.height_at(0.0, 0.0) if dem is not None else 0.0
    out = []
    for it in plan.items:
        if it.command in TAKEOFF_COMMANDS:
            out += [home_g, home_g + it.alt_m]
        elif it.command in ROUTE_COMMANDS and it.has_position:
            out.append(it.alt_m if it.frame == FRAME_GLOBAL else home_g + it.alt_m)
    return np.asarray(out, dtype=float)


def climb_energy_j(plan: MissionPlan, scenario) -> float:
    """Energy [J] of a mission's climbs (energy.RotorcraftPower.climb_energy_j over its heights)."""
    return scenario.power_model.climb_energy_j(mission_heights_m(plan, scenario))


def check_climb_energy(scenario, vehicles, missions) -> list[float]:
    """Each terrain-safe mission's climb energy [J]; refuses (one sentence naming the vehicle) a
    mission whose level-flight energy (``vehicles[i].energy_j``) plus climbs exceed the usable budget."""
    usable = scenario.usable_energy_j
    out = []
    for v, m in zip(vehicles, missions):
        c = climb_energy_j(m, scenario)
        if v.energy_j + c > usable:
            raise InfeasibleError(
                f"vehicle uav{v.index + 1} needs {v.energy_j / 1000:.1f} kJ for its scan plus {c / 1000:.1f} kJ to climb "
                f"over the terrain, more than the usable {usable / 1000:.1f} kJ; add vehicles (fleet.vehicles = "
                f"{scenario.fleet.vehicles}) or raise fleet.energy_budget_j")
        out.append(c)
    return out


def contour_angle(scenario, area_xy: np.ndarray) -> float | None:
    """The lane direction (radians from east, 0..pi) along the area's mean contour lines: across the
    gradient of the least-squares plane through the ground under the area; None on level ground."""
    dem = scenario.dem
    lo, hi = area_xy.min(axis=0), area_xy.max(axis=0)
    xs, ys, z = dem.grid_xy(lo, hi, max(dem.resolution_m, float(np.max(hi - lo)) / 60.0))
    gx, gy = np.meshgrid(xs, ys)
    xy, g = np.column_stack([gx.ravel(), gy.ravel()]), z.ravel()
    ok = np.isfinite(g)
    if ok.sum() < 3:
        return None
    a = np.column_stack([xy[ok], np.ones(ok.sum())])
    (sx, sy, _), *_ = np.linalg.lstsq(a, g[ok], rcond=None)
    if math.hypot(sx, sy) < 0.02:  # under 2 % slope: any direction follows the ground
        return None
    return (math.atan2(sy, sx) + math.pi / 2) % math.pi


def hearing_share(scenario, routes_xy: list, *, need: int, speed_m_s: float) -> float:
    """Share of the area within the 3-D hearing range (``fleet.comm_range_m``) of at least ``need``
    distinct legs of ``routes_xy`` (each launch first and last) flown along their terrain-following
    profiles -- the height the climb and descent limits leave them at, not the aim. Lanes flown up
    and down a steep slope end high above a valley (the descent cannot follow the ground) and hear
    less there than lanes along the contours."""
    import shapely  # noqa: PLC0415
    from shapely.geometry import Polygon  # noqa: PLC0415

    dem = scenario.dem
    area_xy = scenario.area_xy_m()
    poly = Polygon(area_xy)
    lo, hi = area_xy.min(axis=0), area_xy.max(axis=0)
    step = max(scenario.horizontal_range_m / 6.0, math.sqrt(poly.area / 3000.0))
    gx, gy = np.meshgrid(np.arange(lo[0] + step / 2, hi[0], step), np.arange(lo[1] + step / 2, hi[1], step))
    pts = np.column_stack([gx.ravel(), gy.ravel()])
    pts = pts[shapely.contains_xy(poly, pts[:, 0], pts[:, 1])]
    if not len(pts):
        return 1.0
    ground = dem.height_xy(pts, clamp=True)
    r2 = scenario.fleet.comm_range_m ** 2
    legs_heard = np.zeros(len(pts), dtype=int)
    for route in routes_xy:
        prof = route_profile(scenario, np.asarray(route, float), speed_m_s=speed_m_s)
        leg = np.clip(np.searchsorted(prof.vertex, np.arange(len(prof.s)), side="left") - 1, 0, None)
        for k in np.unique(leg):
            on = leg == k
            d2 = (np.sum((pts[:, None, :] - prof.xy[None, on, :]) ** 2, axis=2)
                  + (prof.z[None, on] - ground[:, None]) ** 2)
            legs_heard += np.any(d2 <= r2, axis=1)
    return float(np.mean(legs_heard >= need))
