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


def _static_bound_s(problem: RoutingProblem, radii: np.ndarray) -> float:
    V = problem.speed_m_s
    s, h = problem.starts_xy_m, problem.homes_xy_m
    lb = float(np.max(np.linalg.norm(h - s, axis=1))) / V
    if len(problem.targets) == 0:
        return lb
    c = problem.centres_xy_m
    _, single = best_point_between(s[None], h[None], c[:, None], radii[:, None])
    lb = max(lb, float(np.max(np.min(single, axis=1))) / V)
    gap = np.maximum(np.linalg.norm(c[:, None] - c[None], axis=2) - radii[:, None] - radii[None], 0.0)
    depots = np.concatenate([s, h])
    dep = np.maximum(np.min(np.linalg.norm(c[:, None] - depots[None], axis=2), axis=1) - radii, 0.0)
    n = len(c)
    d = np.zeros((n + 1, n + 1))
    d[:n, :n] = gap
    d[n, :n] = d[:n, n] = dep
    mst = _prim_mst_m(d)
    return max(lb, mst / (len(problem.vehicles) * V))


def lower_bound_s(problem: RoutingProblem) -> float:
    """A makespan [s] no plan can beat (see the module docstring)."""
    radii = problem.radii_m
    speeds = np.linalg.norm(problem.velocities_m_s, axis=1) if problem.targets else np.zeros(0)
    if not np.any(speeds > 0):
        return _static_bound_s(problem, radii)
    lo, hi = 0.0, _static_bound_s(problem, radii)
    # g(T) <= g(0) = hi, so the fixed point lies in [0, hi].
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        if _static_bound_s(problem, radii + speeds * mid) > mid:
            lo = mid
        else:
            hi = mid
    return lo
