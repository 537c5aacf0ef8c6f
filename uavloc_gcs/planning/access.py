"""Edge access: the best point on each disk for a fixed assignment and visiting order.

Static disks, fixed order: minimizing the route length over access points ``q_i`` with
``|q_i - c_i| <= r_i`` is convex (a sum of norms over a product of disks). We solve it by
block-coordinate descent: each point in turn moves to the exact minimizer of
``|a - q| + |q - b|`` over its disk given its neighbours ``a, b``:

* if the segment ``ab`` meets the disk, any point of the segment inside the disk is optimal; we
  take the one nearest the centre (it keeps slack for the neighbours' later moves);
* otherwise the minimizer is on the circle, on the short arc between the directions of ``a`` and
  ``b`` (the reflection point); the derivative along that arc changes sign exactly once, and a
  safeguarded Newton iteration on the angle finds it.

Every block step is exact (or, with few Newton steps, accepted only if it does not lengthen the
route), so the length decreases monotonically; the updates alternate between odd and even slots so
that a whole swarm of routes is processed by a few numpy operations. The test suite checks the
converged lengths against an independent brute-force optimizer.

Moving disks (centre ``c_i + v_i (t - t0)``): the access time of each point follows from the
distance flown before it, so we alternate "times from points" and "points on the disks at those
times". A change of ``dq`` metres in a point moves later access times by at most ``dq / V`` and
the disk centres by ``|v| dq / V``: the alternation is a contraction of factor ``|v| / V`` (1/16
for people walking at 1.5 m/s and vehicles at 25 m/s), so a few sweeps suffice. The approximation is
in the search only (a few sweeps); the final plan is iterated until every access point is within
its disk at the time the vehicle actually gets there (tested).
"""

from __future__ import annotations

import numpy as np

from .problem import RoutingProblem

_TWO_PI = 2.0 * np.pi


def _norm(v: np.ndarray) -> np.ndarray:
    return np.sqrt(v[..., 0] ** 2 + v[..., 1] ** 2)


def best_point_between(a, b, c, r, q_init=None, newton_steps: int = 30):
    """Point ``q`` with ``|q - c| <= r`` minimizing ``|a - q| + |q - b|`` (all broadcastable,
    ``(..., 2)`` metres; ``r`` ``(...)``). Returns ``(q, cost_m)``.

    ``q_init`` (optional) warm-starts the Newton iteration on the circle.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    c = np.asarray(c, dtype=float)
    r = np.asarray(r, dtype=float)
    a, b, c = np.broadcast_arrays(a, b, c)
    r = np.broadcast_to(r, a.shape[:-1])
    ab = b - a
    ab2 = ab[..., 0] ** 2 + ab[..., 1] ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        u = np.where(ab2 > 0, ((c - a) * ab).sum(-1) / np.where(ab2 > 0, ab2, 1.0), 0.0)
    u = np.clip(u, 0.0, 1.0)
    foot = a + u[..., None] * ab
    inside = _norm(foot - c) <= r
    q = foot.copy()
    out = ~inside
    if np.any(out):
        q[out] = _circle_point(a[out], b[out], c[out], r[out],
                               None if q_init is None else np.broadcast_to(q_init, a.shape)[out],
                               newton_steps)
    cost = _norm(q - a) + _norm(b - q)
    return q, cost


def _circle_point(a, b, c, r, q_init, steps: int):
    """Reflection point on the circle (c, r) for a, b outside the disk whose segment misses it."""
    ua, ub = a - c, b - c
    th_a = np.arctan2(ua[:, 1], ua[:, 0])
    th_b = np.arctan2(ub[:, 1], ub[:, 0])
    d = np.mod(th_b - th_a + np.pi, _TWO_PI) - np.pi  # signed short arc a -> b
    lo = np.zeros_like(d)
    hi = np.ones_like(d)
    if q_init is not None:
        v = q_init - c
        th = np.arctan2(v[:, 1], v[:, 0])
        s = np.mod(th - th_a + np.pi, _TWO_PI) - np.pi
        with np.errstate(invalid="ignore", divide="ignore"):
            s = np.where(d != 0, s / d, 0.5)
        s = np.where((s > 0) & (s < 1), s, 0.5)
    else:
        # Initial guess: weight each end by the inverse of its distance (exact when symmetric).
        na, nb = _norm(ua), _norm(ub)
        s = na / (na + nb)
    best_s = s
    best_f = np.full_like(s, np.inf)
    for _ in range(steps):
        th = th_a + s * d
        e = np.stack([np.cos(th), np.sin(th)], axis=-1)
        t = np.stack([-e[:, 1], e[:, 0]], axis=-1)
        q = c + r[:, None] * e
        g = np.zeros_like(s)
        h = np.zeros_like(s)
        f = np.zeros_like(s)
        for p in (a, b):
            w = q - p
            n = np.maximum(_norm(w), 1e-12)
            f += n
            w = w / n[:, None]
            tw = (t * w).sum(-1)
            g += r * tw
            h += -r * (e * w).sum(-1) + r * r * (1.0 - tw * tw) / n
        better = f < best_f
        best_f = np.where(better, f, best_f)
        best_s = np.where(better, s, best_s)
        g *= d
        h *= d * d
        neg = g < 0
        lo = np.where(neg, s, lo)
        hi = np.where(neg, hi, s)
        with np.errstate(invalid="ignore", divide="ignore"):
            s_new = s - g / h
        bad = ~((h > 0) & (s_new > lo) & (s_new < hi))
        s_next = np.where(bad, 0.5 * (lo + hi), s_new)
        done = np.max(np.abs(s_next - s)) < 1e-9
        s = s_next
        if done:
            break
    # The last step is not evaluated; compare it with the best evaluated iterate.
    th = th_a + s * d
    q = c + r[:, None] * np.stack([np.cos(th), np.sin(th)], axis=-1)
    f = _norm(q - a) + _norm(q - b)
    s = np.where(f < best_f, s, best_s)
    th = th_a + s * d
    return c + r[:, None] * np.stack([np.cos(th), np.sin(th)], axis=-1)


def single_visit_length_m(problem: RoutingProblem) -> np.ndarray:
    """(n, m): shortest start -> disk -> home length [m] for each target and vehicle alone.

    Moving targets: the disk is taken at the arrival time, found by a few fixed-point steps.
    """
    c0 = problem.centres_xy_m[:, None, :]
    vel = problem.velocities_m_s[:, None, :]
    r = problem.radii_m[:, None]
    s = problem.starts_xy_m[None, :, :]
    h = problem.homes_xy_m[None, :, :]
    c = np.broadcast_to(c0, (c0.shape[0], s.shape[1], 2))
    moving = np.any(vel != 0)
    for _ in range(8 if moving else 1):
        q, cost = best_point_between(s, h, c, r)
        if not moving:
            break
        t = _norm(q - s) / problem.speed_m_s
        c = c0 + vel * t[..., None]
    return cost
