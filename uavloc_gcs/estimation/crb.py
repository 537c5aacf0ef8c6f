"""Cramer-Rao bounds for the benchmark and the planner (SPEC §3.2).

``J = sum_i (n_i / s^2) grad ln d_i grad ln d_i^T`` over independent samples, evaluated at a
known state (the truth in simulation), plus the estimator's prior information (velocity prior
sigma_v = 0.6 v_max per axis, transmit-offset prior). Averaging J over Monte Carlo runs and
inverting gives the Bayesian (Van Trees) bound on the position error at ``t_ref_s``.
"""

from __future__ import annotations

import math

import numpy as np

from ..observations import SlotBatch
from .estimate import TX_PRIOR_SIGMA_DB
from .fit import POSITION_PRIOR_SIGMA_M, VELOCITY_PRIOR_FRACTION
from .model import ChannelModel, fisher_information


def data_information(
    slots: SlotBatch,
    channel: ChannelModel,
    position_xy_m,
    velocity_m_s,
    t_ref_s: float,
    *,
    model_motion: bool = True,
    estimate_tx_power: bool = False,
) -> np.ndarray:
    """Fisher information of the slots about (x, y[, vx, vy][, beta]) at t_ref_s (P x P)."""
    theta = list(np.asarray(position_xy_m, float))
    if model_motion:
        theta += list(np.asarray(velocity_m_s, float))
    if estimate_tx_power:
        theta.append(0.0)
    tau = slots.t_s - t_ref_s
    weight = np.maximum(slots.n_samples, 1) / channel.log_range_sigma**2
    return fisher_information(np.array(theta), tau, slots.xyz_m[:, :2], slots.xyz_m[:, 2], weight,
                              model_motion, estimate_tx_power)


def prior_information(channel: ChannelModel, *, max_speed_m_s: float, model_motion: bool = True,
                      estimate_tx_power: bool = False) -> np.ndarray:
    """The estimator's prior information matrix (same parameter order as data_information)."""
    p = 2 + 2 * model_motion + estimate_tx_power
    j = np.zeros((p, p))
    j[0, 0] = j[1, 1] = POSITION_PRIOR_SIGMA_M**-2
    if model_motion:
        j[2, 2] = j[3, 3] = (max(max_speed_m_s, 1e-3) * VELOCITY_PRIOR_FRACTION) ** -2
    if estimate_tx_power:
        j[-1, -1] = (TX_PRIOR_SIGMA_DB * channel.nepers_per_db) ** -2
    return j


def position_rmse_bound_m(information: np.ndarray) -> float:
    """sqrt(trace of the position block of information^-1) [m]; inf when singular."""
    try:
        cov = np.linalg.inv(0.5 * (information + information.T))
    except np.linalg.LinAlgError:
        return math.inf
    v = cov[0, 0] + cov[1, 1]
    return float(math.sqrt(v)) if v > 0 else math.inf
