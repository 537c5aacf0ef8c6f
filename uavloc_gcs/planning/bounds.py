"""Lower bounds on the makespan (SPEC §3.2).

* every vehicle must get home: ``max_v |home_v - start_v| / V``;
* every target must be visited by someone: ``max_i min_v (start_v -> disk_i -> home_v) / V``;
* the routes together span all disks: ``(MST over the disks and one merged depot node, with gap
  distances max(0, |c_i - c_j| - r_i - r_j)) / (m V)`` (merging all starts/homes into one node only
  shortens, and every route touches it).

Moving targets: a pass at time ``t <= T`` finds a centre within ``|v| T`` of its ``t0`` position,
so the bound computed with radii ``r + |v| T`` holds for any plan of makespan ``T``. The bound
``g(T)`` decreases with ``T``, so every plan satisfies ``T >= g(T)``, i.e. ``T >= T*`` with
``T* = g(T*)`` found by bisection.
"""

from __future__ import annotations

import numpy as np

from .access import best_point_between
from .problem import RoutingProblem


def _prim_mst_m(d: np.ndarray) -> float:
    n = d.shape[0]
    if n <= 1:
        return 0.0
    in_tree = np.zeros(n, dtype=bool)
    in_tree[0] = True
    best = d[0].copy()
    total = 0.0
    for _ in range(n - 1):
        cand = np.where(in_tree, np.inf, best)
        j = int(np.argmin(cand))
        total += float(cand[j])
        in_tree[j] = True
        best = np.minimum(best, d[j])
    return total


class _Geometry:
    """The radius-independent parts of the static bound, computed once per problem."""

    def __init__(self, problem: RoutingProblem) -> None:
        self.V = problem.speed_m_s
        self.m = len(problem.vehicles)
        self.s, self.h = problem.starts_xy_m, problem.homes_xy_m
        self.home_s = float(np.max(np.linalg.norm(self.h - self.s, axis=1))) / self.V
        self.n = len(problem.targets)
        if self.n:
            self.c = problem.centres_xy_m
            self.cc = np.linalg.norm(self.c[:, None] - self.c[None], axis=2)
            depots = np.concatenate([self.s, self.h])
            self.cdep = np.min(np.linalg.norm(self.c[:, None] - depots[None], axis=2), axis=1)

    def visit_s(self, radii: np.ndarray) -> float:
        """Every target visited by someone: max_i min_v (start_v -> disk_i -> home_v) / V."""
        _, single = best_point_between(self.s[None], self.h[None], self.c[:, None], radii[:, None])
        return float(np.max(np.min(single, axis=1))) / self.V

    def mst_s(self, radii: np.ndarray) -> float:
        """MST over the disks and the merged depot node, gap distances, over m vehicles."""
        n = self.n
        d = np.zeros((n + 1, n + 1))
        d[:n, :n] = np.maximum(self.cc - radii[:, None] - radii[None], 0.0)
        d[n, :n] = d[:n, n] = np.maximum(self.cdep - radii, 0.0)
        return _prim_mst_m(d) / (self.m * self.V)

    def bound_s(self, radii: np.ndarray) -> float:
        if self.n == 0:
            return self.home_s
        return max(self.home_s, self.visit_s(radii), self.mst_s(radii))


def _static_bound_s(problem: RoutingProblem, radii: np.ndarray) -> float:
    return _Geometry(problem).bound_s(radii)


def _fixed_point_s(g, hi_s: float, tol_s: float) -> float:
    """Largest ``T`` known to satisfy ``T < T*`` (within ``tol_s``), where ``T* = g(T*)`` for a
    non-increasing ``g`` with ``g(hi_s) <= hi_s``. Regula falsi (Illinois) on ``g(T) - T``, which
    is strictly decreasing; keeps a bracket, so the returned lower end is always a valid bound."""
    lo, hi = 0.0, hi_s
    f_lo, f_hi = g(lo) - lo, g(hi) - hi
    if f_lo <= 0:
        return 0.0
    if f_hi >= 0:
        return hi
    side = 0
    for _ in range(100):
        if hi - lo <= tol_s:
            break
        mid = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        if not (lo < mid < hi) or (hi - lo) < 4 * tol_s:
            mid = 0.5 * (lo + hi)
        f = g(mid) - mid
        if f > 0:
            lo, f_lo = mid, f
            if side == 1:
                f_hi *= 0.5
            side = 1
        elif f < 0:
            hi, f_hi = mid, f
            if side == -1:
                f_lo *= 0.5
            side = -1
        else:
            return mid
    return lo


def lower_bound_s(problem: RoutingProblem) -> float:
    """A makespan [s] no plan can beat (see the module docstring).

    With moving targets, ``T* = max(T_home, T*_visit, T*_mst)``: every term of ``g`` is
    non-increasing in ``T``, so ``T >= g(T)`` holds exactly when ``T`` is at least each term's
    own fixed point. Each is found by a bracketing root search to 1e-6 s (relative 1e-9)."""
    geo = _Geometry(problem)
    radii = problem.radii_m
    speeds = np.linalg.norm(problem.velocities_m_s, axis=1) if problem.targets else np.zeros(0)
    if not np.any(speeds > 0):
        return geo.bound_s(radii)
    out = geo.home_s
    for term in (geo.visit_s, geo.mst_s):
        hi = term(radii)  # g(T) <= g(0), so the fixed point lies in [0, g(0)]
        if hi > out:  # a term whose value at T = 0 is below the others cannot raise the bound
            out = max(out, _fixed_point_s(lambda t, term=term: term(radii + speeds * t), hi,
                                          max(1e-6, 1e-9 * hi)))
    return out
