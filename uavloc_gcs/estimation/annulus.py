"""The paper's error bound: the farthest point of the intersection of the per-slot annuli.

Each slot says the 3-D distance lies in ``exp(y + beta +- z s / sqrt(n))``; with the vehicle height
that is a ring on the ground around the vehicle's ground point, widened by ``v_max |t_i - t_ref|``
because the person may have walked since. The bound is the largest distance from the estimate to
a point inside every ring. ``z`` is Bonferroni-corrected over the N slots so that, under the
model (i.i.d. shadowing, |v| <= v_max), all N rings hold the truth together with probability
>= 95 %: the intersection is then a genuine 95 % confidence set, and the bound a conservative
radius. With uncorrected per-slot 95 % rings a 1,000-slot intersection is almost always empty.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import ndtri

N_RAYS = 90
MAX_RINGS = 120  # the tightest rings only: fewer constraints can only enlarge the set (stays valid)
REACH_RINGS = 64


def annulus_bound_m(
    estimate_xy_m: np.ndarray,
    t_ref_s: float,
    t_s: np.ndarray,
    a_xy_m: np.ndarray,
    h_m: np.ndarray,
    log_range: np.ndarray,
    n_samples: np.ndarray,
    log_range_sigma: float,
    max_speed_m_s: float,
    *,
    confidence: float = 0.95,
) -> float:
    """Farthest distance [m] from the estimate to the intersection of all rings; NaN if it is empty.

    ``log_range`` are the observed ln ranges already corrected for the phone's transmit offset.
    """
    n = len(t_s)
    if n == 0:
        return math.inf
    z = float(ndtri(1.0 - (1.0 - confidence) / (2.0 * n)))
    half = z * log_range_sigma / np.sqrt(n_samples)
    d_lo, d_hi = np.exp(log_range - half), np.exp(log_range + half)
    walk = max_speed_m_s * np.abs(t_s - t_ref_s)
    inner = np.sqrt(np.maximum(d_lo**2 - h_m**2, 0.0)) - walk
    outer = np.sqrt(np.maximum(d_hi**2 - h_m**2, 0.0)) + walk
    if n > MAX_RINGS:
        keep = np.union1d(np.argsort(outer)[: MAX_RINGS // 2], np.argsort(-inner)[: MAX_RINGS // 2])
        a_xy_m, inner, outer = a_xy_m[keep], inner[keep], outer[keep]
    return _farthest_on_rays(np.asarray(estimate_xy_m, float), a_xy_m, inner, outer)


def reach_bound_m(
    estimate_xy_m: np.ndarray,
    t_ref_s: float,
    t_s: np.ndarray,
    a_xy_m: np.ndarray,
    h_m: np.ndarray,
    comm_range_m: float,
    max_speed_m_s: float,
) -> float:
    """Farthest distance [m] from the estimate to a point within the communication range of every
    slot (ground radius sqrt(D^2 - h^2) + v_max |t_i - t_ref|): a sure bound, whatever the noise.
    inf if the range is unknown; NaN if the discs do not intersect (inconsistent data)."""
    if not math.isfinite(comm_range_m) or len(t_s) == 0:
        return math.inf
    outer = np.sqrt(np.maximum(comm_range_m**2 - h_m**2, 0.0)) + max_speed_m_s * np.abs(t_s - t_ref_s)
    if len(t_s) > REACH_RINGS:  # equal-sized discs: spread-out ones constrain most
        keep = np.unique(np.linspace(0, len(t_s) - 1, REACH_RINGS).astype(int))
        a_xy_m, outer = a_xy_m[keep], outer[keep]
    return _farthest_on_rays(np.asarray(estimate_xy_m, float), a_xy_m, np.zeros_like(outer), outer)


def _farthest_on_rays(e: np.ndarray, c: np.ndarray, inner: np.ndarray, outer: np.ndarray) -> float:
    """Largest feasible distance along N_RAYS rays from e, refined around the best coarse rays
    (a thin sliver of the set, e.g. the lens of one pass, falls between coarse rays)."""
    step = 2.0 * np.pi / N_RAYS
    phi = np.arange(N_RAYS) * step
    rho = _ray_extent(e, c, inner, outer, phi)
    top = phi[np.argsort(np.nan_to_num(rho, nan=-1.0))[-3:]]
    fine = (top[:, None] + np.linspace(-step, step, 25)[None, :]).ravel()
    rho = np.concatenate([rho, _ray_extent(e, c, inner, outer, fine)])
    return math.nan if np.all(np.isnan(rho)) else float(np.nanmax(rho))


def _ray_extent(e, c, inner, outer, phi) -> np.ndarray:
    """Per ray: the farthest distance inside every ring (NaN where the ray misses the set)."""
    u = np.column_stack([np.cos(phi), np.sin(phi)])  # (K, 2)
    ec = e - c  # (N, 2)
    b = u @ ec.T  # (K, N): u . (e - c)
    q = np.einsum("ij,ij->i", ec, ec)  # (N,)
    # inside the outer circle: rho^2 + 2 b rho + q - O^2 <= 0
    disc = b * b - q + outer**2
    sq = np.sqrt(np.maximum(disc, 0.0))
    lo = np.where(disc >= 0, -b - sq, np.inf).max(axis=1)
    hi = np.where(disc >= 0, -b + sq, -np.inf).min(axis=1)
    lo = np.maximum(lo, 0.0)
    # outside the inner circle: excluded open interval (e1, e2) where rho^2 + 2 b rho + q - I^2 < 0
    di = b * b - q + np.where(inner > 0, inner, 0.0) ** 2
    has = (di > 0) & (inner > 0)
    si = np.sqrt(np.maximum(di, 0.0))
    e1 = np.where(has, -b - si, np.inf)
    e2 = np.where(has, -b + si, -np.inf)
    rho = hi.copy()
    for _ in range(8):  # walk inwards past excluded intervals that contain rho
        inside = (e1 < rho[:, None] - 1e-9) & (rho[:, None] < e2 + 1e-9)
        if not inside.any():
            break
        rho = np.where(inside.any(axis=1), np.where(inside, e1, np.inf).min(axis=1), rho)
    ok = (rho >= lo - 1e-9) & (hi >= lo)
    return np.where(ok, rho, np.nan)
