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


def best_point_between(a, b, c, r, q_init=None, newton_steps: int = 30, eps_m: float = 0.0):
    """Point ``q`` with ``|q - c| <= r`` minimizing ``|a - q| + |q - b|`` (all broadcastable,
    ``(..., 2)`` metres; ``r`` ``(...)``). Returns ``(q, cost_m)`` (cost unsmoothed).

    ``q_init`` (optional) warm-starts the Newton iteration on the circle. ``eps_m`` > 0 minimizes
    the smoothed ``sqrt(|a-q|^2+eps^2) + sqrt(|q-b|^2+eps^2)`` instead, whose unconstrained
    minimizer is the midpoint of ``ab`` (used by the final refinement, see ``fitness.refine``).
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
    if eps_m > 0:
        mid = 0.5 * (a + b)
        mid_in = _norm(mid - c) <= r
        # With smoothing the interior optimum is the midpoint; otherwise it is on the circle.
        foot = np.where(mid_in[..., None], mid, foot)
        inside = mid_in
    if eps_m <= 0:
        # A tolerance, so that a neighbour lying on this circle (overlapping disks) counts as
        # inside: the circle search would converge only linearly to that kink.
        dist = _norm(foot - c)
        inside = dist <= r * (1 + 1e-9) + 1e-9
        with np.errstate(invalid="ignore", divide="ignore"):
            shrink = np.where(dist > r, r / np.where(dist > 0, dist, 1.0), 1.0)
        foot = c + (foot - c) * shrink[..., None]
    q = foot.copy()
    out = ~inside
    if np.any(out):
        q[out] = _circle_point(a[out], b[out], c[out], r[out],
                               None if q_init is None else np.broadcast_to(q_init, a.shape)[out],
                               newton_steps, eps_m)
    cost = _norm(q - a) + _norm(b - q)
    return q, cost


def _circle_point(a, b, c, r, q_init, steps: int, eps_m: float = 0.0):
    """Reflection point on the circle (c, r) for a, b outside the disk whose segment misses it.

    Safeguarded Newton on the arc parameter ``s`` in [0, 1] (angle ``th_a + s d``); the derivative
    is negative at ``s = 0`` and positive at ``s = 1``, and the bracket shrinks every step.
    Complex numbers stand for points to keep the number of numpy operations small.
    """
    az = a[:, 0] + 1j * a[:, 1]
    bz = b[:, 0] + 1j * b[:, 1]
    cz = c[:, 0] + 1j * c[:, 1]
    ua, ub = az - cz, bz - cz
    # A neighbour exactly at the centre (possible in the smoothed passes) has no direction: the
    # answer then only depends on the other neighbour, so borrow its direction.
    za, zb = ua == 0, ub == 0
    ua = np.where(za, np.where(zb, 1.0 + 0j, ub), ua)
    ub = np.where(zb, ua, ub)
    ea = ua / np.abs(ua)
    d = np.angle(ub * np.conj(ua))  # signed short arc a -> b
    lo = np.zeros_like(d)
    hi = np.ones_like(d)
    if q_init is not None:
        v = (q_init[:, 0] + 1j * q_init[:, 1]) - cz
        with np.errstate(invalid="ignore", divide="ignore"):
            s = np.where(d != 0, np.angle(v * np.conj(ua)) / d, 0.5)
        s = np.where((s > 0) & (s < 1), s, 0.5)
    else:
        na, nb = np.abs(ua), np.abs(ub)
        s = na / (na + nb)
    best_s = s
    best_f = np.full_like(s, np.inf)
    eps2 = eps_m * eps_m
    for _ in range(steps):
        e = ea * np.exp(1j * (s * d))
        q = cz + r * e
        ec = np.conj(e)
        za = (q - az) * ec  # real part: w.e, imaginary part: w.t (t = i e)
        zb = (q - bz) * ec
        na = np.sqrt(za.real**2 + za.imag**2 + eps2)
        nb = np.sqrt(zb.real**2 + zb.imag**2 + eps2)
        np.maximum(na, 1e-12, out=na)
        np.maximum(nb, 1e-12, out=nb)
        f = na + nb
        ga, gb = r * za.imag, r * zb.imag
        g = (ga / na + gb / nb) * d
        h = ((r * r - r * za.real) / na - ga * ga / na**3
             + (r * r - r * zb.real) / nb - gb * gb / nb**3) * (d * d)
        better = f < best_f
        best_f = np.where(better, f, best_f)
        best_s = np.where(better, s, best_s)
        neg = g < 0
        lo = np.where(neg, s, lo)
        hi = np.where(neg, hi, s)
        with np.errstate(invalid="ignore", divide="ignore"):
            s_new = s - g / h
        bad = ~((h > 0) & (s_new >= lo) & (s_new <= hi))
        s_next = np.where(bad, 0.5 * (lo + hi), s_new)
        done = np.max(np.abs(s_next - s)) < 1e-9
        s = s_next
        if done:
            break
    # The last step is not evaluated yet; compare it with the best evaluated iterate.
    q = cz + r * ea * np.exp(1j * (s * d))
    f = np.sqrt(np.abs(q - az) ** 2 + eps2) + np.sqrt(np.abs(q - bz) ** 2 + eps2)
    s = np.where(f < best_f, s, best_s)
    q = cz + r * ea * np.exp(1j * (s * d))
    return np.stack([q.real, q.imag], axis=-1)


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


def best_point_in_intersection(a, b, centres, radii) -> tuple[np.ndarray, float] | None:
    """Point in the intersection of disks (``centres`` (k, 2), ``radii`` (k,)) minimizing
    ``|a - q| + |q - b|``; None if the disks do not intersect.

    Used to move a run of consecutive access points that coincide as one point: coordinate
    descent cannot split such a run (the sum of norms is not differentiable there), but the joint
    minimizer is one of: a point of segment ``ab`` inside all disks, the best point of one circle
    if it lies in all other disks, or a crossing point of two circles inside all disks.
    """
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    C = np.asarray(centres, float)
    R = np.asarray(radii, float)
    tol = 1e-9
    # Segment case: intersect the parameter intervals of segment ∩ disk.
    ab = b - a
    L2 = float(ab @ ab)
    if L2 > 0:
        lo, hi = 0.0, 1.0
        for c, r in zip(C, R):
            # |a + u ab - c|^2 <= r^2  ->  L2 u^2 + 2 u ab.(a-c) + |a-c|^2 - r^2 <= 0
            bq = 2 * float(ab @ (a - c))
            cq = float((a - c) @ (a - c)) - r * r
            disc = bq * bq - 4 * L2 * cq
            if disc < 0:
                lo, hi = 1.0, 0.0
                break
            sq = np.sqrt(disc)
            lo = max(lo, (-bq - sq) / (2 * L2))
            hi = min(hi, (-bq + sq) / (2 * L2))
        if lo <= hi:
            q = a + 0.5 * (lo + hi) * ab
            return q, float(np.sqrt(L2))
    cands = []
    qs, _ = best_point_between(a[None], b[None], C, R)
    cands.extend(qs)
    k = len(C)
    for i in range(k):
        for j in range(i + 1, k):
            d = float(np.linalg.norm(C[j] - C[i]))
            if d == 0 or d > R[i] + R[j] or d < abs(R[i] - R[j]):
                continue
            x = (d * d + R[i] ** 2 - R[j] ** 2) / (2 * d)
            y = np.sqrt(max(R[i] ** 2 - x * x, 0.0))
            e = (C[j] - C[i]) / d
            nrm = np.array([-e[1], e[0]])
            cands.append(C[i] + x * e + y * nrm)
            cands.append(C[i] + x * e - y * nrm)
    best = None
    for q in cands:
        if np.all(np.linalg.norm(C - q, axis=1) <= R + tol):
            cost = float(np.linalg.norm(q - a) + np.linalg.norm(b - q))
            if best is None or cost < best[1]:
                best = (q, cost)
    return best
