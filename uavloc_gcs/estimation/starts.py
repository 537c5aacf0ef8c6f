"""Where a fit starts, and how much a misfit deflates what it says (for :mod:`.estimate`).

The slots' principal line and the straight legs that heard them (:func:`principal_line`,
:func:`leg_lines`), a point's mirror image across such a line (:func:`mirror_point`), the start
grid and the mirror starts of a problem (:func:`start_points`), and the information deflation its
residuals call for when they show correlated shadowing or a misfit (:func:`inflation_factor`).
"""

from __future__ import annotations

import math

import numpy as np

from .fit import Problem
from .prepared import Prepared

GRID_SLOTS = 80
GRID_SIDE = 17
START_SEPARATION_M = 10.0


def principal_line(data: Prepared) -> tuple[np.ndarray, np.ndarray, float]:
    """Weighted centre, unit direction and straightness (minor/major spread ratio) of the slots."""
    dev = data.a_xy - data.center
    cov = (dev * data.w[:, None]).T @ dev / np.sum(data.w)
    ev, vec = np.linalg.eigh(cov)
    ratio = math.sqrt(max(ev[0], 0.0) / ev[1]) if ev[1] > 0 else 1.0
    return data.center, vec[:, 1], ratio


def mirror_point(p: np.ndarray, center: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Reflection of p across the line through center along direction."""
    normal = np.array([-direction[1], direction[0]])
    return p - 2.0 * np.dot(p - center, normal) * normal


def leg_lines(data: Prepared, *, min_slots: int = 20, max_legs: int = 3) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """Straight legs in the slots: (centre, unit direction, mean time) of up to ``max_legs`` of the
    longest runs of one vehicle without a gap (> 1 s) or a heading change beyond 30 degrees."""
    order = np.lexsort((data.t_s, data.vehicle))
    a, t, veh = data.a_xy[order], data.t_s[order], data.vehicle[order]
    if len(t) < 2:
        return []
    step = np.diff(a, axis=0)
    heading = np.unwrap(np.arctan2(step[:, 1], step[:, 0]))
    brk = (np.diff(t) > 1.0) | (veh[1:] != veh[:-1]) | (np.hypot(step[:, 0], step[:, 1]) < 1e-9)
    seg = np.concatenate([[0], np.cumsum(brk)])
    # within a segment, a new leg whenever the heading leaves its 30-degree bin
    # centred on the first heading: float noise around a straight leg must not flip between bins
    bins = np.floor((heading - heading[0]) / np.radians(30.0) + 0.5)
    leg = seg * 1000 + np.concatenate([[bins[0]], bins]).astype(int)
    change = np.concatenate([[True], leg[1:] != leg[:-1]])
    ids = np.cumsum(change)
    counts = np.bincount(ids)
    out = []
    for k in np.argsort(-counts)[:max_legs]:
        if counts[k] < min_slots:
            break
        m = ids == k
        pts = a[m]
        d = pts[-1] - pts[0]
        norm = float(np.hypot(*d))
        if norm < 1.0:
            continue
        out.append((pts.mean(axis=0), d / norm, float(t[m].mean())))
    return out


def start_points(problem: Problem) -> list[np.ndarray]:
    """Static grid search on a subsample, then: the best cell, its mirror across the slots'
    principal line, and the best cell on the other side of that line."""
    d = problem.data
    sub = np.linspace(0, len(d.t_s) - 1, min(GRID_SLOTS, len(d.t_s))).astype(int)
    rng_h = np.sqrt(np.maximum(np.exp(2.0 * d.y[sub]) - d.h_m[sub] ** 2, 0.0))
    reach = float(np.clip(np.percentile(rng_h, 75), 10.0, 2000.0))
    lo = d.a_xy[sub].min(axis=0) - reach
    hi = d.a_xy[sub].max(axis=0) + reach
    gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], GRID_SIDE), np.linspace(lo[1], hi[1], GRID_SIDE))
    cells = np.column_stack([gx.ravel(), gy.ravel()])
    diff = cells[:, None, :] - d.a_xy[sub][None]
    lnd = 0.5 * np.log(np.einsum("ijk,ijk->ij", diff, diff) + d.h_m[sub] ** 2)
    res = d.y[sub] - lnd
    w = d.w[sub]
    if problem.tx:
        res = res - (res @ w / w.sum())[:, None]
    cost = (res * res) @ w
    center, direction, _ = principal_line(d)
    normal = np.array([-direction[1], direction[0]])
    side = (cells - center) @ normal
    best = cells[int(np.argmin(cost))]
    starts = [best, mirror_point(best, center, direction)]
    other = side * np.sign(np.dot(best - center, normal) or 1.0) < 0
    if other.any():
        starts.append(cells[other][int(np.argmin(cost[other]))])
    out = []
    for p in starts:
        theta = np.zeros(problem.size)
        theta[:2] = p
        if problem.tx:
            lnd_p = 0.5 * np.log(np.sum((p - d.a_xy) ** 2, axis=1) + d.h_m**2)
            theta[problem.beta_index] = float(np.average(lnd_p - d.y, weights=d.w))
        if not any(np.linalg.norm(theta[:2] - q[:2]) < START_SEPARATION_M for q in out):
            out.append(theta)
    return out


def inflation_factor(problem: Problem, theta: np.ndarray) -> float:
    """How much less information the data hold than the i.i.d. model says (>= 1).

    (1 + rho) / (1 - rho) for the lag-1 autocorrelation rho of the residuals of consecutive slots
    of one vehicle (spatially correlated shadowing, or a person who turned), times the residual
    variance ratio when it is clearly above 1. Both are applied only when significant, so the
    i.i.d. case keeps its full information.
    """
    d = problem.data
    r = problem.standardized_residuals(theta)
    n = len(r)
    factor = 1.0
    dof = n - problem.size
    if dof >= 5:
        ratio = float(r @ r) / dof
        if ratio > 1.0 + 3.0 * math.sqrt(2.0 / dof):
            factor *= ratio
    if n >= 8:
        dt = np.diff(d.t_s)
        positive = dt[dt > 0]
        step = float(np.median(positive)) if positive.size else 0.0
        pair = (d.vehicle[1:] == d.vehicle[:-1]) & (dt <= 3.0 * step) & (dt > 0)
        # several vehicles interleave in time: pair each slot with the next one of its own vehicle
        if pair.sum() < n // 2:
            order = np.lexsort((d.t_s, d.vehicle))
            rv, tv, vv = r[order], d.t_s[order], d.vehicle[order]
            dtv = np.diff(tv)
            pair = (vv[1:] == vv[:-1]) & (dtv > 0) & (dtv <= 3.0 * max(step, 1e-9))
            r = rv
        m = int(pair.sum())
        if m >= 8:
            a, b = r[:-1][pair], r[1:][pair]
            rho = float(np.dot(a, b) / math.sqrt(np.dot(a, a) * np.dot(b, b) + 1e-300))
            if rho > 2.0 / math.sqrt(m):
                rho = min(rho, 0.995)
                factor *= (1.0 + rho) / (1.0 - rho)
    return factor
