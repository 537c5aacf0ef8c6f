"""Intersecting-annuli localization (static person), as used by the RL baseline (science.md §6).

Each hover measurement of one person gives an annulus ``[inner, outer]`` of horizontal radii about
the hover point. The position estimate minimizes ``sum_i (|w_i - x| - (I_i + O_i)/2)^2``; the error
bound is the largest distance from the estimate to the border points of the intersection of all
annuli (pairwise circle intersections that lie inside every annulus).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

TOL_M = 0.5  # border points this close outside an annulus still count (rounding)
MAX_ANNULI = 8  # most recent annuli used per person (older ones add little and cost O(n^2))


@dataclass(frozen=True)
class Annulus:
    centre_xy_m: tuple[float, float]
    inner_m: float
    outer_m: float
    t_s: float


def annulus_from_slots(centre_xy_m, log_range_mean: float, n_samples: int, *, s_per_sample: float,
                       altitude_m: float, z: float, t_s: float) -> Annulus:
    """Annulus of horizontal radii from the ML log-range of ``n_samples`` i.i.d. samples."""
    half = z * s_per_sample / math.sqrt(max(n_samples, 1))
    d_lo, d_hi = math.exp(log_range_mean - half), math.exp(log_range_mean + half)
    inner = math.sqrt(max(0.0, d_lo * d_lo - altitude_m * altitude_m))
    outer = math.sqrt(max(0.0, d_hi * d_hi - altitude_m * altitude_m))
    return Annulus((float(centre_xy_m[0]), float(centre_xy_m[1])), inner, outer, float(t_s))


def _arrays(annuli: list[Annulus]):
    w = np.array([a.centre_xy_m for a in annuli], dtype=float).reshape(-1, 2)
    inner = np.array([a.inner_m for a in annuli], dtype=float)
    outer = np.array([a.outer_m for a in annuli], dtype=float)
    return w, inner, outer


def border_points(annuli: list[Annulus]) -> np.ndarray:
    """Pairwise circle intersections lying inside every annulus, (K, 2)."""
    w, inner, outer = _arrays(annuli)
    c = np.concatenate([w, w])
    r = np.concatenate([inner, outer])
    keep = r > 0
    c, r = c[keep], r[keep]
    n = len(r)
    if n < 2:
        return np.zeros((0, 2))
    i, j = np.triu_indices(n, 1)
    d_vec = c[j] - c[i]
    d = np.linalg.norm(d_vec, axis=1)
    ok = (d > 1e-9) & (d <= r[i] + r[j]) & (d >= np.abs(r[i] - r[j]))
    i, j, d_vec, d = i[ok], j[ok], d_vec[ok], d[ok]
    a = (r[i] ** 2 - r[j] ** 2 + d**2) / (2 * d)
    h = np.sqrt(np.maximum(r[i] ** 2 - a**2, 0.0))
    u = d_vec / d[:, None]
    base = c[i] + a[:, None] * u
    perp = np.column_stack([-u[:, 1], u[:, 0]])
    pts = np.concatenate([base + h[:, None] * perp, base - h[:, None] * perp])
    if len(pts) == 0:
        return pts
    dist = np.linalg.norm(pts[:, None, :] - w[None, :, :], axis=2)
    inside = np.all((dist >= inner - TOL_M) & (dist <= outer + TOL_M), axis=1)
    return pts[inside]


def estimate(annuli: list[Annulus], starts: np.ndarray | None = None) -> np.ndarray:
    """Least-squares position [m] from the annuli' mid radii (multi-start)."""
    w, inner, outer = _arrays(annuli)
    mid = 0.5 * (inner + outer)
    if len(annuli) == 1:
        return w[0] + np.array([mid[0], 0.0])

    def resid(x):
        return np.linalg.norm(w - x, axis=1) - mid

    cand = [w.mean(axis=0)]
    if starts is not None and len(starts):
        cand.extend(np.asarray(starts, dtype=float)[:4])
    best = None
    for x0 in cand:
        r = least_squares(resid, x0, method="lm" if len(annuli) >= 2 else "trf")
        if best is None or r.cost < best.cost:
            best = r
    return best.x


def error_bound_m(annuli: list[Annulus], x_m: np.ndarray, pts: np.ndarray | None = None) -> float:
    """Farthest border point of the annuli's intersection from ``x_m`` [m] (inf if empty)."""
    if len(annuli) == 1:
        a = annuli[0]
        return float(np.hypot(*(np.asarray(x_m) - a.centre_xy_m))) + a.outer_m
    pts = border_points(annuli) if pts is None else pts
    if len(pts) == 0:
        return math.inf
    return float(np.max(np.linalg.norm(pts - np.asarray(x_m), axis=1)))


def localize(annuli: list[Annulus], max_annuli: int = MAX_ANNULI, start=None, silent_xy_m=None,
             range_m: float = math.inf) -> tuple[np.ndarray, float, list[Annulus]]:
    """Estimate and error bound from the ``max_annuli`` most recent annuli. If they have no common
    intersection (noise beyond the annulus width, or the person moved, which the static model
    cannot explain), the annulus the least-squares estimate violates most is dropped, repeatedly.

    ``silent_xy_m`` are hover points that did not hear the person: border points within
    ``range_m`` of one are not candidates (this resolves the mirror image of collinear hovers)."""
    used = sorted(annuli, key=lambda a: a.t_s)[-max_annuli:]
    silent = None if silent_xy_m is None or not len(silent_xy_m) else np.asarray(silent_xy_m, float).reshape(-1, 2)
    extra = None if start is None else np.asarray(start, dtype=float).reshape(1, 2)
    while True:
        if len(used) == 1:
            x = _on_ring(used[0], silent, range_m, extra)
            return x, error_bound_m(used, x), used
        pts = border_points(used)
        if silent is not None and len(pts):
            heard_ok = np.all(np.linalg.norm(pts[:, None, :] - silent[None], axis=2) > range_m, axis=1)
            pts = pts[heard_ok] if heard_ok.any() else pts
        starts = pts if extra is None else np.vstack([pts, extra])
        x = estimate(used, starts) if silent is None or not len(pts) else _nearest_fit(used, pts)
        if len(pts):
            return x, error_bound_m(used, x, pts), used
        used.pop(_outlier(used, x))


def _nearest_fit(annuli: list[Annulus], pts: np.ndarray) -> np.ndarray:
    """Least squares started from the kept border points only, keeping the best fit among them
    (the unconstrained fit may slide back to an excluded mirror region)."""
    w, inner, outer = _arrays(annuli)
    mid = 0.5 * (inner + outer)
    best, best_cost = pts[0], math.inf
    for x0 in pts[:4]:
        r = least_squares(lambda x: np.linalg.norm(w - x, axis=1) - mid, x0, method="lm")
        if np.min(np.linalg.norm(pts - r.x, axis=1)) > 0.5 * float(np.max(outer - inner) + 10):
            continue  # slid away from the kept region
        if r.cost < best_cost:
            best, best_cost = r.x, r.cost
    if not math.isfinite(best_cost):
        best = pts.mean(axis=0)
    return best


def _outlier(used: list[Annulus], x: np.ndarray) -> int:
    """Index of the annulus to drop: the one whose removal leaves an intersecting set that fits
    best; if no single removal does, the one the estimate ``x`` violates most."""
    best, best_cost = None, math.inf
    for i in range(len(used)):
        rest = used[:i] + used[i + 1:]
        pts = border_points(rest) if len(rest) > 1 else np.zeros((0, 2))
        if len(rest) > 1 and not len(pts):
            continue
        w, inner, outer = _arrays(rest)
        xi = estimate(rest, pts)
        cost = float(np.sum((np.linalg.norm(w - xi, axis=1) - 0.5 * (inner + outer)) ** 2))
        if cost < best_cost:
            best, best_cost = i, cost
    if best is not None:
        return best
    w, inner, outer = _arrays(used)
    dist = np.linalg.norm(w - x, axis=1)
    violation = np.maximum(np.maximum(inner - dist, dist - outer), 0.0) / np.maximum(outer - inner, 1.0)
    return int(np.argmax(violation))


def _on_ring(a: Annulus, silent, range_m: float, previous) -> np.ndarray:
    """A point on a single annulus' mid circle: the previous estimate's direction, or east, moved
    to the nearest direction not ruled out by a silent hover point."""
    c = np.asarray(a.centre_xy_m)
    mid = 0.5 * (a.inner_m + a.outer_m)
    ang = np.linspace(0.0, 2 * np.pi, 72, endpoint=False)
    ring = c + mid * np.column_stack([np.cos(ang), np.sin(ang)])
    ok = np.ones(len(ring), bool)
    if silent is not None:
        ok = np.all(np.linalg.norm(ring[:, None] - silent[None], axis=2) > range_m, axis=1)
        if not ok.any():
            ok[:] = True
    ref = c + np.array([mid, 0.0]) if previous is None else np.asarray(previous).reshape(2)
    cand = ring[ok]
    return cand[int(np.argmin(np.linalg.norm(cand - ref, axis=1)))]
