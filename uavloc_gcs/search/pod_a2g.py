"""The POD model's hearing under an air-to-ground environment (``[channel] environment``,
:mod:`uavloc_gcs.a2g`): whether a burst is heard depends on the horizontal distance *and* the
height of the vehicle above the phone (the elevation angle decides line of sight), so the tables of
:mod:`.pod` become two-dimensional: per phone type over (horizontal distance, height).

The height is the flight's own (each track sample's z above the phone's ground), not the scenario's
altitude: a look at 30 m and a scan at 100 m are judged each at its height.

Built from :meth:`uavloc_gcs.a2g.A2GChannel.burst_heard_given_margin`: for a phone type (frames
per burst) and a path state the probability of hearing a burst depends only on the margin of a
frame's mean RSSI over the sensitivity, so it is tabulated once against the margin (every
:data:`MARGIN_STEP_DB`) and the 2-D tables are interpolations of it.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..a2g import LOS, NLOS, A2GChannel

H_STEP_M = 2.0  # horizontal distance step of the tables [m]
Z_STEP_M = 2.0  # height step [m]
Z_MAX_M = 300.0  # heights above this are looked up at this height
H_MAX_M = 3000.0  # the tables are trimmed to where some type still hears with more than P_EPS
MARGIN_STEP_DB = 0.05


def frames_pmf(ks, weights) -> np.ndarray:
    """A pmf over 0..max(K) from frame counts ``ks`` and their weights."""
    k = np.asarray(ks, float).astype(int)
    return np.bincount(k, weights=np.asarray(weights, float), minlength=int(k.max()) + 1)


def burst_heard(a2g: A2GChannel, horizontal_m, height_m, *, tx_offset_db, ks, weights,
                channel_share: float) -> np.ndarray:
    """P(a burst of K ~ (ks, weights) frames is heard) at the geometry (exact, no table)."""
    return a2g.burst_heard_probability(horizontal_m, height_m, ("pmf", frames_pmf(ks, weights)),
                                       channel_share=channel_share, tx_offset_db=tx_offset_db)


def tables(a2g: A2GChannel, tx_db, frame_types, channel_share: float, p_eps: float,
           elicit_rate_hz: float = 0.0, elicit_range_m: float = 0.0):
    """Per type (every transmit offset in ``tx_db`` x every (ks, weights) of ``frame_types``, in
    that order): P(burst heard) over (horizontal, height), and with ``elicit_rate_hz`` the heard
    elicited frames per second (the phone answers within ``elicit_range_m`` 3-D, each frame through
    the channel). Returns (h_grid, z_grid, table (H, Z, T), max 3-D reach [m], elicit (H, Z, T) or
    None, reach by height (Z,): the 3-D reach of vehicles at or below each height [m])."""
    h = np.arange(0.0, H_MAX_M + H_STEP_M, H_STEP_M)
    z = np.arange(0.0, Z_MAX_M + Z_STEP_M, Z_STEP_M)
    hh, zz = np.meshgrid(h, z, indexing="ij")
    d3 = np.hypot(hh, zz)
    p_los = a2g.los_probability(hh, zz)
    margin = [a2g.mean_power_dbm(d3, s) - a2g.sensitivity_dbm for s in (LOS, NLOS)]
    tx_db = np.asarray(tx_db, float)
    lo = min(float(m.min()) for m in margin) + float(tx_db.min()) - 1.0
    hi = max(float(m.max()) for m in margin) + float(tx_db.max()) + 1.0
    grid = np.arange(lo, hi + MARGIN_STEP_DB, MARGIN_STEP_DB)
    cols = []
    for tx in tx_db:
        for ks, wk in frame_types:
            pmf = frames_pmf(ks, wk)
            p = 0.0
            for s, w in ((LOS, p_los), (NLOS, 1.0 - p_los)):
                g = a2g.burst_heard_given_margin(s, grid, pmf, channel_share=channel_share)
                p = p + w * np.interp(margin[s] + tx, grid, g)
            cols.append(p)
    table = np.stack(cols, axis=-1)  # (H, Z, T)
    reach = np.nonzero(table.max(axis=(1, 2)) > p_eps)[0]
    n_h = int(reach.max()) + 2 if len(reach) else 2
    table = table[:n_h]
    hit = table.max(axis=2) > p_eps  # (H, Z)
    max_reach = float(d3[:n_h][hit].max()) + H_STEP_M if np.any(hit) else 0.0
    reach_z = np.maximum.accumulate(np.where(hit, d3[:n_h], 0.0).max(axis=0)) + H_STEP_M
    elicit = None
    if elicit_rate_hz > 0:
        rates = []
        for tx in tx_db:
            q = a2g.frame_heard_probability(hh[:n_h], zz[:n_h], tx)
            rates.append(elicit_rate_hz * q * (d3[:n_h] <= elicit_range_m))
        per_tx = np.stack(rates, axis=-1)  # (H, Z, n_tx)
        elicit = np.repeat(per_tx, len(frame_types), axis=-1).astype(np.float32)
    return h[:n_h], z, table, max_reach, elicit, reach_z


def lookup(table: np.ndarray, horizontal_m, height_m) -> np.ndarray:
    """Nearest-cell lookup in a table (H, Z, ...) of :func:`tables` (heights clipped to the grid)."""
    i = np.minimum(np.rint(np.asarray(horizontal_m, float) / H_STEP_M).astype(np.int32), table.shape[0] - 1)
    j = np.clip(np.rint(np.asarray(height_m, float) / Z_STEP_M).astype(np.int32), 0, table.shape[1] - 1)
    return table[i, j]


# ---------------------------------------------------------------------------------------------
# Looks that hear unevenly
#
# The POD model turns a look into a window in which every burst is heard, w = integral of p dt
# (thinning). That is exact where p is 0 or 1, as under the log-distance channel's steep edge, but
# under the air-to-ground channel p is low and broad (line of sight is a matter of chance at low
# angles), and a look then holds several bursts each heard with a middling probability: thinning
# overstates the chance of hearing one (about 14 % relative for a 100 m pass; benchmarks/pod_world).
# So a look is taken as T_eff = w^2 / integral(p^2 dt) seconds of bursts each heard with
# p_bar = integral(p^2) / integral(p): P(>= 1 heard) = E[1 - (1 - p_bar)^N], N the bursts sent in
# T_eff, and P(exactly 1) = E[N p_bar (1 - p_bar)^(N - 1)] -- equal to thinning when p_bar = 1.

P_LEVELS = 41  # p_bar grid 0, 0.025, ..., 1
N_MAX = 200  # bursts in one window the tables count (an hour of the most frequent prober is ~124)


@lru_cache(maxsize=4)
def _uneven_tables(bt):
    """Per phone quantile: G1[T, p] = P(>= 1 heard) and H1[T, p] = P(exactly 1 heard) of a window of
    T seconds (phones.ACTIVE_DT_S grid, the active renewal process in steady state) whose bursts are each
    heard with probability p (P_LEVELS grid). float32 (N_QUANTILES, T, P)."""
    import math

    from scipy.signal import fftconvolve
    from scipy.special import ndtr as _ndtr
    from scipy.stats import lognorm

    from .phones import ACTIVE_CAP_S, ACTIVE_DT_S, N_QUANTILES

    dt = ACTIVE_DT_S
    edges = np.arange(0.0, ACTIVE_CAP_S + dt, dt)
    p = np.linspace(0.0, 1.0, P_LEVELS)
    g1 = np.zeros((N_QUANTILES, len(edges), P_LEVELS), np.float32)
    h1 = np.zeros_like(g1)
    for iu, (med, sig) in enumerate(zip(bt.gap_median_s(), bt.gap_log_sigma())):
        dist = lognorm(s=sig, scale=med)
        c = dist.cdf(edges)
        c[edges < bt.min_gap_s] = 0.0
        pmf = np.diff(np.concatenate([[0.0], c]))
        pmf[-1] += 1.0 - pmf.sum()
        m = bt.min_gap_s
        mean = med * math.exp(sig * sig / 2) * _ndtr((math.log(med / m) + sig * sig) / sig) + m * float(dist.cdf(m))
        surv = 1.0 - c
        acc = np.concatenate([[0.0], 0.5 * (surv[1:] + surv[:-1]) * dt / mean])  # forward recurrence
        ga, ha = np.zeros((len(edges), P_LEVELS)), np.zeros((len(edges), P_LEVELS))
        for k in range(1, N_MAX + 1):
            if k > 1:
                acc = fftconvolve(acc, pmf)[: len(edges)].clip(min=0.0)
            at_least = np.minimum(np.cumsum(acc), 1.0)  # P(N >= k)
            if at_least[-1] < 1e-7:
                break
            ga += at_least[:, None] * (p * (1.0 - p) ** (k - 1))[None]
            fk = k * p * (1.0 - p) ** (k - 1)
            fk1 = (k - 1) * p * (1.0 - p) ** max(k - 2, 0) if k > 1 else np.zeros_like(p)
            ha += at_least[:, None] * (fk - fk1)[None]
        g1[iu], h1[iu] = ga, np.clip(ha, 0.0, 1.0)
    return edges, g1, h1


def heard_12(bt, window_s, p_bar, iu: int) -> tuple[np.ndarray, np.ndarray]:
    """(P(>= 1 burst heard), P(exactly 1)) for windows of ``window_s`` seconds of bursts heard with
    ``p_bar`` each (broadcasting arrays), phone quantile index ``iu``; bilinear in both."""
    edges, g1, h1 = _uneven_tables(bt)
    x = np.clip(np.asarray(window_s, np.float32) / np.float32(edges[1] - edges[0]), 0, len(edges) - 1.001)
    i = x.astype(np.int32)
    fx = x - i
    y = np.clip(np.asarray(p_bar, np.float32) * np.float32(P_LEVELS - 1), 0, P_LEVELS - 1.001)
    j = y.astype(np.int32)
    fy = y - j
    out = []
    for tab in (g1[iu], h1[iu]):
        a = tab[i, j] + fy * (tab[i, j + 1] - tab[i, j])
        b = tab[i + 1, j] + fy * (tab[i + 1, j + 1] - tab[i + 1, j])
        out.append(a + fx * (b - a))
    return out[0], out[1]
