"""The ranging model in log-range form, its Jacobian and Fisher information, and 95 % radii.

A slot of n samples with mean RSSI ``rssi`` [dBm] becomes one log-range observation
``y = ln d0 + (P0 - rssi) ln10 / (10 eta)`` [nepers] with ``y = ln d - beta + e``,
``e ~ N(0, s^2 / n)``, ``s = sigma ln10 / (10 eta)``, d the 3-D distance and
``beta = tx_offset_db ln10 / (10 eta)`` the phone's unknown transmit offset (0 unless estimated).

The state is ``theta = (x, y, vx, vy[, beta])`` at a reference time t_c (metres, m/s) for the
moving model, ``(x, y[, beta])`` for the static one. The person is at ``p + v (t - t_c)``, z = 0:
the slots' z is the vehicle's height above the person (over terrain, see :mod:`.terrain_fit`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ChannelModel:
    """Calibrated log-distance channel: P = P0 - 10 eta log10(d/d0) + N(0, sigma^2) [dBm]."""

    reference_power_dbm: float = -40.0
    path_loss_exponent: float = 2.0
    shadowing_sigma_db: float = 4.0
    reference_distance_m: float = 1.0
    comm_range_m: float = math.inf  # 3-D range within which a phone is heard at all (a sure bound)
    # The receiver hears a frame only when its RSSI exceeds this [dBm] (the field world, SPEC 1.1):
    # the heard frames' likelihood is truncated there and the exact range gate is off (``gate_m``).
    # None: the paper's world, heard exactly within comm_range_m.
    sensitivity_dbm: float | None = None

    @staticmethod
    def from_scenario(sc) -> "ChannelModel":
        ch = sc.channel
        return ChannelModel(ch.reference_power_dbm, ch.path_loss_exponent, ch.shadowing_sigma_db,
                            ch.reference_distance_m, sc.fleet.comm_range_m,
                            getattr(ch, "receiver_sensitivity_dbm", None))

    @property
    def gate_m(self) -> float:
        """The sure 3-D hearing range: ``comm_range_m`` in the paper's world, none (inf) under a
        sensitivity threshold, where shadowing can lift a frame above it at any distance."""
        return self.comm_range_m if self.sensitivity_dbm is None else math.inf

    @property
    def threshold_log_range(self) -> float | None:
        """The sensitivity in log-range form [ln m]: a frame is heard when its observed ln range is
        below it (None without a threshold)."""
        if self.sensitivity_dbm is None:
            return None
        return float(self.log_range(self.sensitivity_dbm))

    @property
    def nepers_per_db(self) -> float:
        """d(ln range)/d(RSSI dB) = ln10 / (10 eta)."""
        return math.log(10.0) / (10.0 * self.path_loss_exponent)

    @property
    def log_range_sigma(self) -> float:
        """Std of ln(range) per sample, s = sigma ln10 / (10 eta) (0.4605 for the paper)."""
        return self.shadowing_sigma_db * self.nepers_per_db

    def log_range(self, rssi_dbm) -> np.ndarray:
        """Observed ln(range) [ln m] from RSSI [dBm] (the phone at its nominal power)."""
        return math.log(self.reference_distance_m) + (self.reference_power_dbm - np.asarray(rssi_dbm)) \
            * self.nepers_per_db

    def rssi_dbm(self, d_m) -> np.ndarray:
        """Median RSSI [dBm] at 3-D distance d_m."""
        return self.reference_power_dbm - 10.0 * self.path_loss_exponent * np.log10(
            np.asarray(d_m) / self.reference_distance_m)


# Slots heard below the airborne floor (uavloc_gcs/heights.py: half the lowest height the search
# flies on purpose, the survey's or its looks' [search] look_height_m; 50 m at the default 100 m)
# are a vehicle taking off, landing or standing at home, and are not estimated from: the newest
# data of a vehicle back home would be rings of range about one point, and the estimate anchored
# there spans the whole ring. Measured on the fake fleet
# (tests/test_e2e_vehicle_faults.py, a person 135 m from home at 60 m altitude, heard on the
# ground): radii of 30-290 m after each look, 30 looks flown, never located. Until issue 41 the
# floor was half the survey altitude whatever the looks flew, which would have thrown away every
# slot of a look at 30 m.


def airborne_slots(slots, floor_m: float, dem=None):
    """The slots heard at or above ``floor_m`` [m] over the ground under the vehicle (their z is
    above the launch point; over a DEM, a uavloc_gcs.terrain.Terrain, the ground's rise from the
    launch point is taken off): each slot judged by its own height (heights.airborne)."""
    from ..heights import airborne

    if len(slots) == 0:
        return slots
    keep = airborne(slots.xyz_m, floor_m, dem)
    return slots if bool(np.all(keep)) else slots.take(keep)


def geometry(theta: np.ndarray, tau_s: np.ndarray, a_xy: np.ndarray, h_m: np.ndarray, moving: bool):
    """Horizontal offsets g (N, 2) person - vehicle and squared 3-D distances (N,)."""
    p = theta[:2]
    if moving:
        pos = p + np.outer(tau_s, theta[2:4])
    else:
        pos = np.broadcast_to(p, a_xy.shape)
    g = pos - a_xy
    d2 = np.einsum("ij,ij->i", g, g) + h_m * h_m
    return g, d2


def log_range_jacobian(g: np.ndarray, d2: np.ndarray, tau_s: np.ndarray, moving: bool, tx: bool) -> np.ndarray:
    """d(ln d - beta)/d theta, (N, P)."""
    gx, gy = g[:, 0] / d2, g[:, 1] / d2
    cols = [gx, gy]
    if moving:
        cols += [tau_s * gx, tau_s * gy]
    if tx:
        cols.append(-np.ones_like(gx))
    return np.column_stack(cols)


def fisher_information(theta, tau_s, a_xy, h_m, weight, moving: bool, tx: bool) -> np.ndarray:
    """Data Fisher information sum_i w_i grad grad^T (P, P) for log-range observations with
    precision w_i = n_i / s^2."""
    g, d2 = geometry(np.asarray(theta, float), tau_s, a_xy, h_m, moving)
    jac = log_range_jacobian(g, d2, tau_s, moving, tx)
    return (jac * weight[:, None]).T @ jac


_GL_X, _GL_W = np.polynomial.legendre.leggauss(48)
_THETA, _THETA_W = 0.5 * np.pi * _GL_X, 0.5 * np.pi * _GL_W


def circle_probability(cov2: np.ndarray, r_m) -> np.ndarray:
    """P(|X| <= r) for X ~ N(0, cov2) in 2-D, for an array of radii r_m [m].

    With eigenvalues l1 >= l2 and z2 the minor-axis coordinate in sigmas,
    P = int phi(z2) erf( sqrt((r^2 - l2 z2^2)+ / (2 l1)) ) dz2 over |z2| <= zk = min(r / sqrt(l2), 8);
    the substitution z2 = zk sin(theta) removes the square-root end point, so 48 Gauss-Legendre
    nodes give ~1e-10.
    """
    from scipy.special import erf

    ev = np.linalg.eigvalsh(0.5 * (cov2 + cov2.T))
    l2, l1 = max(ev[0], 0.0), ev[1]
    r = np.asarray(r_m, float)[..., None]
    zk = np.minimum(r / math.sqrt(l2), 8.0) if l2 > 0 else np.full_like(r, 8.0)
    z = zk * np.sin(_THETA)
    rest = np.maximum(r * r - l2 * z * z, 0.0)
    f = np.exp(-0.5 * z * z) / math.sqrt(2.0 * math.pi) * erf(np.sqrt(rest / (2.0 * l1))) * zk * np.cos(_THETA)
    return f @ _THETA_W


def radius_of_probability(cov2: np.ndarray, prob: float = 0.95) -> float:
    """Radius [m] of the centred circle holding ``prob`` of a 2-D Gaussian with covariance cov2."""
    cov2 = 0.5 * (np.asarray(cov2, float) + np.asarray(cov2, float).T)
    ev = np.linalg.eigvalsh(cov2)
    if not np.all(np.isfinite(ev)):
        return math.inf
    if ev[-1] <= 0:
        return 0.0
    from scipy.special import ndtri

    lo = float(ndtri(0.5 + prob / 2.0) * math.sqrt(ev[-1]))  # the 1-D (degenerate) answer
    hi = float(math.sqrt(-2.0 * math.log(1.0 - prob) * ev[-1]))  # the isotropic answer
    if hi - lo < 1e-9 * hi:
        return hi
    grid = np.linspace(lo, hi, 9)
    p = circle_probability(cov2, grid)
    if p[-1] <= prob:  # isotropic (up to rounding)
        return hi
    k = int(np.clip(np.searchsorted(p, prob), 1, len(grid) - 1))
    a, b, pa, pb = grid[k - 1], grid[k], p[k - 1], p[k]
    for _ in range(2):  # regula falsi on the bracket; P(r) is smooth and monotone
        r = a + (prob - pa) * (b - a) / max(pb - pa, 1e-300)
        pr = float(circle_probability(cov2, r))
        if pr < prob:
            a, pa = r, pr
        else:
            b, pb = r, pr
    return float(a + (prob - pa) * (b - a) / max(pb - pa, 1e-300))


def _unit_polar_grid(radial: int = 128, angular: int = 32) -> np.ndarray:
    """Points standing for a standard 2-D normal, each of equal weight: every radial quantile
    (k + 1/2) / radial of the Rayleigh law at every one of ``angular`` evenly spread angles.
    Deterministic, so that a radius computed from them is a function of its inputs."""
    u = (np.arange(radial) + 0.5) / radial
    rho = np.sqrt(-2.0 * np.log1p(-u))
    phi = 2.0 * math.pi * (np.arange(angular) + 0.5) / angular
    return np.column_stack([np.outer(rho, np.cos(phi)).ravel(), np.outer(rho, np.sin(phi)).ravel()])


_UNIT_GRID = _unit_polar_grid()


def mixture_radius(center, parts, prob: float = 0.95) -> float:
    """Radius [m] of the circle about ``center`` holding ``prob`` of a mixture of 2-D Gaussians.

    ``parts``: (weight, mean (2,), covariance 2x2) per component; the weights are normalised. The
    probability of a circle off a component's centre has no closed form; each component is
    represented by the fixed grid of :func:`_unit_polar_grid` (4,096 points), accurate to about
    1 % of the radius."""
    center = np.asarray(center, float)
    dist, weight = [], []
    for w, mean, cov2 in parts:
        if w <= 0:
            continue
        cov2 = 0.5 * (np.asarray(cov2, float) + np.asarray(cov2, float).T)
        if not np.all(np.isfinite(cov2)) or not np.all(np.isfinite(mean)):
            return math.inf
        ev, vec = np.linalg.eigh(cov2)
        root = vec * np.sqrt(np.clip(ev, 0.0, None))  # root @ root.T == cov2
        pts = np.asarray(mean, float) - center + _UNIT_GRID @ root.T
        dist.append(np.hypot(pts[:, 0], pts[:, 1]))
        weight.append(np.full(len(pts), float(w) / len(pts)))
    if not dist:
        return math.inf
    d, w = np.concatenate(dist), np.concatenate(weight)
    order = np.argsort(d)
    d, cdf = d[order], np.cumsum(w[order]) / np.sum(w)
    k = int(np.searchsorted(cdf, prob))
    if k >= len(d) - 1:
        return float(d[-1])
    if k == 0:
        return float(d[0])
    # linear between the neighbouring points of the empirical distribution
    f = (prob - cdf[k - 1]) / max(cdf[k] - cdf[k - 1], 1e-300)
    return float(d[k - 1] + f * (d[k] - d[k - 1]))


# ---------------------------------------------------------------------------------------------
# The receiver threshold (Tobit model). In log-range form a frame's observed ln range is
# y = m + e, e ~ N(0, s^2), m = ln d - beta, and it is heard when y < y_S (its RSSI above the
# sensitivity S). With z = (m - y_S) / s = (S - mu) / sigma, a frame is heard with probability
# Phi(-z) and missed with probability Phi(z).


def _log_phi(u: np.ndarray) -> np.ndarray:
    return -0.5 * u * u - 0.5 * math.log(2.0 * math.pi)


def mills_ratio(u) -> np.ndarray:
    """phi(u) / Phi(u), computed in logs (finite for every finite u)."""
    from scipy.special import log_ndtr

    u = np.asarray(u, float)
    return np.exp(_log_phi(u) - log_ndtr(u))


def log_probability_residual(u, count) -> tuple[np.ndarray, np.ndarray]:
    """The residual r = sqrt(-2 count ln Phi(u)) (so that r^2 is -2 ln Phi(u)^count) and dr/du.

    For a heard slot of n frames (the truncation) u = -z and count = n; for a silence in which the
    phone sent k frames (the censoring) u = z and count = k. dr/du = -count lambda(u) / r, with
    lambda the Mills ratio; where r underflows (u > ~37) both are 0."""
    from scipy.special import log_ndtr

    u = np.asarray(u, float)
    f = -2.0 * np.asarray(count, float) * log_ndtr(u)
    ok = f > 1e-300
    r = np.sqrt(np.where(ok, f, 0.0))
    dr = np.where(ok, -np.asarray(count, float) * mills_ratio(u) / np.where(ok, r, 1.0), 0.0)
    return r, dr


def truncated_information_factor(z) -> np.ndarray:
    """Fisher information about m of one heard frame under the threshold, in units of 1/s^2:
    the variance ratio of the normal truncated above at y_S, 1 - a lambda(a) - lambda(a)^2 with
    a = -z (1 far inside the range, towards 0 at the edge). The slot mean of n heard frames is
    sufficient for m (an exponential family), so a slot holds n times it."""
    a = -np.asarray(z, float)
    lam = mills_ratio(a)
    return np.clip(1.0 - a * lam - lam * lam, 0.0, 1.0)


def censored_curvature(z) -> np.ndarray:
    """d^2 (-ln Phi(z)) / dz^2 = lambda(z) (z + lambda(z)) (>= 0): the curvature, per frame, of a
    silence in units of 1/s^2 (what it adds to the Laplace precision, the Gauss-Newton way)."""
    z = np.asarray(z, float)
    lam = mills_ratio(z)
    return np.maximum(lam * (z + lam), 0.0)


def tobit_information_factor(z) -> np.ndarray:
    """Expected Fisher information about m of one frame the phone sent, heard or not, in units of
    1/s^2 (Amemiya's Tobit information): Phi(a) - a phi(a) + phi(a)^2 / Phi(-a), a = -z."""
    from scipy.special import ndtr

    a = -np.asarray(z, float)
    phi = np.exp(_log_phi(a))
    return np.maximum(ndtr(a) - a * phi + phi * mills_ratio(-a), 0.0)  # phi(a)^2 / Phi(-a) = phi lambda(-a)


def _heard_mean_gap(t: np.ndarray) -> np.ndarray:
    """E[(y - y_S) / s | heard] - t = -lambda(-t) at standardized mean t = (m - y_S) / s."""
    return -mills_ratio(-t)


def truncated_mle(b) -> np.ndarray:
    """Per slot, the standardized mean t* = (m - y_S) / s that maximises the likelihood of frames
    heard with standardized mean b = (y_bar - y_S) / s < 0: the root of t - lambda(-t) = b (the
    truncated normal is an exponential family in m, so the ML mean matches the heard mean). The
    left side rises from -inf to 0 with slope kappa > 0; t* lies in [b, 1 - 1/b] (Mills ratio
    bound lambda(-t) < t + 1/t for t > 0); bisection, vectorized."""
    b = np.minimum(np.asarray(b, float), -1e-2)
    lo, hi = b.copy(), 1.0 - 1.0 / b
    for _ in range(64):
        mid = 0.5 * (lo + hi)
        below = mid + _heard_mean_gap(mid) < b
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    return 0.5 * (lo + hi)


def truncated_slot_residual(t, b, t_star, n) -> tuple[np.ndarray, np.ndarray]:
    """The heard slots' data term under the threshold as a least-squares residual, and dr/dt.

    A slot of n frames heard with standardized mean b = (y_bar - y_S) / s has
    -2 ln L(t) = c(t) + const with c(t) = n [(b - t)^2 - 2 (-ln Phi(-t))], t = (m - y_S) / s: the
    Gaussian term plus 2 n ln(1 - Phi(z)) (z = t; per frame the density phi / (1 - Phi(z)), whose
    normaliser *lowers* the cost where hearing is unlikely). c is convex with its minimum at
    t* (:func:`truncated_mle`), so r = sign(t - t*) sqrt(c(t) - c(t*)) is a smooth residual with
    r^2 = c - c(t*) (a constant of the data dropped); dr/dt = c'(t) / (2 r),
    c'(t) = 2 n (t - b - lambda(-t)); next to t* the Taylor form r = (t - t*) sqrt(n kappa(t*))."""
    from scipy.special import log_ndtr

    t, b, t_star, n = (np.asarray(a, float) for a in (t, b, t_star, n))
    b = np.minimum(b, -1e-2)

    def cost(u):
        return n * ((b - u) ** 2 + 2.0 * log_ndtr(-u))

    delta = t - t_star
    near = np.abs(delta) < 1e-4 * np.maximum(1.0, np.abs(t_star))
    slope0 = np.sqrt(n * np.maximum(truncated_information_factor(t_star), 1e-12))
    excess = np.maximum(cost(t) - cost(t_star), 0.0)
    r = np.where(near, delta * slope0, np.sign(delta) * np.sqrt(excess))
    safe = np.where(near | (r == 0.0), 1.0, r)
    dr = np.where(near, slope0, n * (t - b - mills_ratio(-t)) / safe)
    return r, dr
