"""The field world's 95 % radius (estimation.field_radius) is the posterior's: checked against a
dense grid of the same truncated likelihood, written out here from the channel model in dBm."""

import numpy as np
import pytest
from scipy.special import log_ndtr, logsumexp

from uavloc_gcs.estimation import estimate_emitter
from uavloc_gcs.estimation.estimate import TX_PRIOR_SIGMA_DB
from uavloc_gcs.observations import SlotBatch

from .test_threshold import FIELD, frames_heard, leg


def crossing_legs(truth_xy, tx_db, seed):
    """A static phone heard by two crossing legs (10 frames a second, kept above the sensitivity)."""
    rng = np.random.default_rng(seed)
    ta, xa = leg(0.0, 0.0, x0=-1000.0, x1=1000.0, rate_hz=10.0)
    tb, xb = leg(0.0, 90.0, x0=-1000.0, x1=1000.0, rate_hz=10.0)
    xb = xb[:, [1, 0, 2]]  # the second leg flies north through the same point
    a = frames_heard(FIELD, truth_xy, ta, xa, rng, vehicle=1, tx_db=tx_db)
    b = frames_heard(FIELD, truth_xy, tb, xb, rng, vehicle=2, tx_db=tx_db)
    return SlotBatch.concat([a, b])


def grid_radius(slots, center_xy, tx_sigma_db, half_m=300.0, step_m=4.0, prob=0.95):
    """The radius about ``center_xy`` holding ``prob`` of the posterior of a static position (flat
    prior) and, when ``tx_sigma_db``, a transmit offset N(0, tx_sigma_db) integrated out."""
    ax = np.arange(-half_m, half_m + step_m / 2, step_m)
    gx, gy = np.meshgrid(center_xy[0] + ax, center_xy[1] + ax)
    p = np.column_stack([gx.ravel(), gy.ravel()])
    xyz = np.asarray(slots.xyz_m)
    d = np.sqrt(np.sum((p[:, None, :] - xyz[None, :, :2]) ** 2, axis=2) + xyz[None, :, 2] ** 2)
    mu0 = FIELD.rssi_dbm(d)  # (G, F)
    s, sens = FIELD.shadowing_sigma_db, FIELD.sensitivity_dbm
    rssi = np.asarray(slots.rssi_dbm)[None, :]
    betas = np.linspace(-3.0, 3.0, 49) * tx_sigma_db if tx_sigma_db else np.zeros(1)
    parts = []
    for beta in betas:
        mu = mu0 + beta
        heard = -0.5 * ((rssi - mu) / s) ** 2 - log_ndtr((mu - sens) / s)  # the frame's density given heard
        parts.append(heard.sum(axis=1) - (0.5 * (beta / tx_sigma_db) ** 2 if tx_sigma_db else 0.0))
    lp = logsumexp(np.array(parts), axis=0)
    w = np.exp(lp - lp.max())
    w /= w.sum()
    edge = (np.abs(gx.ravel() - center_xy[0]) > half_m - 2 * step_m) | (np.abs(gy.ravel() - center_xy[1]) > half_m - 2 * step_m)
    assert w[edge].sum() < 1e-3, "the grid must hold the posterior"
    dist = np.hypot(p[:, 0] - center_xy[0], p[:, 1] - center_xy[1])
    order = np.argsort(dist)
    return float(dist[order][np.searchsorted(np.cumsum(w[order]), prob)])


@pytest.mark.parametrize("tx", [False, True], ids=["tx known", "tx estimated"])
def test_the_sampled_radius_is_the_posteriors(tx):
    truth = np.array([180.0, -140.0])
    slots = crossing_legs(truth, 4.0 if tx else 0.0, seed=7)
    assert 10 <= len(slots) <= 200
    est = estimate_emitter(slots, FIELD, max_speed_m_s=1.5, model_motion=False, estimate_tx_power=tx)
    assert est.ok
    exact = grid_radius(slots, est.position_xy_m, TX_PRIOR_SIGMA_DB if tx else 0.0)
    # importance sampling with 4,096 fixed draws, against a grid of 4 m and 0.75 dB: within 2 % here;
    # with the transmit offset drawn from its prior apart from the position (before 2026-11-28)
    # the radius was 9 % short
    assert est.radius95_m == pytest.approx(exact, rel=0.04), (est.radius95_m, exact)
