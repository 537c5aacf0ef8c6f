"""One emitter's slots made ready for the fit: merged per vehicle, in log-range form, with the rows
of the vehicles that listened and heard nothing (for :mod:`.fit`).

:func:`prepare` merges consecutive slots of one vehicle (``MERGE_S``) into observations of known
weight and puts them in the fit's log-range form (:class:`Prepared`); :func:`censored_rows` turns the
listening vehicles' silences (and, with a frames prior, their hearing counts per burst; with a
burst-rate prior, the bursts nobody heard) into the rows the fit adds (:class:`CensoredRows`,
:class:`ExposureRows`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .evidence import Censored, Exposure
from .maneuver import Passes
from .model import ChannelModel

MERGE_S = 0.1  # consecutive slots of one vehicle merged into one observation (see prepare)


@dataclass(frozen=True)
class Prepared:
    """One emitter's slots in estimator form, time-sorted."""

    t_s: np.ndarray
    tau_s: np.ndarray  # t - t_c
    t_c: float  # information-weighted mean time (the fit's reference)
    a_xy: np.ndarray  # vehicle ground position (N, 2)
    h_m: np.ndarray  # vehicle height above the person (N,)
    vehicle: np.ndarray
    y: np.ndarray  # observed ln range at nominal power
    w: np.ndarray  # precision n / s^2
    n_samples: np.ndarray
    center: np.ndarray  # weighted mean vehicle ground position
    # Over terrain (see .terrain_fit): ground(t_s, xy) -> (rise (N,), gradient (N, 2)), how much
    # higher the ground is at the person's position xy (N, 2) at each row's time than where h_m was
    # taken, and its gradient there; the height above the person is h_m - rise. None: the
    # person's height does not depend on where they are.
    ground: object = None


def prepare(slots, channel: ChannelModel, *, merge_s: float = MERGE_S, height_floor: bool = True) -> Prepared:
    """The slots as log-range observations, time-sorted.

    Consecutive slots of one vehicle within ``merge_s`` are merged into one observation (sample-
    weighted mean of ln r, position and time; summed precision). Over 0.1 s a vehicle moves ~2.5 m,
    so ln d changes by ~1e-4 of its curvature term while a slot's noise is ~0.15: the likelihood is
    unchanged to that order and the fit is ~4x cheaper.

    Heights below 0 (a vehicle under the person) are taken as 0 unless ``height_floor`` is False:
    over terrain the fit moves the person on the ground (``Prepared.ground``) and needs the
    heights as they are.
    """
    y_all = channel.log_range(slots.rssi_dbm)
    n_all = np.maximum(slots.n_samples, 1).astype(float)
    order = np.lexsort((slots.t_s, slots.vehicle))
    t, veh, n, y, a = slots.t_s[order], slots.vehicle[order], n_all[order], y_all[order], slots.xyz_m[order]
    if merge_s > 0 and len(t) > 1:
        new = np.concatenate([[True], (veh[1:] != veh[:-1]) | (np.diff(t) > merge_s)])
        # within a run of one vehicle, start a new group every merge_s seconds
        run = np.cumsum(new)
        run_start = t[np.flatnonzero(new)][run - 1]
        group = np.cumsum(np.concatenate([[True], (run[1:] != run[:-1]) |
                                          (np.floor((t[1:] - run_start[1:]) / merge_s) !=
                                           np.floor((t[:-1] - run_start[:-1]) / merge_s))]))
        starts = np.flatnonzero(np.concatenate([[True], group[1:] != group[:-1]]))
        tot = np.add.reduceat(n, starts)
        t = np.add.reduceat(n * t, starts) / tot
        y = np.add.reduceat(n * y, starts) / tot
        a = np.add.reduceat(n[:, None] * a, starts, axis=0) / tot[:, None]
        veh, n = veh[starts], tot
        by_time = np.argsort(t, kind="stable")
        t, y, a, veh, n = t[by_time], y[by_time], a[by_time], veh[by_time], n[by_time]
    w = n / channel.log_range_sigma**2
    t_c = float(np.sum(w * t) / np.sum(w))
    return Prepared(t, t - t_c, t_c, a[:, :2].copy(), np.maximum(a[:, 2], 0.0) if height_floor else a[:, 2].copy(),
                    veh, y, w, n,
                    np.average(a[:, :2], axis=0, weights=w))


@dataclass(frozen=True)
class CensoredRows:
    """Censored observations (:class:`.evidence.Censored`) in the fit's time frame, each with the
    maneuver pass of the nearest observation heard in its burst (-1: none)."""

    t_s: np.ndarray
    tau_s: np.ndarray
    a_xy: np.ndarray
    h_m: np.ndarray
    frames: np.ndarray
    pass_index: np.ndarray
    # the hearing counts' model (Censored.prior set): counts (K,), burst index 0..B-1, ln p(frames)
    heard: np.ndarray | None = None
    burst: np.ndarray | None = None
    log_p: np.ndarray | None = None
    exposure: "ExposureRows | None" = None  # the bursts nobody heard (evidence.Exposure)

    def __len__(self) -> int:
        return len(self.t_s)

    @property
    def n_bursts(self) -> int:
        return int(self.burst.max()) + 1 if self.burst is not None and len(self.burst) else 0

    @property
    def residual_rows(self) -> int:
        """One residual per burst with the counts' model, else one per silence; one for the exposure."""
        return (self.n_bursts if self.log_p is not None else len(self.t_s)) + (self.exposure is not None)


@dataclass(frozen=True)
class ExposureRows:
    """:class:`.evidence.Exposure` in the fit's time frame (rows as in :class:`CensoredRows`)."""

    t_s: np.ndarray
    tau_s: np.ndarray
    a_xy: np.ndarray
    h_m: np.ndarray
    pass_index: np.ndarray
    source: Exposure


def censored_rows(censored: Censored | None, data: Prepared, passes: Passes | None,
                  same_burst_s: float = 5.0) -> CensoredRows | None:
    """``censored`` in the fit's frame (None when empty)."""
    if censored is None or len(censored) == 0:
        return None
    t = np.asarray(censored.t_s, float)
    xyz = np.asarray(censored.xyz_m, float).reshape(-1, 3)

    def pass_index(times: np.ndarray) -> np.ndarray:
        """The pass of the heard slot nearest each time (within ``same_burst_s``), -1 for none."""
        out = np.full(len(times), -1, dtype=int)
        if passes is not None and len(data.t_s):
            k = np.argmin(np.abs(times[:, None] - data.t_s[None, :]), axis=1)
            near = np.abs(data.t_s[k] - times) <= same_burst_s
            out[near] = passes.index[k[near]]
        return out

    index = pass_index(t)
    counts = {}
    if censored.prior is not None:
        counts = dict(heard=np.asarray(censored.heard, float),
                      burst=np.unique(np.asarray(censored.burst, int), return_inverse=True)[1].reshape(-1),
                      log_p=censored.prior.log_p)
        ex = censored.exposure
        if ex is not None and len(ex):
            te = np.asarray(ex.t_s, float)
            xe = np.asarray(ex.xyz_m, float).reshape(-1, 3)
            ie = pass_index(te)
            counts["exposure"] = ExposureRows(te, te - data.t_c, xe[:, :2].copy(), np.maximum(xe[:, 2], 0.0), ie, ex)
    return CensoredRows(t, t - data.t_c, xyz[:, :2].copy(), np.maximum(xyz[:, 2], 0.0),
                        np.maximum(np.asarray(censored.frames, float), 0.0), index, **counts)


