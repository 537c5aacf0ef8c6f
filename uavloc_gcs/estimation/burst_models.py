"""The channel as the grid posterior needs it: one burst's likelihood given where the vehicle heard it.

:class:`BurstModel` is the protocol :mod:`.burst_grid` reads: the log-likelihood that a vehicle heard
a burst's slots (their mean RSSI and frames each; the frames sent unknown, a prior over their
number) or heard none of it, given the horizontal distance, the height and the phone's transmit
offset. :class:`LogDistanceBursts` is the log-distance channel with per-frame shadowing (the field
world before the air-to-ground channel), :class:`A2GBursts` the air-to-ground channel of
:mod:`uavloc_gcs.a2g` (line of sight by elevation angle, one shadowing per burst), the model the
simulated world draws from.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..errors import EstimationError

class BurstModel(Protocol):
    """The channel as the grid needs it."""

    tx_sigma_db: float  # prior std of a phone's transmit offset [dB]

    def heard_loglik(self, rssi_dbm: np.ndarray, counts: np.ndarray, frames_pmf: np.ndarray,
                     horizontal_m: np.ndarray, height_m: float, tx_offset_db: np.ndarray) -> np.ndarray:
        """log p(a vehicle heard these slots of one burst | geometry, offset), the frames sent unknown
        (``frames_pmf`` over K = 0..Kmax); broadcast over ``horizontal_m`` x ``tx_offset_db``."""

    def silent_loglik(self, frames_pmf: np.ndarray, horizontal_m: np.ndarray, height_m: float,
                      tx_offset_db: np.ndarray) -> np.ndarray:
        """log P(a vehicle listening during a burst heard none of its frames | geometry, offset)."""

    def reach_m(self, height_m: float) -> float:
        """A distance beyond which a burst is practically never heard (the grid's extent)."""


@dataclass(frozen=True)
class LogDistanceBursts:
    """The log-distance channel with i.i.d. per-frame shadowing: a frame's RSSI is
    N(P0 + tx - 10 eta log10(d / d0), sigma^2) and it is heard above ``sensitivity_dbm``."""

    reference_power_dbm: float
    path_loss_exponent: float
    shadowing_sigma_db: float
    reference_distance_m: float
    sensitivity_dbm: float
    tx_sigma_db: float

    @staticmethod
    def from_scenario(sc) -> "LogDistanceBursts":
        ch = sc.channel
        if ch.receiver_sensitivity_dbm is None:
            raise EstimationError("the burst grid needs a receiver threshold ([channel] receiver_sensitivity_dbm)")
        return LogDistanceBursts(ch.reference_power_dbm, ch.path_loss_exponent, ch.shadowing_sigma_db,
                                 ch.reference_distance_m, ch.receiver_sensitivity_dbm,
                                 max(sc.simulation.tx_power_spread_db, TX_FLOOR_DB))

    def _mu(self, horizontal_m, height_m, tx_offset_db) -> np.ndarray:
        d = np.maximum(np.hypot(horizontal_m, height_m), 1e-3)
        return (self.reference_power_dbm + tx_offset_db
                - 10.0 * self.path_loss_exponent * np.log10(d / self.reference_distance_m))

    @staticmethod
    def _count_terms(log_1q: np.ndarray, n: int, frames_pmf: np.ndarray) -> np.ndarray:
        """log sum_K p(K) C(K, n) (1-q)^(K-n): K frames sent, n heard (whose densities the caller
        adds), the others missed, each with probability 1 - q. A smooth function of log(1 - q)
        alone: tabulated once per (n, prior) and interpolated."""
        u, v = _count_table(n, tuple(float(p) for p in frames_pmf))
        return np.interp(np.clip(log_1q, u[0], 0.0), u, v)

    def heard_loglik(self, rssi_dbm, counts, frames_pmf, horizontal_m, height_m, tx_offset_db):
        from scipy.special import log_ndtr

        mu = self._mu(horizontal_m, height_m, tx_offset_db)
        s = self.shadowing_sigma_db
        z_s = (self.sensitivity_dbm - mu) / s
        log_1q = log_ndtr(z_s)  # a frame missed
        n = int(round(float(np.sum(counts))))
        out = self._count_terms(log_1q, n, np.asarray(frames_pmf, float))
        for r, c in zip(np.asarray(rssi_dbm, float), np.asarray(counts, float)):
            # a slot's mean of c frames: each heard frame's density, their mean's spread sigma / sqrt(c)
            sc = s / math.sqrt(max(c, 1.0))
            out = out + (-0.5 * ((r - mu) / sc) ** 2 - math.log(sc * math.sqrt(2.0 * math.pi)))
        return out

    def silent_loglik(self, frames_pmf, horizontal_m, height_m, tx_offset_db):
        from scipy.special import log_ndtr

        mu = self._mu(horizontal_m, height_m, tx_offset_db)
        z_s = (self.sensitivity_dbm - mu) / self.shadowing_sigma_db
        return self._count_terms(log_ndtr(z_s), 0, np.asarray(frames_pmf, float))

    decorrelation_m = None  # i.i.d. per frame: no weighting of units (unit_weights)

    def reach_m(self, height_m: float) -> float:
        # the distance at which a frame 5 sigma above the median (and 3 sigma of offset) is just heard
        margin = self.reference_power_dbm + 3.0 * self.tx_sigma_db + 5.0 * self.shadowing_sigma_db - self.sensitivity_dbm
        d = self.reference_distance_m * 10.0 ** (margin / (10.0 * self.path_loss_exponent))
        return float(math.sqrt(max(d * d - height_m * height_m, 1.0)))


@dataclass(frozen=True)
class A2GBursts:
    """The air-to-ground channel (``uavloc_gcs.a2g``, ``[channel] environment``): line of sight by
    elevation angle, the burst's shared shadowing and each frame's fading integrated out by the
    channel's own burst likelihood -- the model the simulated world draws from (issue 41 item 1:
    the estimator, the POD and the look planner use the same channel)."""

    channel: object  # a2g.A2GChannel (frozen, hashable)
    tx_sigma_db: float
    frames_pmf: tuple[float, ...]
    channel_share: float = 1.0  # the share of a burst's frames sent on channels the sensor listens to

    @staticmethod
    def from_scenario(sc, frames_pmf, channel_share: float = 1.0) -> "A2GBursts | None":
        """None when the scenario names no environment (the log-distance channel). ``channel_share``:
        search.pod's share of probe frames on the listened channels."""
        from ..a2g import A2GChannel

        ch = A2GChannel.from_scenario(sc)
        if ch is None:
            return None
        if ch.sensitivity_dbm is None:
            raise EstimationError("the burst grid needs a receiver threshold ([channel] receiver_sensitivity_dbm)")
        return A2GBursts(ch, max(sc.simulation.tx_power_spread_db, TX_FLOOR_DB), tuple(float(p) for p in frames_pmf),
                         float(channel_share))

    def _call(self, rssi_dbm, counts, frames_pmf, horizontal_m, height_m, tx_offset_db):
        """The channel's burst likelihood over (offset x distance). Given the line-of-sight state it
        depends on the geometry and the offset only through the local mean power, so each state's
        term is computed on a MEAN_POWER_STEP_DB grid of that power and interpolated (a table of 29
        offsets x 1,000 distances costs a few hundred evaluations instead of 29,000)."""
        from ..a2g import LOS, NLOS

        ch = self.channel
        h, tx = np.broadcast_arrays(np.asarray(horizontal_m, float), np.asarray(tx_offset_db, float))
        z = float(height_m)
        d3 = np.hypot(h, z)
        p_los = np.clip(ch.los_probability(h, z), 1e-300, 1.0)
        out = None
        for s, w in ((LOS, p_los), (NLOS, np.clip(1.0 - p_los, 1e-300, 1.0))):
            mp = ch.mean_power_dbm(d3, s, tx)
            lo, hi = float(np.min(mp)), float(np.max(mp))
            grid = np.arange(lo - MEAN_POWER_STEP_DB, hi + 2 * MEAN_POWER_STEP_DB, MEAN_POWER_STEP_DB)
            f = ch.state_log_likelihood_unknown_sent(np.asarray(rssi_dbm, float), np.asarray(frames_pmf, float), grid,
                                                     s, counts=np.asarray(counts, float),
                                                     channel_share=self.channel_share)
            f = np.maximum(f, -1e300)
            part = np.log(w) + np.interp(mp, grid, f)
            out = part if out is None else np.logaddexp(out, part)
        return out

    def heard_loglik(self, rssi_dbm, counts, frames_pmf, horizontal_m, height_m, tx_offset_db):
        return self._call(rssi_dbm, counts, frames_pmf, horizontal_m, height_m, tx_offset_db)

    def silent_loglik(self, frames_pmf, horizontal_m, height_m, tx_offset_db):
        return self._call(np.zeros(0), np.zeros(0), frames_pmf, horizontal_m, height_m, tx_offset_db)

    def reach_m(self, height_m: float) -> float:
        return _a2g_reach_m(self, round(float(height_m)))

    @property
    def decorrelation_m(self) -> float:
        """The distance over which a path's shadowing decorrelates (unit_weights)."""
        return float(self.channel.environment.decorrelation_m)

    @property
    def shared_and_own_db2(self) -> tuple[float, float]:
        """(shadowing variance, fading variance) [dB^2] of a unit in line of sight: the part a unit
        shares with its neighbours and the part that is its own (unit_weights)."""
        from ..a2g import LOS

        return float(self.channel.shadow_db[LOS]) ** 2, float(self.channel.fast_db[LOS]) ** 2


@functools.lru_cache(maxsize=4096)  # (phone model, whole metres of height): a search flies every height while climbing
def _a2g_reach_m(model: A2GBursts, height_m: float) -> float:
    """Where a burst of a phone 2 sigma louder than nominal is heard with probability 1e-3 (the
    urban channel's line of sight at low elevation keeps a thin tail out to kilometres)."""
    pmf = np.asarray(model.frames_pmf, float)
    return max(float(model.channel.hearing_distance_m(height_m, frames=("pmf", pmf), p=1e-3,
                                                      channel_share=model.channel_share,
                                                      tx_offset_db=2.0 * model.tx_sigma_db, step_m=5.0)), 50.0)


MEAN_POWER_STEP_DB = 0.05  # A2GBursts: grid step of a state's likelihood over the local mean power

TX_FLOOR_DB = 1.0  # the offset prior is never narrower than this (no phone is exactly nominal)
COUNT_TABLE_U = np.concatenate([-np.geomspace(60.0, 1e-6, 1200), [0.0]])  # log(1 - q) where tabulated


@functools.lru_cache(maxsize=512)
def _count_table(n: int, frames_pmf: tuple) -> tuple[np.ndarray, np.ndarray]:
    """(u, log sum_K p(K) C(K, n) e^(u (K - n))) over COUNT_TABLE_U (-inf where no K >= n)."""
    from scipy.special import gammaln

    pmf = np.asarray(frames_pmf, float)
    k = np.arange(len(pmf))
    ok = (k >= n) & (pmf > 0)
    u = COUNT_TABLE_U
    if not np.any(ok):
        return u, np.full(len(u), -1e300)
    kk = k[ok]
    lc = np.log(pmf[ok] / pmf.sum()) + gammaln(kk + 1) - gammaln(n + 1) - gammaln(kk - n + 1)
    a = lc[None, :] + (kk - n)[None, :] * u[:, None]
    m = np.max(a, axis=1, keepdims=True)
    return u, np.squeeze(m, 1) + np.log(np.sum(np.exp(a - m), axis=1))


