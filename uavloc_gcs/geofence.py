"""The scenario's geofence: every flight uavloc plans stays inside it (issue 26 item 4).

A scenario may give an inclusion polygon (``area.geofence_deg`` or ``area.geofence_file``: a
GeoJSON polygon or the inclusion polygon of a QGroundControl ``.plan``), for instance the airspace
a team was cleared to fly in. Without one, the search area grown by ``area.default_geofence_m``
(50 m unless the scenario says otherwise; with the way to it from a launch point beside it) is the
fence the daemon's looks and passes stay inside (:func:`flight_fence`; issue 42: with no fence, looks
left the field world's area by up to 111 m), and ``uavloc plan``, its preview and the daemon's log
say so (:func:`describe`). The policy itself keeps its look points within the area grown by the
hearing-range margin (``search.aiming.LOOK_AREA_MARGIN``), the scan inside the area.

What "inside" means here:

* every point uavloc places (scan waypoints, look points, orbit circles, coverage passes) lies at
  least ``area.geofence_margin_m`` inside the fence: room for tracking error and for the corner a
  pass-through waypoint cuts (the scan's own exported fence keeps 30 m around its path, for the
  same reason);
* every leg between them stays inside the fence shrunk by half that margin. A leg that would cut
  across a notch of a concave fence is replaced by the shortest path through the shrunk fence's
  corners (a visibility graph over its vertices, searched by Dijkstra);
* the launch point and the vehicle's position when a mission is uploaded may lie on the fence
  (a launch at the area's corner): legs from them are checked against the fence itself near them.

A route that cannot be kept inside (a fence whose shrunk interior falls apart into pieces, say)
raises :class:`~uavloc_gcs.errors.InfeasibleError` naming the leg; it is never flown.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass, field

import numpy as np

from .errors import InfeasibleError

__all__ = ["Geofence", "default_for", "describe", "flight_fence", "for_scenario", "scan_beyond_m"]

_TOL_M = 0.5  # numerical room when testing a leg against a polygon


@dataclass
class Geofence:
    """An inclusion polygon in local metres (counter-clockwise, not closed) and its margin."""

    polygon_xy_m: np.ndarray
    margin_m: float = 30.0
    _cache: dict = field(default_factory=dict, repr=False)

    # -- polygons --------------------------------------------------------------------------
    @property
    def polygon(self):
        from shapely.geometry import Polygon

        p = self._cache.get("poly")
        if p is None:
            p = self._cache["poly"] = Polygon(np.asarray(self.polygon_xy_m, float))
        return p

    def inner(self, extra_inset_m: float = 0.0):
        """The fence shrunk by its margin plus ``extra_inset_m`` (possibly empty or in pieces)."""
        d = round(self.margin_m + max(float(extra_inset_m), 0.0), 1)
        p = self._cache.get(("inner", d))
        if p is None:
            p = self._cache[("inner", d)] = self.polygon.buffer(-d, join_style="mitre") if d > 0 else self.polygon
        return p

    def _corridor(self):
        d = round(self.margin_m / 2.0, 1)
        p = self._cache.get(("corridor", d))
        if p is None:
            p = self._cache[("corridor", d)] = self.polygon.buffer(-d + _TOL_M, join_style="mitre")
        return p

    # -- points ----------------------------------------------------------------------------
    def contains(self, pts_xy_m) -> np.ndarray:
        """Which points lie inside the fence itself (with half a metre of numerical room)."""
        import shapely

        pts = np.asarray(pts_xy_m, float).reshape(-1, 2)
        return shapely.contains_xy(self.polygon.buffer(_TOL_M), pts[:, 0], pts[:, 1])

    def clip(self, pts_xy_m, extra_inset_m: float = 0.0, within=None) -> np.ndarray:
        """Points moved to the nearest point of the fence's interior (its margin plus
        ``extra_inset_m`` inside; if that is empty, the margin alone) and, when ``within`` (a
        shapely polygon, e.g. the area grown by the hearing range) overlaps it, of their overlap."""
        import shapely
        from shapely.ops import nearest_points

        pts = np.asarray(pts_xy_m, float).reshape(-1, 2)
        if not len(pts):
            return pts
        region = self.inner(extra_inset_m)
        if region.is_empty:
            region = self.inner(0.0)
        if region.is_empty:
            raise InfeasibleError(f"the geofence leaves no room inside its {self.margin_m:g} m margin")
        if within is not None:
            both = region.intersection(within)
            if not both.is_empty and both.area > 1.0:
                region = both
        inside = shapely.contains_xy(region, pts[:, 0], pts[:, 1])
        out = pts.copy()
        for i in np.flatnonzero(~inside):
            q = nearest_points(region, shapely.Point(pts[i]))[0]
            out[i] = (q.x, q.y)
        return out

    # -- legs ------------------------------------------------------------------------------
    def leg_inside(self, a, b, *, ends=()) -> bool:
        """Whether the leg a->b stays inside the fence shrunk by half its margin; near a point of
        ``ends`` (launch point, vehicle position), which may lie on the fence, inside the fence."""
        from shapely.geometry import LineString, Point

        a, b = np.asarray(a, float), np.asarray(b, float)
        line = LineString([a, b]) if np.linalg.norm(b - a) > 1e-9 else Point(a)
        return bool(self._leg_region(ends).covers(line))

    def _leg_region(self, ends):
        """Where legs may run: the corridor, and the fence itself near ``ends`` (cached per ends:
        a detour's search tests every pair of corners)."""
        from shapely.geometry import Point
        from shapely.ops import unary_union

        key = ("legs", tuple((round(float(e[0]), 2), round(float(e[1]), 2)) for e in ends))
        region = self._cache.get(key)
        if region is None:
            region = self._corridor()
            if ends:
                near = unary_union([Point(e).buffer(self.margin_m) for e in ends])
                region = region.union(near.intersection(self.polygon.buffer(_TOL_M)))
            if len(self._cache) > 256:  # vehicle positions make new keys: keep the cache small
                self._cache = {k: v for k, v in self._cache.items() if not (isinstance(k, tuple) and k[0] == "legs")}
            self._cache[key] = region
        return region

    def _nodes(self) -> np.ndarray:
        n = self._cache.get("nodes")
        if n is None:
            inner = self.inner(0.0).simplify(1.0)
            rings = [np.asarray(g.exterior.coords)[:-1] for g in getattr(inner, "geoms", [inner]) if not g.is_empty]
            n = self._cache["nodes"] = np.vstack(rings) if rings else np.zeros((0, 2))
        return n

    def detour(self, a, b, *, ends=()) -> np.ndarray:
        """The corners to fly through between a and b (none when the straight leg is inside):
        the shortest path through the shrunk fence's vertices whose every leg is inside."""
        if self.leg_inside(a, b, ends=ends):
            return np.zeros((0, 2))
        nodes = self._nodes()
        pts = [np.asarray(a, float), np.asarray(b, float)] + [q for q in nodes]
        n = len(pts)
        dist = [math.inf] * n
        prev = [-1] * n
        dist[0] = 0.0
        heap = [(0.0, 0)]
        seen = [False] * n
        while heap:
            d, u = heapq.heappop(heap)
            if seen[u]:
                continue
            seen[u] = True
            if u == 1:
                break
            for v in range(1, n):
                if seen[v]:
                    continue
                w = float(np.linalg.norm(pts[v] - pts[u]))
                if d + w >= dist[v] or not self.leg_inside(pts[u], pts[v], ends=ends):
                    continue
                dist[v] = d + w
                prev[v] = u
                heapq.heappush(heap, (dist[v], v))
        if not math.isfinite(dist[1]):
            raise InfeasibleError(
                f"no path inside the geofence from ({a[0]:.0f}, {a[1]:.0f}) m to "
                f"({b[0]:.0f}, {b[1]:.0f}) m (local east, north of the launch point) keeps its "
                f"{self.margin_m:g} m margin")
        path = []
        u = prev[1]
        while u > 0:
            path.append(pts[u])
            u = prev[u]
        return np.asarray(path[::-1], float).reshape(-1, 2)

    def route(self, pts_xy_m, *, start_xy_m=None, end_xy_m=None) -> tuple[np.ndarray, np.ndarray]:
        """``pts_xy_m`` flown from ``start_xy_m`` and back to ``end_xy_m`` (either may be None),
        with detour corners inserted where a leg would leave the fence. The points themselves are
        not moved (clip them first). Returns (points with detours, the index of each given point
        in it); the detours to ``end_xy_m`` come last."""
        pts = np.asarray(pts_xy_m, float).reshape(-1, 2)
        ends = tuple(np.asarray(e, float)[:2] for e in (start_xy_m, end_xy_m) if e is not None)
        out, idx = [], []
        prev = None if start_xy_m is None else np.asarray(start_xy_m, float)[:2]
        for q in pts:
            if prev is not None:
                out.extend(self.detour(prev, q, ends=ends))
            idx.append(len(out))
            out.append(q)
            prev = q
        if end_xy_m is not None and prev is not None:
            out.extend(self.detour(prev, np.asarray(end_xy_m, float)[:2], ends=ends))
        return np.asarray(out, float).reshape(-1, 2), np.asarray(idx, int)

    def clip_route(self, pts_xy_m, *, start_xy_m, end_xy_m) -> np.ndarray:
        """A route through ``pts_xy_m`` (from ``start_xy_m`` back to ``end_xy_m``, neither
        returned) kept inside: each leg, moved sideways by up to the margin where that keeps more
        of it (:meth:`_best_shift`), cut to its part inside the fence's margin (a scan lane keeps
        its direction; a leg wholly outside is dropped), and the pieces joined round the fence's
        corners (:meth:`detour`)."""
        from shapely.geometry import LineString, Point

        pts = np.asarray(pts_xy_m, float).reshape(-1, 2)
        inner = self.inner(0.0)
        if inner.is_empty:
            raise InfeasibleError(f"the geofence leaves no room inside its {self.margin_m:g} m margin")
        region = inner.buffer(_TOL_M, join_style="mitre")  # a lane on the margin's edge is kept whole
        pieces: list[np.ndarray] = []
        for a, b in zip(pts[:-1], pts[1:]):
            if np.linalg.norm(b - a) < 1e-9:
                continue
            leg, parts = self._best_shift(region, a, b)
            parts.sort(key=lambda g: leg.project(Point(g.coords[0])) + leg.project(Point(g.coords[-1])))
            for g in parts:
                c = np.asarray(g.coords, float)[[0, -1]]
                if leg.project(Point(c[0])) > leg.project(Point(c[1])):
                    c = c[::-1]
                pieces.append(c)
        if len(pts) == 1 or not pieces:  # a single point, or a route wholly outside: its nearest inside
            keep = self.clip(pts[:1] if not pieces else pts)
            pieces = [keep]
        out = np.vstack(pieces)
        keep = [0] + [k for k in range(1, len(out)) if np.linalg.norm(out[k] - out[k - 1]) > 1.0]
        routed, _ = self.route(out[keep], start_xy_m=start_xy_m, end_xy_m=end_xy_m)
        return routed

    def _best_shift(self, region, a, b):
        """The leg a->b, or a parallel copy moved sideways by up to the margin (plus 5 m), whose
        part inside ``region`` is longest (the least move among equals): an outer scan lane
        planned half a metre inside the area's edge, which is also the fence, moves in by the
        margin instead of being dropped. Returns (that leg, its inside pieces)."""
        from shapely.geometry import LineString

        d = (b - a) / np.linalg.norm(b - a)
        n = np.array([-d[1], d[0]])
        best = None
        for s in sorted(set(np.r_[0.0, np.arange(2.5, self.margin_m + 5.0 + 1e-9, 2.5)]) | {self.margin_m + 5.0}):
            for sign in ((1.0,) if s == 0 else (1.0, -1.0)):
                leg = LineString([a + sign * s * n, b + sign * s * n])
                cut = region.intersection(leg)
                parts = [g for g in getattr(cut, "geoms", [cut]) if g.geom_type == "LineString" and g.length > 1.0]
                got = sum(g.length for g in parts)
                if best is None or got > best[0] + 1.0:
                    best = (got, leg, parts)
        return best[1], best[2]

    def outside_legs(self, pts_xy_m, *, ends=()) -> list[int]:
        """Indices k of the legs pts[k] -> pts[k+1] that leave the fence itself (the final check)."""
        from shapely.geometry import LineString

        pts = np.asarray(pts_xy_m, float).reshape(-1, 2)
        poly = self.polygon.buffer(_TOL_M)
        return [k for k in range(len(pts) - 1)
                if np.linalg.norm(pts[k + 1] - pts[k]) > 1e-9 and not poly.covers(LineString(pts[k:k + 2]))]


_FENCES: dict = {}


def for_scenario(sc) -> Geofence | None:
    """The scenario's geofence in its local frame, or None when it gives none."""
    ll = getattr(sc, "geofence_latlon_deg", ())
    if not ll:
        return None
    key = (tuple(ll), tuple(sc.launch_latlon_deg), float(sc.area.geofence_margin_m))
    g = _FENCES.get(key)
    if g is None:
        xy = sc.frame.to_local_xy(np.asarray(ll, float))
        x, y = xy[:, 0], xy[:, 1]
        if np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) < 0:
            xy = xy[::-1].copy()
        g = _FENCES[key] = Geofence(xy, float(sc.area.geofence_margin_m))
    return g


def default_for(sc) -> Geofence:
    """The fence of a scenario that gives none: its search area grown by ``area.default_geofence_m``,
    joined (when the launch point lies beyond that) by the way from the launch point to the area,
    as wide; the scenario's ``area.geofence_margin_m`` is kept inside it like any fence's."""
    from shapely.geometry import LineString, Point, Polygon
    from shapely.ops import nearest_points

    grow, margin = float(sc.area.default_geofence_m), float(sc.area.geofence_margin_m)
    key = ("default", tuple(map(tuple, np.round(sc.area_xy_m(), 3))), tuple(sc.launch_latlon_deg), grow, margin)
    g = _FENCES.get(key)
    if g is None:
        area = Polygon(sc.area_xy_m())
        # round corners: the points kept ``margin`` inside are then at most grow - margin from the
        # area at its corners too (a mitred corner put a look 28 m beyond a 20 m promise)
        poly = area.buffer(grow, quad_segs=4)
        launch = Point(0.0, 0.0)
        if not poly.buffer(-margin).covers(launch):  # a launch beside the area: the way there is in it
            near = nearest_points(area, launch)[0]
            poly = poly.union(LineString([(0.0, 0.0), (near.x, near.y)]).buffer(grow, quad_segs=4))
        poly = poly.simplify(0.5)
        xy = np.asarray(poly.exterior.coords, float)[:-1]
        x, y = xy[:, 0], xy[:, 1]
        if np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) < 0:
            xy = xy[::-1].copy()
        g = _FENCES[key] = Geofence(xy, margin)
    return g


def flight_fence(sc) -> Geofence:
    """The fence the daemon's flights stay inside: the scenario's geofence, else :func:`default_for`."""
    return for_scenario(sc) or default_for(sc)


def describe(sc, scan=None) -> str:
    """One sentence for the operator: which fence the flights stay inside. ``scan``: the planned
    scan (scan.ScanPlan); without a geofence its lane ends and turns, planned to cover the area's
    edges, are not clipped to the default fence, and a second sentence says how far they reach."""
    margin = float(sc.area.geofence_margin_m)
    if for_scenario(sc) is not None:
        return f"Every flight stays inside the scenario's geofence (points {margin:g} m inside it)."
    grow = float(sc.area.default_geofence_m)
    from shapely.geometry import Point, Polygon

    way = Polygon(sc.area_xy_m()).distance(Point(0.0, 0.0))
    via = (f" with the way from the launch point ({way:.0f} m from the area), as wide," if way > grow - margin
           else "")
    text = (f"No geofence given: the search area plus {grow:g} m (area.default_geofence_m){via} is the fence; every "
            f"look and pass stays inside it (points {margin:g} m inside, so at most {grow - margin:g} m beyond the "
            f"area{' or that way' if via else ''}).")
    beyond = scan_beyond_m(sc, scan) if scan is not None else 0.0
    if beyond > grow - margin + _TOL_M:
        text += (f" The scan's lane ends and turns, planned to cover the area's edges, reach up to {beyond:.0f} m "
                 "beyond the area (give area.geofence_deg to keep the scan inside a fence too).")
    return text


def scan_beyond_m(sc, scan) -> float:
    """How far [m] the planned ``scan``'s routes (from and back to the launch point excluded: that
    way is in :func:`default_for`'s fence) reach beyond the search area."""
    import shapely
    from shapely.geometry import LineString, Polygon

    area = Polygon(sc.area_xy_m())
    worst = 0.0
    for v in scan.vehicles:
        wps = np.asarray(v.waypoints_xy_m, float).reshape(-1, 2)
        if len(wps) < 2:
            continue
        line = LineString(wps)
        pts = shapely.line_interpolate_point(line, np.append(np.arange(0.0, line.length, 2.0), line.length))
        worst = max(worst, float(np.max(shapely.distance(area, pts))))
    return worst
