"""Where each look goes (the step between judging and planning in :class:`~.policy.SearchPolicy`).

For every pending person: the point to pass and the look radius around it (the access radius of
the estimate for the planned pass time, cut for a repeated look, moved beside the person, kept off
a mirror line), turned into orbit looks where phones send bursts (:mod:`.orbit`), and every look
point kept inside the area grown by its hearing margin and inside the scenario's geofence. The
data these read are :mod:`.hearing`'s and :mod:`.judging`'s; :mod:`.policy` routes the targets. The
module switches below are read at call time: ``uavloc bench looks`` variants set them.
"""

from __future__ import annotations

import math

import numpy as np

from .. import geofence
from ..errors import EstimationError
from ..observations import SlotBatch
from . import orbit as orb
from . import targets as tg
from .hearing import _Person
from .judging import Judging

# Every look point lies inside the search area grown by this fraction of the horizontal hearing
# range (1: 112 m in the paper scenario), the stated margin of issue 26. None: no limit.
LOOK_AREA_MARGIN: float | None = 1.0
ACCESS_TIME_QUANTUM_S = 2.0  # access radii are computed for pass times rounded up to this
# A repeated look whose vehicle is already inside the look radius would be planned at the
# vehicle's own position: a look of zero length that adds nothing (measured on PX4 SITL: three
# such looks while the vehicle flew home, radius 15.8 -> 40.8 m, given up). Its radius is cut to
# this fraction of that vehicle's distance, so the look flies towards the person.
INSIDE_LOOK_FRACTION = 0.5
# A repeated look (the last one heard the person without locating them) is planned beside the
# person, across the line from the nearest vehicle, alternating sides: its disk is centred one
# look radius off the estimate, perpendicular to that line, with this fraction of the radius.
# Otherwise a vehicle near home flies out to the near edge of the disk and straight back along the
# line it came, and the looks repeat one another (measured on PX4 SITL: four looks at
# (142,104), (147,99), (141,95), (154,102) m for an estimate at (165,110) m, given up).
# `uavloc bench looks --variants default,radial`: SITL sparse-scan scenario, 120 worlds, 351/360
# located against 345/360, -5.5 +- 3.3 s; paper scenario, 20 worlds, 400/400 against 395/400,
# -4.2 +- 4.0 s. None: off.
SIDEWAYS_LOOK_FRACTION = 0.25


def _sideways(centre: np.ndarray, radius: float, starts: np.ndarray, unresolved: int) -> tuple[np.ndarray, float]:
    """The disk of a repeated look moved beside the person (see SIDEWAYS_LOOK_FRACTION)."""
    start = starts[int(np.argmin(np.linalg.norm(starts - centre, axis=1)))]
    d = centre - start
    length = float(np.hypot(*d))
    if length < 1e-6 or radius <= 0.0:
        return centre, radius
    side = 1.0 if unresolved % 2 else -1.0
    normal = side * np.array([-d[1], d[0]]) / length
    return centre + normal * radius, SIDEWAYS_LOOK_FRACTION * radius


class Aiming(Judging):
    """The look targets of the pending people; mixed under SearchPolicy, whose state it reads."""

    def _targets(self, t_s: float, vehicles: list, planned_times: dict[int, float] | None,
                 previous: list | None = None) -> list:
        """Planner targets of the pending people. ``planned_times``: pass times [s] of a plan just
        made (the recheck); ``previous``: the targets that plan was made for, whose look radii are
        kept where the planned pass is no later than the time they were computed for (an earlier
        pass only allows a larger radius)."""
        from ..planning import Target

        starts = np.array([v.start_xy_m for v in vehicles], dtype=float).reshape(-1, 2)
        before = {t.id: t for t in previous} if previous is not None else {}
        out = []
        for eid in self.pending_ids():
            if eid in self._deferred:  # waits for a fresh pack (sorties): not in this plan
                continue
            p = self._people[eid]
            cand = self._candidate(p) if self._ok(p) else None
            if cand is None:  # heard, but too little to fit: fly over where it was heard
                xy = SlotBatch.concat(p.batches).xyz_m[:, :2].mean(axis=0)
                out.append(Target(str(eid), (float(xy[0]), float(xy[1])), (0.0, 0.0), 0.0))
                continue
            centre = cand.at(t_s)
            near = float(np.min(np.linalg.norm(starts - centre, axis=1))) if len(starts) else math.inf
            if planned_times is not None and eid in planned_times:
                t_pass = planned_times[eid]
            elif eid in self._awaiting and self._awaiting[eid] > t_s:
                t_pass = self._awaiting[eid]  # the last plan's pass time: a warm start keeps most
            else:
                t_pass = t_s + (near if math.isfinite(near) else 0.0) / self.speed_m_s
            old = before.get(str(eid))
            if old is not None and t_pass <= self._target_t_pass.get(eid, -math.inf):
                out.append(old)
                continue
            rho = self._access_radius(p, t_pass)
            sep = self._separation(p)
            vel = cand.velocity_m_s if self.model_motion else np.zeros(2)
            vmax_plan = 0.45 * self.speed_m_s
            speed = float(np.hypot(*vel))
            if speed > vmax_plan:
                vel = vel * (vmax_plan / speed)
            unresolved = p.looks - p.misses
            radius = tg.look_radius_m(rho, sep, unresolved)
            if unresolved > 0 and INSIDE_LOOK_FRACTION is not None and near < radius:
                radius = INSIDE_LOOK_FRACTION * near
            elif unresolved > 0 and sep is None and SIDEWAYS_LOOK_FRACTION is not None and len(starts):
                centre, radius = _sideways(centre, radius, starts, unresolved)
            out.append(Target(str(eid), (float(centre[0]), float(centre[1])),
                              (float(vel[0]), float(vel[1])), radius))
        return orb.orbit_targets(self, t_s, out)  # burst world: orbit looks (search/orbit.py)

    def _access_radius(self, p: _Person, t_pass_s: float) -> float:
        """The access radius [m] of ``p``'s estimate for a pass at ``t_pass_s``, rounded up to the
        next ACCESS_TIME_QUANTUM_S (a later pass gets a smaller radius, so this errs safe) and
        cached per estimate: replans minutes apart mostly ask the same question again."""
        from ..estimation import access_radius_m

        t_key = math.ceil(t_pass_s / ACCESS_TIME_QUANTUM_S) * ACCESS_TIME_QUANTUM_S
        self._target_t_pass[p.emitter_id] = t_key
        key = (p.emitter_id, t_key)
        hit = self._access_cache.get(key)
        if hit is not None and hit[0] is p.estimate:
            return hit[1]
        try:
            rho = float(access_radius_m(
                p.estimate, t_pass_s=t_key, altitude_m=self.scenario.fleet.altitude_m,
                speed_m_s=self.speed_m_s, channel=self.channel, required_accuracy_m=self.required_m,
                comm_range_m=self.scenario.fleet.comm_range_m))
        except (EstimationError, ValueError):
            rho = 0.0
        self._access_cache[key] = (p.estimate, rho)
        return rho

    def _inside_reach(self, pts: np.ndarray, inset_m: float = 0.0) -> np.ndarray:
        """Look points moved into the search area grown by the hearing range (``LOOK_AREA_MARGIN``
        of it): people are searched for inside the area, and from that margin a vehicle still
        hears its edge. A look at an estimate predicted far outside (a wide field-world posterior,
        a walker extrapolated) flew 1.1 km north of the area in the field demo; it now goes as far
        as the margin and no further. ``inset_m``: the margin less this much (at least the area
        itself), for an orbit's centre, whose circle of that radius must stay within the margin.
        With a scenario geofence, also inside it by its margin (``uavloc_gcs.geofence``)."""
        import shapely
        from shapely.geometry import Polygon
        from shapely.ops import nearest_points

        pts = np.asarray(pts, dtype=float).reshape(-1, 2)
        fence = geofence.for_scenario(self.scenario)
        if not len(pts) or (LOOK_AREA_MARGIN is None and fence is None):
            return pts
        grow = max((LOOK_AREA_MARGIN or 0.0) * self.range_m - float(inset_m), 0.0)
        if self._reach_poly is None:
            self._reach_poly = {}
        poly = self._reach_poly.get(round(grow, 1))
        if poly is None:
            poly = self._reach_poly[round(grow, 1)] = Polygon(self.area_xy_m).buffer(grow)
        if fence is not None:  # and inside the scenario's geofence, its margin (and the orbit) in
            return fence.clip(pts, extra_inset_m=inset_m, within=None if LOOK_AREA_MARGIN is None else poly)
        inside = shapely.contains_xy(poly, pts[:, 0], pts[:, 1])
        out = pts.copy()
        for i in np.flatnonzero(~inside):
            q = nearest_points(poly.exterior, shapely.Point(pts[i]))[0]
            out[i] = (q.x, q.y)
        return out
