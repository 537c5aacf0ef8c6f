"""When phones send, for the POD model and the looks: :class:`BurstTiming` (see :mod:`.pod`'s docstring).

A stationary renewal process per phone, gaps log-normal about a median drawn by a phone quantile,
long silences replacing a gap now and then, taken in steady state (a search starts at a random
moment of every phone's life): how many bursts a window of a given length holds
(:func:`_active_tables`), the silence timelines that make passes dependent (:func:`_silences`,
:func:`_overlap`), and the window in which a phone sends k bursts with probability p
(``BurstTiming.window_for``, the orbit looks' dwell).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from .phones import ACTIVE_CAP_S, ACTIVE_DT_S, MIN_QUIET_S, N_QUANTILES, SILENCE_DRAWS, WINDOW_CAP_S


def _ndtr(x):
    from scipy.special import ndtr

    return ndtr(x)


@dataclass(frozen=True)
class BurstTiming:
    """The phones' burst timing (see the module docstring). ``continuous``: the paper's emitter."""

    continuous: bool
    slot_s: float = 0.025
    gap_median_min_s: float = 20.0
    gap_median_max_s: float = 135.0
    gap_p90_min_s: float = 60.0
    gap_p90_max_s: float = 270.0
    long_silence_per_gap: float = 0.0094
    long_silence_min_s: float = 1800.0
    long_silence_max_s: float = 5400.0
    min_gap_s: float = 4.2

    @classmethod
    def from_scenario(cls, sc) -> "BurstTiming":
        em = sc.emission
        if em.model == "continuous":
            return cls(True, slot_s=sc.channel.slot_s)
        return cls(False, sc.channel.slot_s, em.burst_gap_median_min_s, em.burst_gap_median_max_s,
                   em.burst_gap_p90_min_s, em.burst_gap_p90_max_s, em.long_silence_per_gap,
                   em.long_silence_min_s, em.long_silence_max_s,
                   em.frames_per_burst_max * em.frame_spacing_s + MIN_QUIET_S)

    # -- per phone quantile ---------------------------------------------------------------
    @property
    def quantiles(self) -> np.ndarray:
        return (np.arange(N_QUANTILES) + 0.5) / N_QUANTILES

    def gap_median_s(self) -> np.ndarray:
        u = self.quantiles
        return self.gap_median_min_s * (self.gap_median_max_s / self.gap_median_min_s) ** u

    def gap_log_sigma(self) -> np.ndarray:
        u = self.quantiles
        p90 = self.gap_p90_min_s * (self.gap_p90_max_s / self.gap_p90_min_s) ** u
        return np.log(p90 / self.gap_median_s()) / 1.2815515655446004

    def mean_active_gap_s(self) -> np.ndarray:
        """Mean gap between bursts outside long silences, per phone quantile [s]."""
        return _active_tables(self)[2]

    def silence_share(self) -> np.ndarray:
        """Steady-state share of time a phone spends in long silences, per quantile."""
        q = self.long_silence_per_gap
        mean_l = _loguniform_mean(self.long_silence_min_s, self.long_silence_max_s)
        g = self.mean_active_gap_s()
        return q * mean_l / ((1.0 - q) * g + q * mean_l)

    def p_active(self, k: int, alive_s, iu: int) -> np.ndarray:
        """P(>= k bursts within ``alive_s`` seconds of a phone of quantile index ``iu`` outside a
        long silence), the steady state of the gaps alone."""
        grid, cdf, _ = _active_tables(self, k)
        return np.interp(alive_s, grid, cdf[k - 1][iu], right=cdf[k - 1][iu][-1])

    def p_active_12(self, alive_s: np.ndarray, iu: int) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`p_active` for k = 1 and 2 at once (direct indexing on the regular grid)."""
        grid, cdf, _ = _active_tables(self)
        x = np.clip(np.asarray(alive_s, np.float32) * np.float32(1.0 / ACTIVE_DT_S), 0, len(grid) - 1.001)
        i = x.astype(np.int32)
        f = x - i
        c1, c2 = cdf[0][iu].astype(np.float32), cdf[1][iu].astype(np.float32)
        return c1[i] + f * (c1[i + 1] - c1[i]), c2[i] + f * (c2[i + 1] - c2[i])

    def silences(self, horizon_s: float) -> list[np.ndarray]:
        """Per phone quantile: (SILENCE_DRAWS, M, 2) silent intervals [s] from t = 0 (steady state),
        padded with empty intervals; deterministic."""
        return _silences(self, round(float(horizon_s), 1))

    # -- the population ---------------------------------------------------------------------
    def p_at_least(self, k: int, window_s):
        """Population-average P(>= k bursts sent during a window of ``window_s`` seconds) (scalar or
        array), steady state, long silences included."""
        w = np.asarray(window_s, float)
        if self.continuous:
            out = (w >= max(int(k), 1) * self.slot_s).astype(float)
            return float(out) if out.ndim == 0 else out
        k = int(k)
        if k <= 0:
            return 1.0 if w.ndim == 0 else np.ones_like(w)
        flat = w.reshape(-1)
        horizon = float(max(np.max(flat, initial=0.0), 1.0))
        total = np.zeros(len(flat))
        for iu, sil in enumerate(self.silences(horizon)):
            alive = flat[None, :] - _overlap(np.zeros(len(flat)), flat, sil)  # (D, n)
            total += self.p_active(k, alive, iu).mean(axis=0)
        out = total / N_QUANTILES
        return float(out[0]) if w.ndim == 0 else out.reshape(w.shape)

    def window_for(self, k: int, p: float) -> float:
        """Smallest window [s] with ``p_at_least(k, w) >= p``; math.inf if none below
        :data:`WINDOW_CAP_S`."""
        if self.continuous:
            return max(int(k), 1) * self.slot_s
        if self.p_at_least(k, WINDOW_CAP_S) < p:
            return math.inf
        lo, hi = 0.0, WINDOW_CAP_S
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if self.p_at_least(k, mid) >= p else (mid, hi)
            if hi - lo < 0.5:
                break
        return hi


def _loguniform_mean(a: float, b: float) -> float:
    return (b - a) / math.log(b / a) if b > a else a


@lru_cache(maxsize=16)
def _active_tables(bt: BurstTiming, k_max: int = 3):
    """Grid of windows [s], CDF tables cdf[k-1][iu] = P(>= k bursts in a window) for the active
    renewal process (log-normal gaps, at least ``min_gap_s``) in steady state, mean gaps per quantile."""
    from scipy.signal import fftconvolve
    from scipy.stats import lognorm

    k_max = max(3, int(k_max))
    dt = ACTIVE_DT_S
    edges = np.arange(0.0, ACTIVE_CAP_S + dt, dt)
    cdf = [np.zeros((N_QUANTILES, len(edges))) for _ in range(k_max)]
    means = np.zeros(N_QUANTILES)
    for iu, (med, sig) in enumerate(zip(bt.gap_median_s(), bt.gap_log_sigma())):
        dist = lognorm(s=sig, scale=med)
        c = dist.cdf(edges)
        c[edges < bt.min_gap_s] = 0.0  # the gap is at least min_gap_s: its mass sits at min_gap_s
        pmf = np.diff(np.concatenate([[0.0], c]))  # pmf[i] = P(G in (edges[i-1], edges[i]])
        pmf[-1] += 1.0 - pmf.sum()
        # mean of max(G, min_gap): E[G 1{G > m}] + m P(G <= m)
        m = bt.min_gap_s
        tail = med * math.exp(sig * sig / 2) * _ndtr((math.log(med / m) + sig * sig) / sig)
        mean = tail + m * float(dist.cdf(m))
        means[iu] = mean
        # forward recurrence time: density S(a) / mean
        surv = 1.0 - c
        fa = np.concatenate([[0.0], 0.5 * (surv[1:] + surv[:-1]) * dt / mean])
        acc = fa
        for k in range(k_max):
            if k > 0:
                acc = fftconvolve(acc, pmf)[: len(edges)].clip(min=0.0)
            cdf[k][iu] = np.minimum(np.cumsum(acc), 1.0)
    return edges, cdf, means


@lru_cache(maxsize=16)
def _silences(bt: BurstTiming, horizon_s: float) -> list[np.ndarray]:
    rng = np.random.default_rng(20261125)
    q, a, b = bt.long_silence_per_gap, bt.long_silence_min_s, bt.long_silence_max_s
    out = []
    share = bt.silence_share()
    gaps = bt.mean_active_gap_s()
    for iu in range(N_QUANTILES):
        rows = []
        active_mean = gaps[iu] * (1.0 - q) / q if q > 0 else math.inf
        for d in range(SILENCE_DRAWS):
            u = (d + rng.uniform()) / SILENCE_DRAWS  # stratified: the silent share is drawn exactly
            iv = []
            if u < share[iu]:  # silent now: a length-biased log-uniform silence is uniform on [a, b]
                length = rng.uniform(a, b)
                t = rng.uniform() * length
                iv.append((0.0, t))
            else:
                t = 0.0
            while math.isfinite(active_mean):
                t += rng.exponential(active_mean)
                if t >= horizon_s:
                    break
                length = math.exp(rng.uniform(math.log(a), math.log(b)))
                iv.append((t, t + length))
                t += length
                if t >= horizon_s:
                    break
            rows.append(iv)
        m = max(1, max(len(r) for r in rows))
        arr = np.zeros((SILENCE_DRAWS, m, 2))
        for d, r in enumerate(rows):
            if r:
                arr[d, : len(r)] = r
        out.append(arr)
    return out


def _overlap(t0: np.ndarray, t1: np.ndarray, sil: np.ndarray) -> np.ndarray:
    """Seconds of [t0, t1] (any shape S) inside the silent intervals (D, M, 2): shape (D,) + S."""
    s0 = sil[:, :, 0].reshape(sil.shape[:2] + (1,) * t0.ndim)
    s1 = sil[:, :, 1].reshape(sil.shape[:2] + (1,) * t0.ndim)
    ov = np.clip(np.minimum(t1[None, None], s1) - np.maximum(t0[None, None], s0), 0.0, None)
    return ov.sum(axis=1)


