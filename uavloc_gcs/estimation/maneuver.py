"""Process noise for people who do not walk in a straight line (turns, stops, speed changes).

The constant-velocity (CV) model is the *local* motion of a person; over minutes a person turns,
pauses and changes speed (the simulator's ``random_waypoint``: legs of a few hundred metres at
v_max/2..v_max with 0-30 s pauses). We model the mismatch as white-noise acceleration (an
integrated random walk, IRW) of spectral density q [m^2/s^3] per axis: the true position at time t
deviates from the CV line through the state at the anchor time t_a by delta(t) with

    Cov(delta_x(t1), delta_x(t2)) = q s^2 (3 l - s) / 6,  s = min(|t1-t_a|, |t2-t_a|), l = max(..)

when t1 and t2 lie on the same side of t_a (0 otherwise); Var = q |t - t_a|^3 / 3. The slots are
grouped into *passes* (runs without a time gap, at most ``PASS_MAX_S`` long); each pass gets one
2-D offset delta_j from the line with that joint Gaussian prior (the deviation changes little
within a pass). The offsets are estimated with the state and marginalised by the Laplace
covariance, so an old pass informs the current position only as far as the person could not have
left the line since: old slots are down-weighted, not trusted, and a pass far from the current
position cannot dominate.

q = v_max^2 / ``MANEUVER_TIME_S`` with ``MANEUVER_TIME_S`` = 600 s: a velocity change of the order
of v_max per axis every 600 s. Random waypoint in the paper area has a stop, a start and a turn
(|dv| ~ v, E v^2 ~ 1.3 m^2/s^2) about every 400 s of walk and pause; matching the per-axis
variance gives ~0.0033 m^2/s^3, and v_max^2 / 600 s = 0.00375 m^2/s^3 is that rounded up.
Measured trade-off (``uavloc bench localize``, tests/uavloc_gcs/estimation/test_maneuver.py): the
real process is a jump process with heavier tails than this Gaussian, so a sharp turn at full
speed right after the scan can still mislead the fix (the old lanes pick the wrong mirror of a
single later look pass in 3 of 6 seeds of the turn test); 300 s covers more, but then old data
decay so fast that short look passes no longer bring a static person below 15 m
(tests/sim_link/experiments/test_missionsim.py). ``maneuver_time_s = inf`` gives the pure CV model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

MANEUVER_TIME_S = 600.0  # see the module docstring
PASS_GAP_S = 2.0  # a silence longer than this starts a new pass
PASS_MAX_S = 15.0  # a continuous pass is cut into pieces of at most this length
MAX_PASSES = 8  # more passes are merged (adjacent in time) to bound the cost
MIN_OFFSET_SIGMA_M = 1.0  # passes whose prior deviation is below this stay on the line


def intensity_m2_s3(max_speed_m_s: float, maneuver_time_s: float = MANEUVER_TIME_S) -> float:
    """q [m^2/s^3] per axis; 0 for a static model or an infinite maneuver time."""
    if not (maneuver_time_s > 0) or math.isinf(maneuver_time_s) or max_speed_m_s <= 0:
        return 0.0
    return max_speed_m_s**2 / maneuver_time_s


def irw_covariance(lags_s: np.ndarray, q: float) -> np.ndarray:
    """Per-axis covariance (m, m) [m^2] of the deviations from the CV line at the given lags."""
    a = np.asarray(lags_s, float)
    s = np.minimum(np.abs(a)[:, None], np.abs(a)[None, :])
    big = np.maximum(np.abs(a)[:, None], np.abs(a)[None, :])
    same = np.sign(a)[:, None] * np.sign(a)[None, :] > 0
    return np.where(same, q * s * s * (3.0 * big - s) / 6.0, 0.0)


def state_noise(q: float, dt_s: float) -> np.ndarray:
    """4x4 IRW noise over (x, y, vx, vy) accumulated over |dt_s| (added to a CV prediction)."""
    out = np.zeros((4, 4))
    if q <= 0 or dt_s == 0:
        return out
    t = abs(dt_s)
    block = q * np.array([[t**3 / 3.0, t * t / 2.0], [t * t / 2.0, t]])
    if dt_s < 0:  # back in time the position-velocity correlation changes sign
        block[0, 1] = block[1, 0] = -block[0, 1]
    for k in range(2):
        out[np.ix_([k, k + 2], [k, k + 2])] = block
    return out


@dataclass(frozen=True)
class Passes:
    """Per-observation pass index (-1: on the CV line, no offset), and the whitening W (m, m) of the
    offsets' per-axis prior covariance (W Sigma W^T = I)."""

    index: np.ndarray
    count: int
    whiten: np.ndarray
    lags_s: np.ndarray


def find_passes(t_s: np.ndarray, t_anchor_s: float, q: float) -> Passes | None:
    """Group time-sorted observation times into passes and build the offsets' prior; None when no
    pass is old enough (from the anchor) to deviate by ``MIN_OFFSET_SIGMA_M``."""
    t = np.asarray(t_s, float)
    if q <= 0 or len(t) == 0:
        return None
    new = np.concatenate([[True], np.diff(t) > PASS_GAP_S])
    seg = np.cumsum(new) - 1
    seg_start = t[np.flatnonzero(new)][seg]
    piece = seg * 100_000 + np.floor((t - seg_start) / PASS_MAX_S).astype(int)
    _, raw = np.unique(piece, return_inverse=True)
    mids = np.array([t[raw == k].mean() for k in range(raw.max() + 1)])
    lags = mids - t_anchor_s
    free = np.sqrt(q * np.abs(lags) ** 3 / 3.0) >= MIN_OFFSET_SIGMA_M
    if not free.any():
        return None
    groups = [[k] for k in np.flatnonzero(free)]
    while len(groups) > MAX_PASSES:  # merge the two adjacent groups closest in time
        centre = [mids[g].mean() for g in groups]
        j = int(np.argmin(np.diff(centre)))
        groups[j: j + 2] = [groups[j] + groups[j + 1]]
    index = np.full(len(t), -1, dtype=int)
    glags = np.zeros(len(groups))
    for j, g in enumerate(groups):
        m = np.isin(raw, g)
        index[m] = j
        glags[j] = t[m].mean() - t_anchor_s
    cov = irw_covariance(glags, q)
    cov += np.eye(len(groups)) * 1e-9 * max(float(np.max(np.diag(cov))), 1.0)
    whiten = np.linalg.inv(np.linalg.cholesky(cov))
    return Passes(index, len(groups), whiten, glags)


def offset_jacobian(g: np.ndarray, d2: np.ndarray, passes: Passes) -> np.ndarray:
    """d ln d / d(offsets) (N, 2m): the position columns, placed in the observation's pass."""
    out = np.zeros((len(d2), 2 * passes.count))
    rows = np.flatnonzero(passes.index >= 0)
    cols = 2 * passes.index[rows]
    out[rows, cols] = g[rows, 0] / d2[rows]
    out[rows, cols + 1] = g[rows, 1] / d2[rows]
    return out
