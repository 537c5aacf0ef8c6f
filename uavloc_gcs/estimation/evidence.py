"""The hearing itself as evidence: where a phone was heard, and where it was not.

A phone is heard only within the communication range D (3-D) of a vehicle, so every slot heard
puts the person within ground range sqrt(D^2 - h^2) of the vehicle then, and every slot a vehicle
listened without hearing the phone (*silence*) puts the person outside it. The RSSI fit does not
use this (the likelihood of the slots heard only), and its mirror images often contradict it: the
mirror of a person between two lanes across one lane lies beyond the other lane's reach, and the
mirror across a single lane may lie where another vehicle flew over and heard nothing.

:func:`build_bounds` turns both into soft one-sided constraints on the person's track (a hinge
residual, zero inside, growing linearly with the violation over a softness of
``TOLERANCE_FLOOR_M`` plus the maneuver deviation since the anchor for silences, or the velocity
mismatch within a pass for slots heard, whose pass offset carries the maneuver). The estimator
refits every candidate where they bind, so a mirror that needs the person out of reach of a slot
heard, or within reach of a silence, moves or loses its posterior mass; the binding rows also add
(deflated) information to the Laplace covariance (``modes.BOUNDS_IN_COVARIANCE``, measured there).

Opt-in (``estimate_emitter(..., silence=)``): the simulator's hearing is a hard range gate, which
this exploits fully; a real phone's detection edge is softer (the softness should then grow).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

TOLERANCE_FLOOR_M = 2.0  # a slot's flight (0.6 m) and the rounding of the range gate, generously
MAX_HEARD = 400  # heard slots checked (evenly spaced; the constraint varies slowly along a pass)
MAX_SILENT = 600


@dataclass(frozen=True)
class Silence:
    """Where vehicles listened without hearing this phone: times (M,) [s] and positions (M, 3)
    [m, local ENU, z = height above the people]."""

    t_s: np.ndarray
    xyz_m: np.ndarray

    @staticmethod
    def empty() -> "Silence":
        return Silence(np.zeros(0), np.zeros((0, 3)))

    def __len__(self) -> int:
        return len(self.t_s)


def silence_from_track(t_s, xyz_m, heard_t_s, *, slot_s: float, quiet_s: float | None = None) -> Silence:
    """The slots of a listening track (times (N,), positions (N, 3)) at which this phone was not
    heard: no heard slot within ``quiet_s`` [s] (default half a slot, i.e. not that slot)."""
    t = np.asarray(t_s, float).reshape(-1)
    xyz = np.asarray(xyz_m, float).reshape(-1, 3)
    heard = np.sort(np.asarray(heard_t_s, float).reshape(-1))
    if len(heard) == 0 or len(t) == 0:
        return Silence(t, xyz)
    k = np.clip(np.searchsorted(heard, t), 1, len(heard) - 1) if len(heard) > 1 else np.zeros(len(t), int)
    near = np.minimum(np.abs(heard[k] - t), np.abs(heard[np.maximum(k - 1, 0)] - t))
    quiet = near > (0.5 * slot_s if quiet_s is None else quiet_s)
    return Silence(t[quiet], xyz[quiet])


@dataclass(frozen=True)
class Bounds:
    """Range constraints on the person's CV track, in the fit's time frame: offsets tau_s (K,) from
    the fit's reference time, vehicle ground positions (K, 2), ground reach (K,), sign (K,) (+1: heard,
    the person within reach; -1: silent, outside it) and softness sigma_m (K,)."""

    tau_s: np.ndarray
    a_xy: np.ndarray
    reach_m: np.ndarray
    sign: np.ndarray
    sigma_m: np.ndarray
    pass_index: np.ndarray  # (K,) the maneuver pass of a heard row (its offset applies); -1: none
    # Over terrain (see .terrain_fit, prepared.Prepared.ground): the rows' heights above the person h_m
    # (K,) as taken, the range, the fit's reference time and ground(t_s, xy) -> (rise, gradient):
    # each row then bounds the slant range to the person on the ground wherever the fit moves them
    # (in slant metres: a ground reach sqrt(range^2 - h^2) changes without bound as h nears the
    # range, and its rows made a 3 m "95 %" circle in the mountains demo).
    h_m: np.ndarray | None = None
    range_m: float = math.inf
    t_c: float = 0.0
    ground: object = None

    def __len__(self) -> int:
        return len(self.tau_s)

    def _slant(self, g: np.ndarray, where: np.ndarray):
        """Over terrain: each row's slant distance to the person on the ground at ``where`` (K,)
        and its gradient by the person's position (K, 2)."""
        rise, grad = self.ground(self.tau_s + self.t_c, where)
        h = self.h_m - rise
        d = np.maximum(np.sqrt(g[:, 0] * g[:, 0] + g[:, 1] * g[:, 1] + h * h), 1e-9)
        return d, (g - h[:, None] * grad) / d[:, None]

    def residuals(self, p: np.ndarray, v: np.ndarray | None, shift: np.ndarray | None = None) -> np.ndarray:
        g, where = self._offsets(p, v, shift)
        if self.ground is not None:  # the range itself (its gradient stays bounded near the disc's edge)
            d, _ = self._slant(g, where)
            return np.maximum(self.sign * (d - self.range_m), 0.0) / self.sigma_m
        ground = np.hypot(g[:, 0], g[:, 1])
        return np.maximum(self.sign * (ground - self.reach_m), 0.0) / self.sigma_m

    def jacobian(self, p: np.ndarray, v: np.ndarray | None, shift: np.ndarray | None = None) -> np.ndarray:
        """(K, 4) d residual / d (x, y, vx, vy) (the velocity columns zero for the static model); the
        derivative by a row's pass offset equals its position columns."""
        g, where = self._offsets(p, v, shift)
        if self.ground is not None:
            d, u = self._slant(g, where)
            active = self.sign * (d - self.range_m) > 0
        else:
            ground = np.maximum(np.hypot(g[:, 0], g[:, 1]), 1e-9)
            active = self.sign * (ground - self.reach_m) > 0
            u = g / ground[:, None]
        u = u * (active * self.sign / self.sigma_m)[:, None]
        return np.column_stack([u, u * self.tau_s[:, None]]) if v is not None else np.column_stack([u, 0 * u])

    def _offsets(self, p, v, shift=None):
        """Person - vehicle ground offsets (K, 2) and the person's positions (K, 2)."""
        where = p + (np.outer(self.tau_s, v) if v is not None else np.zeros_like(self.a_xy))
        if shift is not None:  # (K, 2) the rows' pass offsets
            where = where + shift
        return where - self.a_xy, where


def build_bounds(t_c: float, t_anchor: float, heard_t_s, heard_xyz_m, heard_pass, heard_pass_t_s,
                 silence: Silence | None,
                 comm_range_m: float, q_m2_s3: float, near_xy_m: np.ndarray, max_speed_m_s: float,
                 moving: bool, ground=None) -> Bounds | None:
    """The constraints worth fitting: heard slots spread over the data (``MAX_HEARD``) and the
    silent slots that could bind near any of ``near_xy_m`` (candidate positions at t_c). Softness:
    ``TOLERANCE_FLOOR_M`` plus the maneuver deviation since the anchor (and for the static model
    the walk v_max |tau|). ``ground``: over terrain, ``prepared.Prepared.ground`` (each row then bounds
    the slant range to the person on the ground where the fit puts them)."""
    if not math.isfinite(comm_range_m):
        return None
    ht = np.asarray(heard_t_s, float)
    hx = np.asarray(heard_xyz_m, float)
    k = _spread(len(ht), MAX_HEARD)
    t, xyz, sign = [ht[k]], [hx[k]], [np.ones(len(k))]
    index = [np.asarray(heard_pass, int)[k]]
    # one offset per pass: within it the true velocity may differ from the fitted one by 2 v_max
    within = [2.0 * max_speed_m_s * np.abs(ht[k] - np.asarray(heard_pass_t_s, float)[k])]
    if silence is not None and len(silence):
        reach = np.sqrt(np.maximum(comm_range_m**2 - silence.xyz_m[:, 2] ** 2, 0.0))
        slack = max_speed_m_s * np.abs(silence.t_s - t_c) + 30.0
        d = np.min(np.linalg.norm(silence.xyz_m[None, :, :2] - np.asarray(near_xy_m)[:, None, :], axis=2), axis=0)
        m = np.flatnonzero(d < reach + slack)
        m = m[_spread(len(m), MAX_SILENT)]
        t.append(silence.t_s[m])
        xyz.append(silence.xyz_m[m])
        sign.append(-np.ones(len(m)))
        index.append(np.full(len(m), -1))
        within.append(np.zeros(len(m)))
    t, xyz, sign, index = np.concatenate(t), np.vstack(xyz), np.concatenate(sign), np.concatenate(index)
    if len(t) == 0:
        return None
    # a heard row's pass offset carries the maneuver; a silent row has none, so its softness does
    sigma = TOLERANCE_FLOOR_M + np.concatenate(within) + np.where(
        index >= 0, 0.0, np.sqrt(q_m2_s3 * np.abs(t - t_anchor) ** 3 / 3.0))
    if not moving:
        sigma = sigma + max_speed_m_s * np.abs(t - t_c)
    reach = np.sqrt(np.maximum(comm_range_m**2 - xyz[:, 2] ** 2, 0.0))
    if ground is not None:
        return Bounds(t - t_c, xyz[:, :2].copy(), reach, sign, sigma, index, xyz[:, 2].copy(), float(comm_range_m),
                      float(t_c), ground)
    return Bounds(t - t_c, xyz[:, :2].copy(), reach, sign, sigma, index)


def _spread(n: int, cap: int) -> np.ndarray:
    return np.arange(n) if n <= cap else np.unique(np.linspace(0, n - 1, cap).astype(int))


# ---------------------------------------------------------------------------------------------
# The field world (SPEC 1.1): a receiver threshold instead of a range gate, and phones that send
# bursts. A vehicle that heard nothing is evidence only while the phone is known to have sent:
# within a burst some vehicle heard. Each such silence is a censored observation of the frames
# sent then, P(none heard | d) = Phi((S - mu(d)) / sigma)^k (see model.log_probability_residual).

BURST_GAP_S = 3.0  # heard frames closer in time than this are one burst (a burst lasts ~1-2 s)
LISTEN_GAP_S = 1.0  # a track sample at most this far from the burst's time: the vehicle was listening


@dataclass(frozen=True)
class Censored:
    """Vehicles that listened without hearing this phone while it sent: times (M,) [s], vehicle
    positions (M, 3) [m, local ENU, z = height above the people] and the number of frames (M,) the
    phone sent on the channel listened (a lower bound: fewer frames is weaker evidence)."""

    t_s: np.ndarray
    xyz_m: np.ndarray
    frames: np.ndarray
    # With a frames prior (censored_silence(frames_prior=)): every listening vehicle of every heard
    # burst is a row, with the frames it heard (0: silent) and its burst's index; ``frames`` unused.
    heard: np.ndarray | None = None
    burst: np.ndarray | None = None
    prior: "FramesPrior | None" = None
    # The bursts nobody heard (censored_silence(exposure_rates=), with a frames prior): see Exposure.
    exposure: "Exposure | None" = None

    @staticmethod
    def empty() -> "Censored":
        return Censored(np.zeros(0), np.zeros((0, 3)), np.zeros(0))

    def __len__(self) -> int:
        return len(self.t_s)


def burst_windows(heard_t_s, *, gap_s: float = BURST_GAP_S) -> list[tuple[float, float, np.ndarray]]:
    """The heard slots' times grouped into bursts: (first time, last time, row indices) per burst,
    a new burst after every gap longer than ``gap_s`` [s]."""
    t = np.asarray(heard_t_s, float).reshape(-1)
    if len(t) == 0:
        return []
    order = np.argsort(t, kind="stable")
    cut = np.flatnonzero(np.diff(t[order]) > gap_s) + 1
    return [(float(t[g[0]]), float(t[g[-1]]), g) for g in np.split(order, cut)]


def censored_silence(tracks, heard, *, gap_s: float = BURST_GAP_S, listen_gap_s: float = LISTEN_GAP_S,
                     frames: float | None = None, frames_prior: "FramesPrior | None" = None,
                     exposure_rates: "tuple[np.ndarray, np.ndarray] | None" = None) -> Censored:
    """Censored observations of one phone from where the vehicles listened.

    ``tracks``: (vehicle id, times (N,) [s], positions (N, 3) [m, z = height above the people]) per
    receiver, what it flew while listening (its flight log). ``heard``: this phone's heard slots
    (a ``SlotBatch``, ``vehicle`` and ``n_samples`` used). For every burst (heard slots grouped by
    :func:`burst_windows`) each vehicle that heard none of it, and whose track has a sample within
    ``listen_gap_s`` of the burst's middle time, gives one row at its (interpolated) position then.

    Frames per row: the phone sent at least as many frames on the channel as the vehicle that heard
    most of them received (every vehicle is assumed to listen on the burst's channel then: pass only
    the tracks of receivers that did), so that count is used; ``frames`` overrides it (e.g. 1, the
    most conservative). Outside the bursts nothing is known: a phone between bursts is silent, so a
    vehicle overhead that heard nothing says nothing.

    ``frames_prior`` (a :class:`FramesPrior` of the frames sent per burst on the channel): the
    vehicles that heard the burst become rows too, with their counts, and the fit uses the
    hearing counts' likelihood (:func:`burst_count_loglik`) instead of the conservative count.
    ``exposure_rates`` (with ``frames_prior``; :func:`burst_rate_prior`): the bursts sent that no
    vehicle heard are evidence too (:class:`Exposure`, :func:`burst_exposure`).
    """
    t_h = np.asarray(heard.t_s, float)
    veh_h = np.asarray(heard.vehicle)
    n_h = np.maximum(np.asarray(heard.n_samples, float), 1.0)
    rows_t, rows_x, rows_k, rows_n, rows_b = [], [], [], [], []
    xyz_h = np.asarray(heard.xyz_m, float).reshape(-1, 3)
    for b, (t0, t1, idx) in enumerate(burst_windows(t_h, gap_s=gap_s)):
        mid = 0.5 * (t0 + t1)
        by_vehicle = {int(v): float(n_h[idx][veh_h[idx] == v].sum()) for v in np.unique(veh_h[idx])}
        k = float(frames) if frames is not None else max(by_vehicle.values())
        if frames_prior is not None:  # the hearing vehicles: where they heard it, how often
            for v, n in by_vehicle.items():
                m = idx[veh_h[idx] == v]
                rows_t.append(float(np.average(t_h[m], weights=n_h[m])))
                rows_x.append(list(np.average(xyz_h[m], axis=0, weights=n_h[m])))
                rows_k.append(k)
                rows_n.append(n)
                rows_b.append(b)
        for vehicle, t_s, xyz_m in tracks:
            if int(vehicle) in by_vehicle:
                continue
            t = np.asarray(t_s, float).reshape(-1)
            xyz = np.asarray(xyz_m, float).reshape(-1, 3)
            if len(t) == 0 or float(np.min(np.abs(t - mid))) > listen_gap_s:
                continue
            order = np.argsort(t)
            t, xyz = t[order], xyz[order]
            rows_t.append(mid)
            rows_x.append([np.interp(mid, t, xyz[:, c]) for c in range(3)])
            rows_k.append(k)
            rows_n.append(0.0)
            rows_b.append(b)
    if not rows_t:
        return Censored.empty()
    if frames_prior is None:
        return Censored(np.array(rows_t), np.array(rows_x, float), np.array(rows_k, float))
    exposure = (burst_exposure(tracks, heard, frames_prior=frames_prior, rates=exposure_rates, gap_s=gap_s)
                if exposure_rates is not None else None)
    return Censored(np.array(rows_t), np.array(rows_x, float), np.array(rows_k, float), np.array(rows_n, float),
                    np.array(rows_b, int), frames_prior, exposure)


# ---------------------------------------------------------------------------------------------
# Hearing counts: with a prior over the frames a phone sends per burst, whether (and how often) a
# vehicle heard a burst is evidence too. Per heard burst b, with K frames sent on the channel and
# every listening vehicle v hearing each with probability q_v = Phi(-z_v) independently,
#   P_b = sum_K p(K) prod_v Binom(n_v; K, q_v)
# (n_v = 0 for a vehicle that heard none of it). The truncated density of the heard frames' RSSI
# is conditional on their being heard, so the two multiply without double counting. Without a
# prior (K unknown, anything >= the most heard) only the silences can be used (K conservative).

_NEG = -1.0e30  # log 0 that stays finite in sums (0 * -inf is nan)


@dataclass(frozen=True)
class FramesPrior:
    """Prior probabilities ``p`` (K,) of the phone sending 1, 2, ..., K frames in a burst on the
    channel listened (normalised on use)."""

    p: np.ndarray

    @property
    def log_p(self) -> np.ndarray:
        p = np.asarray(self.p, float)
        with np.errstate(divide="ignore"):
            return np.where(p > 0, np.log(np.maximum(p, 1e-300) / p.sum()), _NEG)


def burst_count_loglik(z: np.ndarray, heard: np.ndarray, burst: np.ndarray, n_bursts: int,
                       log_p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ln P_b for states of rows z (S, R) (z = (S - mu) / sigma per listening row), heard counts
    (R,), burst index (R,) in 0..n_bursts-1: (S, B); and d ln P_b / d z_r (S, R) for the row's
    own burst: -n_r lambda(-z_r) + (E[K | b] - n_r) lambda(z_r)."""
    from scipy.special import gammaln, log_ndtr

    from .model import mills_ratio

    z = np.atleast_2d(np.asarray(z, float))
    n = np.asarray(heard, float)
    k = np.arange(1, len(log_p) + 1, dtype=float)
    lq, l1q = log_ndtr(-z), log_ndtr(z)
    kn = k[None, :] - n[:, None]  # (R, K)
    coef = np.where(kn >= 0, gammaln(k[None, :] + 1) - gammaln(n[:, None] + 1) - gammaln(np.maximum(kn, 0) + 1), _NEG)
    logbin = coef[None] + n[None, :, None] * lq[:, :, None] + np.maximum(kn, 0)[None] * l1q[:, :, None]
    member = np.zeros((len(n), n_bursts))
    member[np.arange(len(n)), burst] = 1.0
    per = np.tensordot(logbin, member, axes=([1], [0])).transpose(0, 2, 1) + log_p[None, None, :]  # (S, B, K)
    top = per.max(axis=2, keepdims=True)
    w = np.exp(per - top)
    total = w.sum(axis=2)
    logp = top[:, :, 0] + np.log(total)
    mean_k = (w @ k) / total  # (S, B)
    ek = mean_k[:, burst]  # (S, R)
    dz = -n * mills_ratio(-z) + (ek - n) * mills_ratio(z)
    return logp, dz


# ---------------------------------------------------------------------------------------------
# Exposure: the bursts the phone sent that nobody heard. Bursts are a renewal process of unknown
# rate lam (a Poisson process here); hearing N of them while the vehicles listened has likelihood
#   prod_b [lam P_b] * exp(-lam A),   A(theta) = int P(a burst sent at t is heard | theta) dt
# (P_b: the heard bursts' counts, above). With a prior over lam, the factor the heard bursts do not
# carry is F(A) = int p(lam) lam^N exp(-lam A) dlam: where the vehicles listened long within reach
# (A large) hearing only N bursts is unlikely. Without it the posterior leans towards where the
# vehicles listened most: under an orbit look, the 95 % radius of a walker covered 0.83-0.85
# (docs/science/estimator.md, "The bursts nobody heard").

EXPOSURE_STEP_S = 2.0  # the time cells A is summed over (a vehicle moves 24-50 m in one)
EXPOSURE_MARGIN_S = 150.0  # listening this long before the first and after the last heard burst counts
EXPOSURE_RATES = 48  # points of the burst-rate prior


@dataclass(frozen=True)
class Exposure:
    """Where the vehicles listened around this phone's heard bursts: per row a time (M,) [s], a
    vehicle position (M, 3) [m, z = height above the people] and its time cell (M,) (the rows of one
    cell are the vehicles listening then), each cell ``dt_s`` long; the burst-rate prior as rates
    (J,) [1/s] with ln weights (J,); the frames prior's ln p(K); the bursts heard N."""

    t_s: np.ndarray
    xyz_m: np.ndarray
    cell: np.ndarray
    dt_s: float
    rates: np.ndarray
    log_w: np.ndarray
    log_p: np.ndarray
    bursts: int

    def __len__(self) -> int:
        return len(self.t_s)

    def loglik(self, z: np.ndarray, *, gradient: bool = True) -> tuple[np.ndarray, np.ndarray | None, float]:
        """:func:`exposure_loglik` of these rows at z (S, M)."""
        return exposure_loglik(z, self.cell, self.dt_s, self.rates, self.log_w, self.log_p, self.bursts,
                               gradient=gradient)


def burst_rate_prior(median_gap_s: tuple[float, float], gap_log_sigma: float | tuple[float, float] = 0.0, *,
                     log_uniform: bool = False, points: int = EXPOSURE_RATES) -> tuple[np.ndarray, np.ndarray]:
    """Rates [1/s] and ln weights of a phone's burst rate when its median gap between bursts is
    spread over ``median_gap_s`` (uniformly, or log-uniformly with ``log_uniform``) and each gap is
    log-normal about it with ``gap_log_sigma`` (one value, or its values at the shortest and the
    longest median, interpolated in log median): the rate is 1 / mean gap, mean = median exp(s^2/2)."""
    lo, hi = (float(g) for g in median_gap_s)
    if not (0.0 < lo <= hi):
        raise ValueError(f"median gap between bursts must be positive and ordered, got {median_gap_s}")
    med = np.exp(np.linspace(math.log(lo), math.log(hi), points)) if hi > lo else np.array([lo])
    s_lo, s_hi = (gap_log_sigma, gap_log_sigma) if np.isscalar(gap_log_sigma) else gap_log_sigma
    frac = np.log(med / lo) / math.log(hi / lo) if hi > lo else np.zeros(1)
    sigma = s_lo + (s_hi - s_lo) * frac
    # on a log-spaced grid: log-uniform gives equal weights, uniform weights proportional to the median
    log_w = np.zeros(len(med)) if log_uniform else np.log(med)
    log_w = log_w - np.log(np.sum(np.exp(log_w)))
    return 1.0 / (med * np.exp(0.5 * sigma**2)), log_w


def burst_exposure(tracks, heard, *, frames_prior: "FramesPrior", rates: tuple[np.ndarray, np.ndarray],
                   margin_s: float = EXPOSURE_MARGIN_S, step_s: float = EXPOSURE_STEP_S,
                   gap_s: float = BURST_GAP_S) -> Exposure | None:
    """The exposure rows of one phone from the vehicles' listening ``tracks`` (as for
    :func:`censored_silence`) over its heard bursts' span, ``margin_s`` either side: every
    ``step_s`` each vehicle with a track sample within ``step_s`` is a row at its interpolated
    position. ``rates``: :func:`burst_rate_prior`. None when nothing was heard or nobody listened."""
    t_h = np.asarray(heard.t_s, float)
    windows = burst_windows(t_h, gap_s=gap_s)
    if not windows:
        return None
    t0 = windows[0][0] - margin_s
    t1 = windows[-1][1] + margin_s
    grid = np.arange(t0, t1 + 0.5 * step_s, step_s)
    rows_t, rows_x, rows_c = [], [], []
    for _, t_s, xyz_m in tracks:
        t = np.asarray(t_s, float).reshape(-1)
        if len(t) == 0:
            continue
        xyz = np.asarray(xyz_m, float).reshape(-1, 3)
        order = np.argsort(t)
        t, xyz = t[order], xyz[order]
        k = np.clip(np.searchsorted(t, grid), 1, max(len(t) - 1, 1)) if len(t) > 1 else np.zeros(len(grid), int)
        near = np.minimum(np.abs(t[k] - grid), np.abs(t[np.maximum(k - 1, 0)] - grid)) <= step_s
        if not near.any():
            continue
        g = grid[near]
        rows_t.append(g)
        rows_x.append(np.column_stack([np.interp(g, t, xyz[:, c]) for c in range(3)]))
        rows_c.append(np.flatnonzero(near))
    if not rows_t:
        return None
    r, lw = rates
    return Exposure(np.concatenate(rows_t), np.vstack(rows_x), np.concatenate(rows_c), float(step_s),
                    np.asarray(r, float), np.asarray(lw, float), frames_prior.log_p, len(windows))


def exposure_loglik(z: np.ndarray, cell: np.ndarray, dt_s: float, rates: np.ndarray, log_w: np.ndarray,
                    log_p: np.ndarray, bursts: int, *, gradient: bool = True
                    ) -> tuple[np.ndarray, np.ndarray | None, float]:
    """ln F(A) for states of rows z (S, M) (z = (S - mu) / sigma per row, cells ``cell`` (M,)), its
    derivative d ln F / d z_r (S, M) (None without ``gradient``: the samplers need only ln F), and
    ln F(0), the largest it can be."""
    from scipy.special import log_ndtr

    z = np.atleast_2d(np.asarray(z, float))
    cell = np.asarray(cell, int).reshape(-1)
    order = np.argsort(cell, kind="stable")
    first = np.r_[True, cell[order][1:] != cell[order][:-1]]
    inv = np.empty(len(cell), int)
    inv[order] = np.cumsum(first) - 1  # each row's cell, numbered 0..C-1
    lm = log_ndtr(z)  # ln P(a frame unheard) per row
    L = np.add.reduceat(lm[:, order], np.flatnonzero(first), axis=1)  # (S, C): per cell, every vehicle
    miss, dmiss = _burst_miss(np.minimum(L, 0.0), log_p)  # P(the burst unheard) per cell, d / d L
    A = dt_s * np.sum(1.0 - miss, axis=1)  # (S,)
    a = log_w + bursts * np.log(rates)  # (J,)
    per = a[None, :] - np.outer(A, rates)
    top = per.max(axis=1, keepdims=True)
    e = np.exp(per - top)
    total = e.sum(axis=1)
    logF = top[:, 0] + np.log(total)
    logF0 = float(a.max() + np.log(np.sum(np.exp(a - a.max()))))
    if not gradient:
        return logF, None, logF0
    dlogF_dA = -((e / total[:, None]) @ rates)  # (S,)
    mills = np.exp(-0.5 * z * z - 0.5 * math.log(2.0 * math.pi) - lm)  # phi(z) / Phi(z)
    dA_dz = -dt_s * dmiss[:, inv] * mills  # (S, M)
    return logF, dlogF_dA[:, None] * dA_dz, logF0


_MISS_TABLE: dict = {}


def _burst_miss(L: np.ndarray, log_p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """M = sum_K p(K) x^K with x = exp(L) (every frame of a burst of K unheard), and dM/dL = x M'(x).
    Exact for a few states (the fit); for many (the benchmarks' samplers) interpolated in x from a
    table of 8193 points (error below 1e-5 for K <= 100)."""
    k = np.arange(1, len(log_p) + 1, dtype=float)
    x = np.exp(L)
    if L.shape[0] <= 64:
        e = np.exp(log_p[None, None, :] + k[None, None, :] * L[:, :, None])
        return e.sum(axis=2), e @ k
    key = log_p.tobytes()
    table = _MISS_TABLE.get(key)
    if table is None:
        grid = np.linspace(0.0, 1.0, 8193)
        powers = grid[:, None] ** k[None, :]
        p = np.exp(log_p)
        table = _MISS_TABLE[key] = (grid, powers @ p, (powers * k) @ p)
        if len(_MISS_TABLE) > 8:
            _MISS_TABLE.pop(next(iter(_MISS_TABLE)))
    grid, m, dm = table
    u = x * (len(grid) - 1)  # the grid is uniform on [0, 1]: linear interpolation by index
    i = np.minimum(u.astype(int), len(grid) - 2)
    f = u - i
    return m[i] + f * (m[i + 1] - m[i]), dm[i] + f * (dm[i + 1] - dm[i])
