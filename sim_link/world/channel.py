"""The simulated radio channel: log-distance path loss with log-normal shadowing (SPEC §1).

One RSSI sample of a phone at 3-D distance d is
``P = P0 + tx_offset - 10 eta log10(d / d0) + Psi`` [dBm] with Psi ~ N(0, sigma^2) [dB].

Two shadowing models:

- i.i.d. (the paper): every sample draws its own Psi;
- correlated (``simulation.correlated_shadowing``): Psi of one vehicle-phone pair is a Gudmundson
  process, i.e. exponentially correlated over the distance moved,
  ``corr = exp(-Δs / shadowing_decorrelation_m)``, where Δs is the distance the vehicle flew plus the
  distance the person walked between two samples. Samples of one slot are spaced evenly over the
  distance moved since the previous slot. Marginally Psi is still N(0, sigma^2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Largest span of log-correlation handled in one closed-form block (exp(600) is finite).
_LOG_SPAN = 600.0


@dataclass(frozen=True)
class ChannelParams:
    reference_power_dbm: float = -40.0
    path_loss_exponent: float = 2.0
    shadowing_sigma_db: float = 4.0
    reference_distance_m: float = 1.0
    samples_per_slot: int = 10
    correlated: bool = False
    decorrelation_m: float = 20.0

    @staticmethod
    def from_scenario(sc) -> "ChannelParams":
        ch, sim = sc.channel, sc.simulation
        return ChannelParams(
            ch.reference_power_dbm, ch.path_loss_exponent, ch.shadowing_sigma_db, ch.reference_distance_m,
            ch.samples_per_slot, sim.correlated_shadowing, sim.shadowing_decorrelation_m,
        )

    def median_rssi_dbm(self, d_m) -> np.ndarray:
        """RSSI without shadowing at 3-D distance d_m [dBm]."""
        d = np.maximum(np.asarray(d_m, dtype=float), 1e-3)
        return self.reference_power_dbm - 10.0 * self.path_loss_exponent * np.log10(d / self.reference_distance_m)


@dataclass
class ShadowingState:
    """Per-vehicle shadowing memory (correlated model only): last sample of every phone."""

    rng: np.random.Generator
    last_t_s: float = -np.inf
    last_xyz_m: np.ndarray | None = None  # (3,)
    last_people_xy_m: np.ndarray | None = None  # (S, 2)
    psi_db: np.ndarray | None = None  # (S,) last shadowing sample
    # frame-by-frame worlds (probe bursts, a receiver threshold): distance flown so far and, per
    # phone, the odometer and the phone's position at its last frame heard by this vehicle
    odometer_m: float = 0.0
    pair_odometer_m: np.ndarray | None = None  # (S,)
    pair_people_xy_m: np.ndarray | None = None  # (S, 2)


def draw_shadowing_db(params: ChannelParams, state: ShadowingState, moved_m: np.ndarray) -> np.ndarray:
    """Shadowing samples (N, K, S) [dB] for N slots of K samples and S phones.

    ``moved_m`` (N, S) is the distance moved (vehicle + person) since the previous slot of this
    vehicle (0 for its first slot). Consumes exactly N*K*S standard normals (plus S on the first
    call of a correlated channel), so a track heard slot by slot gives the same numbers as heard at once.
    """
    n, s = moved_m.shape
    k = params.samples_per_slot
    sigma = params.shadowing_sigma_db
    if params.correlated and state.psi_db is None:
        state.psi_db = sigma * state.rng.standard_normal(s)
    z = state.rng.standard_normal((n, k, s))
    if not params.correlated:
        return sigma * z
    step = np.repeat(moved_m / k, k, axis=0)  # (N*K, S) distance between consecutive samples
    log_rho = -step / params.decorrelation_m
    innov = sigma * np.sqrt(-np.expm1(2.0 * log_rho)) * z.reshape(n * k, s)
    psi = _ar1(state.psi_db, log_rho, innov)
    state.psi_db = psi[-1].copy()
    return psi.reshape(n, k, s)


def draw_frame_shadowing_db(params: ChannelParams, state: ShadowingState, person: np.ndarray,
                            odometer_m: np.ndarray, person_xy_m: np.ndarray, n_people: int) -> np.ndarray:
    """Shadowing [dB] of F frames in time order: ``person`` (F,) sender, ``odometer_m`` (F,) the
    vehicle's distance flown at each frame, ``person_xy_m`` (F, 2) the sender's position.

    i.i.d.: one N(0, sigma^2) per frame. Correlated: one Gudmundson process per vehicle-phone pair,
    advanced by the distance the vehicle flew plus the distance the phone moved since that pair's
    previous frame. Consumes F standard normals (plus S on the first call of a correlated channel),
    so frames heard in pieces give the same numbers as heard at once.
    """
    sigma = params.shadowing_sigma_db
    if params.correlated and state.psi_db is None:
        state.psi_db = sigma * state.rng.standard_normal(n_people)
    z = state.rng.standard_normal(len(person))
    if not params.correlated:
        return sigma * z
    if state.pair_odometer_m is None:
        state.pair_odometer_m = np.zeros(n_people)
    out = np.empty(len(person))
    for i in np.unique(person):
        rows = np.nonzero(person == i)[0]
        odo, xy = odometer_m[rows], person_xy_m[rows]
        prev_xy = xy[0] if state.pair_people_xy_m is None or np.isnan(state.pair_people_xy_m[i, 0]) \
            else state.pair_people_xy_m[i]
        walked = np.linalg.norm(np.diff(np.vstack([prev_xy, xy]), axis=0), axis=1)
        moved = np.diff(np.concatenate([[state.pair_odometer_m[i]], odo])) + walked
        log_rho = -np.maximum(moved, 0.0)[:, None] / params.decorrelation_m
        innov = sigma * np.sqrt(-np.expm1(2.0 * log_rho)) * z[rows, None]
        psi = _ar1(state.psi_db[i : i + 1], log_rho, innov)[:, 0]
        out[rows] = psi
        state.psi_db[i] = psi[-1]
        state.pair_odometer_m[i] = odo[-1]
        if state.pair_people_xy_m is None:
            state.pair_people_xy_m = np.full((n_people, 2), np.nan)
        state.pair_people_xy_m[i] = xy[-1]
    return out


def _ar1(x0: np.ndarray, log_rho: np.ndarray, innov: np.ndarray) -> np.ndarray:
    """x_i = rho_i x_{i-1} + innov_i for all columns at once, in closed form per block:
    x_i = exp(L_i) (x0 + sum_{j<=i} exp(-L_j) innov_j), L = cumsum(log rho)."""
    m = len(log_rho)
    log_rho = np.maximum(log_rho, -50.0)  # rho < 2e-22 is zero for all purposes; keeps blocks long
    out = np.empty_like(innov)
    start, x = 0, x0
    while start < m:
        L = np.cumsum(log_rho[start:], axis=0)
        over = np.nonzero(L.min(axis=1) < -_LOG_SPAN)[0]
        stop = m if over.size == 0 else start + max(int(over[0]), 1)
        L = L[: stop - start]
        acc = x + np.cumsum(np.exp(-L) * innov[start:stop], axis=0)
        out[start:stop] = np.exp(L) * acc
        x = out[stop - 1]
        start = stop
    return out
