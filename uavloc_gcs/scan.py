"""Initial scan: split the area among the fleet and sweep each part with boustrophedon lanes.

SPEC §2.1. Every vehicle leaves the launch point (local (0, 0)), flies parallel lanes over its
sub-area through pass-through waypoints (never hovering) and returns to the launch point.

Layout, in a frame rotated so that lanes are horizontal ("along" = lane direction,
"across" = offset between lanes):

* **Lane spacing.** With ``scan.coverage = "double"`` (the default) lanes are at most R apart and
  the outermost lanes run (almost) on the area's edge, so every point lies within R of **two**
  lanes: a person is heard from two legs at different offsets, which is what makes a moving person
  observable at all (SPEC §3.1: one straight leg fixes only three of four unknowns, plus a mirror
  image). ``"single"`` uses the paper's coverage spacing sqrt(2)·R (the diagonal-free cell size of
  the paper's grid) with the outer lanes half a spacing inside the edge: every point within R of
  one lane, about 30 % fewer lanes, but half-observable people. ``scan.lane_spacing_m`` replaces the
  mode's spacing (it is an upper bound; lanes are spread evenly across the area).
* **Lanes** are the chords of the area at each offset (several per offset in concave areas;
  the vehicle flies straight over a notch between them). Two repair passes lengthen lane ends
  wherever a point is not within R of enough lanes (acute corners, slanted edges, notches):
  first against a dense sample of the area, then against the exactly computed uncovered region
  (polygon buffers of the lanes, which err on the side of "uncovered").
* **Split**, balanced by flight time **including the transit from and back to the launch
  point**; two ways are tried and the shorter longest flight wins: (a) lanes ("rows") in
  contiguous groups, one per vehicle, by an exact dynamic programme, each group flown in the best
  of its four boustrophedon entries; (b) one serpentine over all rows cut into consecutive pieces
  anywhere, mid-lane too (bisection on the makespan with a greedy cut), which balances finer.
  All hull-edge directions (plus east and north) are tried as lane directions. Over terrain
  (``terrain.dem``) also the direction along the area's mean contour lines, and the direction is
  chosen by how much of the area its lanes, flown along their climb- and descent-limited
  terrain-following profile, keep within hearing of enough lanes (then by length).

Time and energy use a constant cruise speed (``energy.route_cost``): climb, descent and turns are
not modelled, so they are a lower bound on what the battery needs.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass

import numpy as np

from .energy import route_cost
from .errors import ConfigError, InfeasibleError
from .mission import MissionPlan, flight_mission
from .scan_rows import Rows, coverage_counts, layout_rows, refine, repair, rotation, sample_area

log = logging.getLogger(__name__)

__all__ = ["VehicleScan", "ScanPlan", "plan_scan", "scan_missions", "fence_xy_m", "lane_spacing_for",
           "coverage_counts"]

MIN_LANES_PER_RANGE = 10.0  # the narrowest lane spacing accepted is R / this


@dataclass(frozen=True)
class VehicleScan:
    """One vehicle's part of the scan, in local metres (launch point = (0, 0)).

    ``waypoints_xy_m`` are the pass-through points in flight order, without the launch point;
    ``length_m``/``duration_s``/``energy_j`` cover launch -> waypoints -> launch at cruise speed.
    """

    index: int
    subarea_xy_m: np.ndarray  # (K, 2) exterior ring of the largest part of the sub-area, CCW
    subarea_parts_xy_m: tuple  # all parts (concave areas can be cut into several)
    lanes_xy_m: tuple  # of (2, 2) arrays [[x0, y0], [x1, y1]] in flight direction
    waypoints_xy_m: np.ndarray  # (N, 2)
    length_m: float
    duration_s: float
    energy_j: float

    def route_xy_m(self) -> np.ndarray:
        """The whole flight path including the launch point at both ends, (N + 2, 2)."""
        z = np.zeros((1, 2))
        return np.vstack([z, self.waypoints_xy_m, z])


@dataclass(frozen=True)
class ScanPlan:
    vehicles: tuple  # of VehicleScan (vehicles with nothing to scan are left out)
    lane_spacing_m: float  # actual spacing between adjacent lanes
    coverage: str  # "double" or "single"
    lane_heading_deg: float  # compass bearing of the lanes (0..180)
    range_m: float  # horizontal hearing radius R used for the layout

    @property
    def makespan_s(self) -> float:
        return max((v.duration_s for v in self.vehicles), default=0.0)


def lane_spacing_for(scenario) -> tuple[float, str]:
    """Maximum lane spacing [m] and the coverage mode for ``scenario`` (ConfigError if unusable)."""
    r = scenario.horizontal_range_m
    mode = scenario.scan.coverage
    given = scenario.scan.lane_spacing_m
    if given is None:
        return (r if mode == "double" else math.sqrt(2.0) * r), mode
    limit = r if mode == "double" else 2.0 * r
    if given < r / MIN_LANES_PER_RANGE:
        # closer lanes hear the same people again; planning grows with the square of the lanes
        # (0.5 m over the paper's area asked for 4.65 TiB)
        raise ConfigError(
            f"{given:g} m is too narrow: lanes closer than R/{MIN_LANES_PER_RANGE:g} = "
            f"{r / MIN_LANES_PER_RANGE:.1f} m hear the same people again (R = {r:.1f} m)",
            source=scenario.source, key="scan.lane_spacing_m",
        )
    if given > limit:
        why = ("double coverage needs lanes at most R" if mode == "double"
               else "lanes farther apart than 2R leave strips nobody hears")
        raise ConfigError(
            f"{given:g} m is too wide: {why} = {limit:.1f} m apart (R = {r:.1f} m)",
            source=scenario.source, key="scan.lane_spacing_m",
        )
    return float(given), mode


# ---------------------------------------------------------------------------------------------
# Splitting rows among vehicles


def _group_costs(rows: Rows, rot_inv: np.ndarray):
    """Route length [m] of every contiguous row group (i..j) and its best entry choice.

    Returns (cost (n, n), choice (n, n)); choice in 0..3 = (start at i or j) x (enter left/right).
    """
    n = len(rows.offsets)
    left = np.array([[row[0][0], c] for row, c in zip(rows.intervals, rows.offsets)]) @ rot_inv.T
    right = np.array([[row[-1][1], c] for row, c in zip(rows.intervals, rows.offsets)]) @ rot_inv.T
    span = np.array([row[-1][1] - row[0][0] for row in rows.intervals])
    con_r = np.linalg.norm(np.diff(right, axis=0), axis=1) if n > 1 else np.zeros(0)
    con_l = np.linalg.norm(np.diff(left, axis=0), axis=1) if n > 1 else np.zeros(0)
    m = np.arange(n - 1)
    # Connector m joins rows m, m+1 on the side given by parity (m - start) and the entry side.
    pa = np.concatenate([[0.0], np.cumsum(np.where(m % 2 == 0, con_r, con_l))])
    pb = np.concatenate([[0.0], np.cumsum(np.where(m % 2 == 0, con_l, con_r))])
    ps = np.concatenate([[0.0], np.cumsum(span)])
    ii, jj = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    base = ps[jj + 1] - ps[ii]
    d_left, d_right = np.linalg.norm(left, axis=1), np.linalg.norm(right, axis=1)
    costs = []
    for start_low in (True, False):
        s = ii if start_low else jj  # first row flown
        e = jj if start_low else ii  # last row flown
        for enter_left in (True, False):
            # Upward from i entering left, connector m (rows m, m+1) is on the right when m - i is
            # even; downward from j entering left, it is on the right when m - (j - 1) is even.
            # ``pa`` sums right connectors at even m, ``pb`` at odd m.
            use_a = ((s % 2 == 0) == enter_left) if start_low else ((s % 2 == 1) == enter_left)
            conn = np.where(use_a, pa[jj] - pa[ii], pb[jj] - pb[ii])
            entry = np.where(enter_left, d_left[s], d_right[s])
            exit_left = (np.abs(e - s) % 2 == 1) == enter_left
            exit_d = np.where(exit_left, d_left[e], d_right[e])
            costs.append(base + conn + entry + exit_d)
    stack = np.stack(costs)
    choice = np.argmin(stack, axis=0)
    cost = np.min(stack, axis=0)
    cost[ii > jj] = np.inf
    return cost, choice


def _partition(cost: np.ndarray, vehicles: int) -> list[tuple[int, int]]:
    """Contiguous groups (i, j) minimizing the largest cost; at most ``vehicles`` groups."""
    n = cost.shape[0]
    best = np.full((vehicles + 1, n + 1), np.inf)  # best[m][j]: rows 0..j-1 with m vehicles
    arg = np.zeros((vehicles + 1, n + 1), dtype=int)
    best[:, 0] = 0.0
    for m in range(1, vehicles + 1):
        for j in range(1, n + 1):
            i = np.arange(j)  # group rows i..j-1
            cand = np.maximum(best[m - 1, i], cost[i, j - 1])
            k = int(np.argmin(cand))
            if best[m - 1, j] <= cand[k]:
                best[m, j], arg[m, j] = best[m - 1, j], -1
            else:
                best[m, j], arg[m, j] = cand[k], k
    groups, m, j = [], vehicles, n
    while j > 0:
        k = arg[m, j]
        if k >= 0:
            groups.append((int(k), j - 1))
            j = k
        m -= 1
    return groups[::-1]


def _group_waypoints(rows: Rows, i: int, j: int, choice: int) -> tuple[np.ndarray, list]:
    """Waypoints and flown lane segments (rotated frame) of rows i..j for an entry ``choice``."""
    start_low, enter_left = choice < 2, choice % 2 == 0
    order = range(i, j + 1) if start_low else range(j, i - 1, -1)
    pts, lanes = [], []
    left_to_right = enter_left
    for k in order:
        c = rows.offsets[k]
        ivs = rows.intervals[k] if left_to_right else [[b, a] for a, b in reversed(rows.intervals[k])]
        for a0, a1 in ivs:
            pts += [(a0, c), (a1, c)]
            lanes.append(np.array([[a0, c], [a1, c]]))
        left_to_right = not left_to_right
    return np.array(pts), lanes


# ---------------------------------------------------------------------------------------------
# Public API


def _candidate_angles(poly) -> list[float]:
    hull = np.asarray(poly.convex_hull.exterior.coords)
    edges = np.diff(hull, axis=0)
    lengths = np.linalg.norm(edges, axis=1)
    angles = [0.0, math.pi / 2]
    for k in np.argsort(-lengths, kind="stable")[:16]:
        th = math.atan2(edges[k, 1], edges[k, 0]) % math.pi
        if all(min(abs(th - a), math.pi - abs(th - a)) > math.radians(0.5) for a in angles):
            angles.append(th)
    return angles


@dataclass(frozen=True)
class _Piece:
    """One vehicle's share, in the rotated frame: waypoints, flown lane segments, and for each row
    the along-range of the row's band it is responsible for (for drawing its sub-area)."""

    pts_r: np.ndarray
    lanes_r: list
    row_ranges: dict  # row index -> (along_lo, along_hi), +-inf where it reaches the row's end


def _row_group_pieces(rows: Rows, cost, choice, vehicles: int) -> list[_Piece]:
    """Contiguous whole-row groups, the exact min-max split (:func:`_partition`)."""
    out = []
    for i, j in _partition(cost, vehicles):
        pts_r, lanes_r = _group_waypoints(rows, i, j, int(choice[i, j]))
        out.append(_Piece(pts_r, lanes_r, {k: (-math.inf, math.inf) for k in range(i, j + 1)}))
    return out


def _serpentine_pieces(rows: Rows, rot: np.ndarray, choice: int, vehicles: int) -> list[_Piece]:
    """Cut one serpentine over all rows into consecutive pieces anywhere along it (mid-row too).

    A piece from arclength s0 to s1 costs (s1 - s0) + |p(s0)| + |p(s1)| (launch at the origin);
    that is non-decreasing in s1, so the smallest feasible makespan T is found by bisection with a
    greedy "as far as T allows" cut. This balances flight times finer than whole rows can.
    """
    n = len(rows.offsets)
    pts_r, _ = _group_waypoints(rows, 0, n - 1, choice)
    seg_row, seg_lane = [], []
    order = range(n) if choice < 2 else range(n - 1, -1, -1)
    for pos, k in enumerate(order):
        m = len(rows.intervals[k])
        for q in range(m):
            seg_row.append(k)
            seg_lane.append(True)  # the interval itself
            if q < m - 1:
                seg_row.append(k)
                seg_lane.append(False)  # gap over a notch, same row
        if pos < n - 1:
            seg_row.append(-1)
            seg_lane.append(False)  # connector to the next row
    xy = pts_r @ rot
    seg = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    total = float(cum[-1])
    dist = np.linalg.norm(xy, axis=1)
    g = cum + dist  # non-decreasing along the path

    def at(s: float) -> np.ndarray:
        k = min(max(int(np.searchsorted(cum, s, side="right")) - 1, 0), len(seg) - 1)
        t = 0.0 if seg[k] == 0 else (s - cum[k]) / seg[k]
        return xy[k] + min(max(t, 0.0), 1.0) * (xy[k + 1] - xy[k])

    def reach(s: float, budget: float) -> float:
        rhs = budget + s - float(np.linalg.norm(at(s)))
        k = int(np.searchsorted(g, rhs, side="right")) - 1
        if k >= len(cum) - 1:
            return total
        # On segment k, p(t) = P + t u: t + |P + t u| <= c  <=>  t <= (c^2 - |P|^2) / (2 (P.u + c)).
        c, P = rhs - cum[k], xy[k]
        u = (xy[k + 1] - P) / seg[k] if seg[k] > 0 else np.zeros(2)
        den = 2.0 * (float(P @ u) + c)
        t = seg[k] if den <= 0 else min(seg[k], max((c * c - float(P @ P)) / den, 0.0))
        return max(float(cum[k] + t), s)

    def cuts(budget: float) -> list[tuple[float, float]] | None:
        out, s = [], 0.0
        for _ in range(vehicles):
            e = reach(s, budget)
            if e <= s + 1e-9:
                return None
            if e >= total - 1e-6:
                out.append((s, total))  # snap: the last piece ends exactly where the serpentine does
                return out
            out.append((s, e))
            s = e
        return None

    lo, hi = 0.0, total + 2.0 * float(dist.max()) + 1.0
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if cuts(mid) is not None else (mid, hi)
    pieces = []
    row_span = {}
    for j, k in enumerate(seg_row):
        if k >= 0:
            a, b = row_span.get(k, (cum[j], cum[j + 1]))
            row_span[k] = (min(a, cum[j]), max(b, cum[j + 1]))
    for s0, s1 in cuts(hi):
        inner = [k for k in range(len(cum)) if s0 < cum[k] < s1]
        wps = np.vstack([at(s0)] + [xy[k] for k in inner] + [at(s1)])
        lanes = []
        for j in range(len(seg)):
            a, b = max(s0, cum[j]), min(s1, cum[j + 1])
            if seg_lane[j] and b - a > 1e-6:
                lanes.append(np.vstack([at(a), at(b)]) @ rot.T)
        ranges = {}
        for k, (rs, re) in row_span.items():
            a, b = max(s0, rs), min(s1, re)
            if b - a <= 1e-9:
                continue
            a_al, b_al = (at(a) @ rot.T)[0], (at(b) @ rot.T)[0]
            forward = (at(re) @ rot.T)[0] >= (at(rs) @ rot.T)[0]
            if a <= rs + 1e-6:
                a_al = -math.inf if forward else math.inf
            if b >= re - 1e-6:
                b_al = math.inf if forward else -math.inf
            ranges[k] = (min(a_al, b_al), max(a_al, b_al))
        pieces.append(_Piece(wps @ rot.T, lanes, ranges))
    return pieces


def _route_len(pts_xy: np.ndarray) -> float:
    route = np.vstack([np.zeros((1, 2)), pts_xy, np.zeros((1, 2))])
    return float(np.sum(np.linalg.norm(np.diff(route, axis=0), axis=1)))


def plan_scan(scenario) -> ScanPlan:
    """Plan the initial scan of ``scenario``: sub-areas, lanes and waypoints per vehicle.

    For every candidate lane direction two splits are tried -- whole rows per vehicle (exact
    min-max) and one serpentine cut anywhere (finer balance) -- and the shortest longest flight
    wins (then the shortest total). Raises ConfigError for an unusable lane spacing and
    InfeasibleError when a vehicle's scan needs more than ``scenario.usable_energy_j`` (with
    ``fleet.batteries`` > 1: more sorties than packs, ``sorties.scan_sorties``).
    """
    from shapely.geometry import Polygon

    r = scenario.horizontal_range_m
    spacing, mode = lane_spacing_for(scenario)
    need = 2 if mode == "double" else 1
    poly = Polygon(scenario.area_xy_m())
    m = scenario.fleet.vehicles
    dem = scenario.dem
    angles = _candidate_angles(poly)
    if dem is not None:
        from .terrain_missions import contour_angle

        along = contour_angle(scenario, np.asarray(poly.exterior.coords)[:-1])
        if along is not None and all(min(abs(along - a), math.pi - abs(along - a)) > math.radians(0.5)
                                     for a in angles):
            angles.append(along)
    best = None
    per_angle = {}
    for theta in angles:
        rot = rotation(theta)
        poly_r = Polygon(np.asarray(poly.exterior.coords) @ rot.T)
        rows = layout_rows(poly_r, spacing, mode)
        step = max(r / 20.0, math.sqrt(poly.area / 20000.0))
        rows = repair(rows, sample_area(poly_r, step), r, need, margin=step)
        rows = refine(rows, poly_r, r, need, step)
        cost, choice = _group_costs(rows, rot.T)
        options = [_row_group_pieces(rows, cost, choice, m)]
        if m > 1:
            options += [_serpentine_pieces(rows, rot, c, m) for c in range(4)]
        for pieces in options:
            lengths = [_route_len(pc.pts_r @ rot) for pc in pieces]
            key = (round(max(lengths), 3), round(sum(lengths), 3), theta)
            if best is None or key < best[0]:
                best = (key, theta, rot, poly_r, rows, pieces)
            if theta not in per_angle or key < per_angle[theta][0]:
                per_angle[theta] = (key, theta, rot, poly_r, rows, pieces)
        log.debug("lanes at %.1f deg: %d rows, best makespan so far %.0f m", math.degrees(theta),
                  len(rows.offsets), best[0][0])
    if dem is not None and len(per_angle) > 1:
        best = _best_over_terrain(scenario, sorted(per_angle.values(), key=lambda c: c[0]), need)
    _, theta, rot, poly_r, rows, pieces = best
    vehicles = [_vehicle_scan(scenario, idx, pc, rows, rot, poly_r) for idx, pc in enumerate(pieces)]
    bearing = (90.0 - math.degrees(theta)) % 180.0
    plan = ScanPlan(tuple(vehicles), rows.spacing_m, mode, bearing, r)
    _check_energy(scenario, plan)
    return plan


HEARING_SHARE_TIE = 0.01  # lane directions hearing within this share of the best count as equal


def _best_over_terrain(scenario, candidates: list, need: int):
    """Over terrain, the lane direction whose lanes, flown along their terrain-following profiles,
    keep the most of the area within hearing of ``need`` lanes; among those within
    :data:`HEARING_SHARE_TIE` of it the shortest (``candidates`` come shortest first).

    Lanes up and down a slope steeper than the descent limit allows at the scan speed end high
    above the valley and hear little there (examples/mountains.toml: 3 m/s at 15 m/s is a 20 %
    descent over ground falling up to 45 %); lanes along the contours stay at the planned height."""
    from .terrain_missions import TerrainRefused, hearing_share

    shares = []
    for cand in candidates:
        _, _, rot, poly_r, rows, pieces = cand
        routes = [np.vstack([np.zeros((1, 2)), _vehicle_scan(scenario, i, pc, rows, rot, poly_r).waypoints_xy_m,
                             np.zeros((1, 2))]) for i, pc in enumerate(pieces)]
        try:
            share = hearing_share(scenario, routes, need=need, speed_m_s=scenario.fleet.speed_m_s)
        except TerrainRefused:  # this direction cannot keep its clearance; terrain_safe says why if none can
            share = -1.0
        shares.append(share)
        log.debug("lanes at %.1f deg over the terrain: %.3f of the area heard by %d lanes",
                  math.degrees(cand[1]), share, need)
    top = max(shares)
    return next(c for c, sh in zip(candidates, shares) if sh >= top - HEARING_SHARE_TIE)


def _vehicle_scan(scenario, idx: int, pc: _Piece, rows: Rows, rot: np.ndarray, poly_r) -> VehicleScan:
    from shapely.geometry import box
    from shapely.ops import unary_union

    a0, _, a1, _ = poly_r.bounds
    wps = _dedupe(pc.pts_r @ rot)  # rot is orthonormal: inverse = transpose
    lanes = tuple(seg @ rot for seg in pc.lanes_r)
    n = len(rows.offsets)
    cells = []
    for k, (lo_a, hi_a) in sorted(pc.row_ranges.items()):
        lo_c = (rows.offsets[k - 1] + rows.offsets[k]) / 2 if k > 0 else -1e9
        hi_c = (rows.offsets[k] + rows.offsets[k + 1]) / 2 if k + 1 < n else 1e9
        cells.append(box(max(lo_a, a0 - 1), lo_c, min(hi_a, a1 + 1), hi_c))
    part = poly_r.intersection(unary_union(cells)) if cells else None
    geoms = [] if part is None else getattr(part, "geoms", [part])
    polys = sorted((g for g in geoms if g.geom_type == "Polygon" and g.area > 1e-6), key=lambda g: -g.area)
    parts = tuple(_ccw(np.asarray(g.exterior.coords)[:-1] @ rot) for g in polys)
    wps = _inside_fence(scenario, wps)
    route = np.vstack([np.zeros((1, 2)), wps, np.zeros((1, 2))])
    rc = route_cost(route, scenario.fleet.speed_m_s, scenario.power_model)
    return VehicleScan(idx, parts[0] if parts else np.zeros((0, 2)), parts, lanes, wps,
                       rc.length_m, rc.duration_s, rc.energy_j)


def _inside_fence(scenario, wps: np.ndarray) -> np.ndarray:
    """The scan's waypoints kept inside the scenario's geofence (none: unchanged): every lane
    cut to its part inside the fence's margin, with corners added where a leg from the launch
    point, between lanes or back would cut across a notch of the fence (uavloc_gcs/geofence.py).
    What lies beyond the fence is not flown; the coverage of the flown tracks says so."""
    from . import geofence

    fence = geofence.for_scenario(scenario)
    if fence is None or not len(wps):
        return wps
    return _dedupe(fence.clip_route(wps, start_xy_m=np.zeros(2), end_xy_m=np.zeros(2)))


def _dedupe(xy: np.ndarray, tol_m: float = 0.01) -> np.ndarray:
    keep = [0] + [k for k in range(1, len(xy)) if np.linalg.norm(xy[k] - xy[k - 1]) > tol_m]
    return xy[keep]


def _ccw(xy: np.ndarray) -> np.ndarray:
    x, y = xy[:, 0], xy[:, 1]
    return xy if np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) > 0 else xy[::-1].copy()


def _check_energy(scenario, plan: ScanPlan) -> None:
    if scenario.fleet.batteries > 1:  # flown in sorties, one pack each (issue 38): at most fleet.batteries
        from .sorties import scan_sorties

        scan_sorties(scenario, plan)
        return
    budget = scenario.usable_energy_j
    for v in plan.vehicles:
        if v.energy_j > budget:
            f = scenario.fleet
            raise InfeasibleError(
                f"vehicle uav{v.index + 1} needs {v.energy_j / 1000:.1f} kJ for its {v.length_m / 1000:.2f} km scan "
                f"but may use only {budget / 1000:.1f} kJ ({f.energy_budget_j / 1000:.1f} kJ budget minus "
                f"{f.energy_reserve_fraction:.0%} reserve); add vehicles (fleet.vehicles = {f.vehicles}), "
                "raise fleet.energy_budget_j, or use scan.coverage = \"single\""
            )


FENCE_MARGIN_M = 30.0  # room for tracking error and corner blending around the planned path


def fence_xy_m(scenario, plan: ScanPlan, margin_m: float = FENCE_MARGIN_M) -> np.ndarray:
    """Inclusion geofence (K, 2), counter-clockwise: the area, or, when the flight leaves it.

    The scan leaves the area polygon on the way from and to the launch point, over the notches of
    concave areas and where lanes are lengthened to keep double coverage; a fence equal to the
    area would then make PX4 reject the mission (waypoints outside the fence) and ArduPilot
    breach it in flight. So the fence is the area when every route, widened by ``margin_m``,
    stays inside it, else the convex hull of the area and all routes, grown by ``margin_m``.
    A scenario that gives a geofence (``area.geofence_deg``/``geofence_file``) gets that one.
    """
    from shapely.geometry import MultiLineString, MultiPoint, Polygon

    from . import geofence

    given = geofence.for_scenario(scenario)
    if given is not None:  # the scenario's own fence: the scan was planned inside it
        return _ccw(np.asarray(given.polygon_xy_m, float))
    area_xy = scenario.area_xy_m()
    area = Polygon(area_xy)
    routes = [v.route_xy_m() for v in plan.vehicles]
    if routes and MultiLineString([r for r in routes if len(r) >= 2]).buffer(margin_m).within(area):
        return area_xy
    pts = np.vstack([area_xy] + routes)
    # Simplifying drops near-collinear hull vertices (it may cut up to 0.5 m, added back below).
    hull = MultiPoint(pts).convex_hull.simplify(0.5).buffer(margin_m + 0.5, join_style="mitre", mitre_limit=2.0)
    return _ccw(np.asarray(hull.exterior.coords)[:-1])


def scan_missions(scenario, plan: ScanPlan) -> list[MissionPlan]:
    """One MAVLink mission per planned vehicle: takeoff, speed, pass-through waypoints, RTL.

    Home is the launch point. The inclusion geofence (clockwise, as QGroundControl writes it) is
    :func:`fence_xy_m`: the area, or a hull around the area and every route when they leave it.
    """
    frame = scenario.frame
    fleet = scenario.fleet
    fence = tuple(tuple(map(float, v)) for v in reversed(frame.to_wgs84_latlon(fence_xy_m(scenario, plan))))
    out = []
    for v in plan.vehicles:
        latlon = frame.to_wgs84_latlon(v.waypoints_xy_m) if len(v.waypoints_xy_m) else np.zeros((0, 2))
        # The launch point's AMSL altitude is unknown; 0 is what QGroundControl writes without
        # terrain data. A null (NaN) would reach ArduPilot as item 0 through importers such as
        # MAVSDK's, and ArduPilot rejects a NaN altitude (INVALID_PARAM7); it replaces home anyway.
        mission = flight_mission(
            latlon.tolist(), alt_m=fleet.altitude_m, speed_m_s=fleet.speed_m_s, autopilot=fleet.autopilot,
            home_latlon_deg=scenario.launch_latlon_deg, home_alt_amsl_m=0.0,
        )
        out.append(dataclasses.replace(mission, geofence_polygons=((True, fence),)))
    return out
