"""Cramer-Rao bounds for the benchmark and the planner (SPEC §3.2).

``J = sum_i (n_i / s^2) grad ln d_i grad ln d_i^T`` over independent samples, evaluated at a
known state (the truth in simulation), plus the estimator's prior information (velocity prior
sigma_v = 0.6 v_max per axis, transmit-offset prior). Averaging J over Monte Carlo runs and
inverting gives the Bayesian (Van Trees) bound on the position error at ``t_ref_s``.

Under a receiver threshold (``ChannelModel.sensitivity_dbm``, the field world) the same model as
the estimator's (:mod:`.fit`): a heard slot of n frames holds n times the truncated normal's
information about m = ln d - beta (``model.truncated_information_factor``), and
:func:`censored_information` adds the silences' curvature. :func:`frames_information` is the
complete-data information of frames the phone sent, heard or not (the Tobit information per frame):
the bound of any estimator that knows when the phone sent, what ``bench localize --emission bursts``
inverts.
"""

from __future__ import annotations

import math

import numpy as np

from ..observations import SlotBatch
from .estimate import TX_PRIOR_SIGMA_DB
from .fit import POSITION_PRIOR_SIGMA_M, VELOCITY_PRIOR_FRACTION
from .model import (
    ChannelModel,
    censored_curvature,
    fisher_information,
    geometry,
    log_range_jacobian,
    tobit_information_factor,
    truncated_information_factor,
)


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
    if channel.sensitivity_dbm is not None:
        weight = weight * truncated_information_factor(_z(channel, np.array(theta), tau, slots.xyz_m, model_motion))
    return fisher_information(np.array(theta), tau, slots.xyz_m[:, :2], slots.xyz_m[:, 2], weight,
                              model_motion, estimate_tx_power)


def _z(channel: ChannelModel, theta: np.ndarray, tau: np.ndarray, xyz_m: np.ndarray, moving: bool) -> np.ndarray:
    """(S - mu) / sigma at the nominal power (beta = 0) of rows at vehicle positions xyz_m."""
    _, d2 = geometry(theta, tau, np.asarray(xyz_m)[:, :2], np.asarray(xyz_m)[:, 2], moving)
    return (0.5 * np.log(d2) - channel.threshold_log_range) / channel.log_range_sigma


def _rows_information(channel, position_xy_m, velocity_m_s, t_ref_s, t_s, xyz_m, factor, model_motion,
                      estimate_tx_power) -> np.ndarray:
    theta = list(np.asarray(position_xy_m, float)) + (list(np.asarray(velocity_m_s, float)) if model_motion else [])
    theta = np.array(theta + ([0.0] if estimate_tx_power else []))
    tau = np.asarray(t_s, float) - t_ref_s
    xyz = np.asarray(xyz_m, float).reshape(-1, 3)
    z = _z(channel, theta, tau, xyz, model_motion)
    g, d2 = geometry(theta, tau, xyz[:, :2], xyz[:, 2], model_motion)
    jac = log_range_jacobian(g, d2, tau, model_motion, estimate_tx_power)
    w = factor(z) / channel.log_range_sigma**2
    return (jac * w[:, None]).T @ jac


def censored_information(censored, channel: ChannelModel, position_xy_m, velocity_m_s, t_ref_s: float, *,
                         model_motion: bool = True, estimate_tx_power: bool = False) -> np.ndarray:
    """The silences' (:class:`.evidence.Censored`) curvature at the state, k_j lambda(z)(z + lambda(z)) /
    s^2 per row: what the estimator adds to its Laplace precision (P x P)."""
    k = np.asarray(censored.frames, float)
    return _rows_information(channel, position_xy_m, velocity_m_s, t_ref_s, censored.t_s, censored.xyz_m,
                             lambda z: k * censored_curvature(z), model_motion, estimate_tx_power)


def frames_information(t_s, xyz_m, channel: ChannelModel, position_xy_m, velocity_m_s, t_ref_s: float, *,
                       model_motion: bool = True, estimate_tx_power: bool = False) -> np.ndarray:
    """Expected Fisher information of frames the phone sent at times t_s (F,) while a receiver was
    at xyz_m (F, 3), each heard (its RSSI above the threshold) or not: the Tobit information
    (``model.tobit_information_factor``) per frame (P x P)."""
    return _rows_information(channel, position_xy_m, velocity_m_s, t_ref_s, t_s, xyz_m, tobit_information_factor,
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
