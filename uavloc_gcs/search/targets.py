"""Turning estimates into planner targets: which candidate to visit, where, and how close.

Pure functions over estimates (duck-typed against :mod:`uavloc_gcs.estimation`'s ``Estimate``):

- :func:`candidates` -- the primary solution and, when the estimator reports a mirror ambiguity,
  the reflected solution, each as ``(xy_m, velocity_m_s)`` at the estimate's reference time;
- :func:`inside_area` -- whether a point lies in the search polygon (within a margin); people are
  inside the area by assumption, so a mirror candidate well outside it is not a real alternative;
- :func:`look_radius_m` -- the horizontal radius within which a pass counts as a look. For an
  ambiguous person the radius is capped at a quarter of the candidate separation so the pass is
  off the mirror line and tells the two candidates apart (a pass along the mirror line would not).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Candidate:
    """A hypothesis about where a person is: position [m] at ``t_ref_s`` and velocity [m/s]."""

    xy_m: np.ndarray
    velocity_m_s: np.ndarray
    t_ref_s: float

    def at(self, t_s: float) -> np.ndarray:
        """Position [m] predicted at ``t_s`` with constant velocity."""
        return self.xy_m + self.velocity_m_s * (t_s - self.t_ref_s)


def _xy(value) -> np.ndarray | None:
    if value is None:
        return None
    if hasattr(value, "position_xy_m"):
        value = value.position_xy_m
    arr = np.asarray(value, dtype=float).reshape(-1)
    return arr[:2] if arr.size >= 2 and np.all(np.isfinite(arr[:2])) else None


def _velocity(value, fallback: np.ndarray) -> np.ndarray:
    v = getattr(value, "velocity_m_s", None)
    if v is None:
        return fallback
    arr = np.asarray(v, dtype=float).reshape(-1)
    return arr[:2] if arr.size >= 2 and np.all(np.isfinite(arr[:2])) else fallback


def estimate_t_ref_s(estimate, default: float) -> float:
    """The estimate's reference time [s] (the time its position refers to)."""
    t = getattr(estimate, "t_ref_s", None)
    return float(t) if t is not None and math.isfinite(float(t)) else float(default)


def candidates(estimate, t_ref_default_s: float) -> list[Candidate]:
    """[primary] or [primary, mirror] candidates of an estimate (mirror only when ambiguous)."""
    t_ref = estimate_t_ref_s(estimate, t_ref_default_s)
    p = _xy(estimate)
    v = _velocity(estimate, np.zeros(2))
    out = [Candidate(p, v, t_ref)] if p is not None else []
    if getattr(estimate, "ambiguous", False):
        mirror = getattr(estimate, "mirror", None)
        q = _xy(mirror)
        if q is not None and p is not None:
            out.append(Candidate(q, _velocity(mirror, v), t_ref))
    return out


def inside_area(area_xy_m: np.ndarray, xy_m: np.ndarray, margin_m: float = 0.0) -> bool:
    """True if ``xy_m`` is inside the polygon or within ``margin_m`` of its boundary."""
    poly = np.asarray(area_xy_m, dtype=float)
    x, y = float(xy_m[0]), float(xy_m[1])
    inside = False
    n = len(poly)
    for i in range(n):
        x1, y1 = poly[i]
        x2, y2 = poly[(i + 1) % n]
        if (y1 > y) != (y2 > y):
            xc = x1 + (y - y1) * (x2 - x1) / (y2 - y1)
            if xc > x:
                inside = not inside
    if inside or margin_m <= 0:
        return inside
    return boundary_distance_m(poly, xy_m) <= margin_m


def boundary_distance_m(area_xy_m: np.ndarray, xy_m: np.ndarray) -> float:
    """Distance [m] from a point to the polygon's boundary."""
    a = np.asarray(area_xy_m, dtype=float)
    b = np.roll(a, -1, axis=0)
    p = np.asarray(xy_m, dtype=float)[:2]
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0, 1)
    closest = a + t[:, None] * ab
    return float(np.min(np.linalg.norm(closest - p, axis=1)))


# Factor on the look radius per earlier look that heard the person without locating them; 1 = off.
# The access radius assumes a whole pass at that offset, but a look flies through one point of the
# disk, so a look at the edge of range can add almost nothing and the same look is planned again.
# Measured with `uavloc bench looks` (MLE-EPSO (M), paired worlds, 2026-11-24): on the SITL suite's
# sparse-scan scenario (benchmarks/scenarios/sitl_sparse_scan.toml, 3 static people, 40 worlds)
# 120/120 located against 115/120 with 1.0, 152.8 s against 159.8 s; on the paper scenario (20
# walkers, 20 worlds) 395/400 against 394/400, +1.1 +- 1.4 s. With the sideways looks added later
# (search.aiming.SIDEWAYS_LOOK_FRACTION) the two differ little: 120/120 both, 799/800 both (40 worlds).
LOOK_SHRINK = 0.5


def look_radius_m(access_radius_m: float, separation_m: float | None, unresolved_looks: int = 0,
                  shrink: float | None = None) -> float:
    """Look radius [m]: the access radius, capped at separation/4 for a mirror-ambiguous person,
    and multiplied by ``shrink`` (default LOOK_SHRINK) for every earlier look that heard the
    person without locating them.

    The access radius assumes a whole straight pass at that offset; the planner only flies
    *through* the access point, often as the end of a short hop from a vehicle already near it,
    so at the edge of range a look can add almost nothing (measured: a vehicle crept along a
    walker's 110 m ring, four looks, radius 91 -> 96 m, given up). Shrinking the radius brings
    the next pass closer, where it is informative whatever its length (on by default, measured:
    see LOOK_SHRINK).
    """
    r = access_radius_m if math.isfinite(access_radius_m) and access_radius_m > 0 else 0.0
    if separation_m is not None:
        r = min(r, 0.25 * separation_m)
    factor = LOOK_SHRINK if shrink is None else float(shrink)
    return max(r * factor ** max(int(unresolved_looks), 0), 0.0)
