"""Drawing frames through the air-to-ground channel of :mod:`uavloc_gcs.a2g` (``[channel] environment``).

Each vehicle-phone pair is a path with memory. A *unit* is what shares one draw of the path's
state and large-scale shadowing: the frames of one probe burst heard by one vehicle, or one elicited
frame (an on-board access point makes phones answer one frame at a time). For every unit:

- the LoS state: line of sight when Phi(U) < P_LoS(theta), theta the elevation at the unit's first
  frame, U a standard normal;
- the shadowing X = shadow[state] * Z, Z a standard normal;
- U and Z are Gudmundson processes over the units of the pair: between two units
  ``corr = exp(-moved / decorrelation_m)``, moved = the vehicle's distance flown plus the phone's
  distance walked between the units' first frames. Bursts far apart are independent, elicited
  frames a few metres apart nearly share their state and shadowing; marginally every unit is drawn
  from the model exactly.

Every frame adds its own small-scale fading, drawn exactly (Rician in LoS, Rayleigh in NLoS:
``A2GChannel.fading``). Per call, 4 standard normals are drawn per frame (two for the fading, two
innovations used when the frame starts a unit) in the frames' time order, so hearing a track in
pieces gives the same numbers as at once; a burst cut by a piece boundary keeps its draw (the pair
remembers its last unit).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uavloc_gcs.a2g import LOS, NLOS, A2GChannel

from .channel import _ar1

_NO_UNIT = -2  # a pair that has no unit yet (burst ids are >= 0; elicited frames are -1)


@dataclass
class PathMemory:
    """One vehicle's memory of its paths to the S phones: the last unit of each pair."""

    key: np.ndarray  # (S,) burst id of the last unit (-1 elicited, _NO_UNIT none)
    z: np.ndarray  # (S,) its standard-normal shadowing
    u: np.ndarray  # (S,) its standard-normal LoS latent
    los: np.ndarray  # (S,) bool, its state
    odometer_m: np.ndarray  # (S,) the vehicle's distance flown at its first frame
    xy_m: np.ndarray  # (S, 2) the phone's position at its first frame

    @staticmethod
    def empty(n_people: int) -> "PathMemory":
        return PathMemory(np.full(n_people, _NO_UNIT), np.zeros(n_people), np.zeros(n_people),
                          np.zeros(n_people, bool), np.zeros(n_people), np.zeros((n_people, 2)))


def draw_rssi_dbm(channel: A2GChannel, memory: PathMemory, rng: np.random.Generator, person: np.ndarray,
                  burst: np.ndarray, odometer_m: np.ndarray, person_xy_m: np.ndarray, horizontal_m: np.ndarray,
                  height_m: np.ndarray, tx_offset_db: np.ndarray) -> np.ndarray:
    """RSSI [dBm] of F frames in time order, as one vehicle receives them: ``person`` (F,) sender,
    ``burst`` (F,) the sender's burst index (-1 for an elicited frame), ``odometer_m`` (F,) the
    vehicle's distance flown at each frame, ``person_xy_m`` (F, 2) the sender's position,
    ``horizontal_m`` / ``height_m`` (F,) the geometry, ``tx_offset_db`` (F,) the sender's transmit
    offset. Updates ``memory``; consumes 4F standard normals."""
    f = len(person)
    normals = rng.standard_normal((f, 4))
    if f == 0:
        return np.zeros(0)
    env = channel.environment
    d3 = np.hypot(horizontal_m, height_m)
    p_los = channel.los_probability(horizontal_m, height_m)
    excess, shadow = channel.excess_db, channel.shadow_db
    fades = [channel.fading(LOS), channel.fading(NLOS)]
    out = np.empty(f)
    for i in np.unique(person):
        rows = np.nonzero(person == i)[0]
        b = burst[rows]
        prev_key = np.concatenate([[memory.key[i]], b[:-1]])
        new = (b < 0) | (b != prev_key)  # a frame that starts a unit
        starts = rows[new]
        z_u = np.empty(len(rows))
        u_u = np.empty(len(rows))
        los_u = np.empty(len(rows), bool)
        if len(starts):
            odo, xy = odometer_m[starts], person_xy_m[starts]
            first_ever = memory.key[i] == _NO_UNIT
            prev_odo = np.concatenate([[memory.odometer_m[i]], odo[:-1]])
            prev_xy = np.vstack([memory.xy_m[i], xy[:-1]])
            moved = np.maximum(odo - prev_odo, 0.0) + np.linalg.norm(xy - prev_xy, axis=1)
            log_rho = -moved / env.decorrelation_m
            if first_ever:
                log_rho[0] = -np.inf  # the pair's first unit is a fresh draw
            scale = np.sqrt(-np.expm1(2.0 * np.maximum(log_rho, -50.0)))
            innov = scale[:, None] * normals[starts, 2:]
            x0 = np.array([memory.z[i], memory.u[i]])
            if first_ever:
                x0 = np.zeros(2)
            zu = _ar1(x0, np.repeat(np.maximum(log_rho, -50.0)[:, None], 2, axis=1), innov)
            unit_los = _ndtr(zu[:, 1]) < p_los[starts]
        # map units to frames: index of the unit each frame belongs to (-1: the remembered unit)
        unit = np.cumsum(new) - 1
        carried = unit < 0
        if np.any(carried):
            z_u[carried], u_u[carried], los_u[carried] = memory.z[i], memory.u[i], memory.los[i]
        if len(starts):
            z_u[~carried], u_u[~carried] = zu[unit[~carried], 0], zu[unit[~carried], 1]
            los_u[~carried] = unit_los[unit[~carried]]
        state = np.where(los_u, LOS, NLOS)
        fade = np.where(los_u, fades[LOS].sample(normals[rows, :2]), fades[NLOS].sample(normals[rows, :2]))
        out[rows] = channel.spreading_dbm(d3[rows], tx_offset_db[rows]) - excess[state] + shadow[state] * z_u + fade
        if len(starts):
            memory.odometer_m[i], memory.xy_m[i] = odometer_m[starts[-1]], person_xy_m[starts[-1]]
        memory.key[i] = b[-1]
        memory.z[i], memory.u[i], memory.los[i] = z_u[-1], u_u[-1], los_u[-1]
    return out


def _ndtr(x):
    from scipy.special import ndtr

    return ndtr(x)
