"""Where the vehicle was when it heard each slot: positions from a flight log, slots as CSV.

A ``.tlog`` (what the ground station or the companion recorded) gives GLOBAL_POSITION_INT in the
autopilot's boot clock and SYSTEM_TIME, which pairs that clock with UNIX time. Positions are put on
the UNIX clock from the first SYSTEM_TIME that has a UNIX time (as the simulated companion does;
without one, the log's own receive stamps are used) and interpolated linearly at each slot's start.
Slots outside the flown time, or in a gap between reports longer than ``max_gap_s``, are dropped:
nothing is invented where the vehicle's position is unknown.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import FileFormatError
from .aggregate import Entries, format_mac
from .frames import RADIO_NAMES

MAX_GAP_S = 1.0


@dataclass(frozen=True)
class Track:
    """One vehicle's positions on the UNIX clock, in time order."""

    vehicle: int
    t_s: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    alt_m: np.ndarray  # height above home

    def at(self, t_s: np.ndarray, max_gap_s: float = MAX_GAP_S) -> tuple[np.ndarray, np.ndarray]:
        """(ok mask, (K, 3) lat/lon/alt) at the times ``t_s``."""
        t = self.t_s
        i = np.searchsorted(t, t_s, side="right")
        ok = (i > 0) & (i < len(t))
        i = np.clip(i, 1, max(len(t) - 1, 1))
        t0, t1 = t[i - 1], t[i]
        ok &= (t1 - t0) <= max_gap_s
        w = np.where(t1 > t0, (t_s - t0) / np.where(t1 > t0, t1 - t0, 1.0), 0.0)
        out = np.empty((len(t_s), 3))
        for k, col in enumerate((self.lat_deg, self.lon_deg, self.alt_m)):
            out[:, k] = col[i - 1] + w * (col[i] - col[i - 1])
        return ok, out


def read_tracks(path: str | Path) -> dict[int, Track]:
    """Each autopilot's track in a ``.tlog`` (component 1's GLOBAL_POSITION_INT). Raises
    FileFormatError when the file is missing or holds no position."""
    from ..link.tlog import iter_tlog

    p = Path(path)
    if not p.is_file():
        raise FileFormatError("flight log not found", path=str(p))
    anchors: dict[int, tuple[float, float]] = {}  # sysid -> (unix_s, boot_s) from SYSTEM_TIME
    rows: dict[int, list] = {}
    for t_us, m in iter_tlog(p):
        kind = m.get_type()
        sysid = m.get_srcSystem()
        if kind == "SYSTEM_TIME" and m.time_unix_usec > 0 and sysid not in anchors:
            anchors[sysid] = (m.time_unix_usec / 1e6, m.time_boot_ms / 1e3)
        elif kind == "GLOBAL_POSITION_INT" and m.get_srcComponent() == 1:
            rows.setdefault(sysid, []).append((t_us / 1e6, m.time_boot_ms / 1e3, m.lat / 1e7, m.lon / 1e7,
                                               m.relative_alt / 1e3))
    if not rows:
        raise FileFormatError("holds no GLOBAL_POSITION_INT: no vehicle positions to place the slots", path=str(p))
    tracks = {}
    for sysid, r in rows.items():
        a = np.array(r)
        if sysid in anchors:
            unix0, boot0 = anchors[sysid]
            t = unix0 + (a[:, 1] - boot0)
        else:
            t = a[:, 0]
        order = np.argsort(t, kind="stable")
        tracks[sysid] = Track(sysid, t[order], a[order, 2], a[order, 3], a[order, 4])
    return tracks


def slots_csv(entries: Entries, track: Track, *, max_gap_s: float = MAX_GAP_S) -> tuple[str, int]:
    """Slot CSV text (``uavloc localize`` input) of the entries heard along ``track``, and the
    number of entries dropped because the vehicle's position at their time is unknown. ``t_s``
    counts from the whole UNIX second of the first kept slot (stated in a comment line);
    ``emitter_id`` is the address, as the ground takes it from UAVLOC_RSSI_BATCH2."""
    ok, pos = track.at(entries.t_s, max_gap_s)
    idx = np.flatnonzero(ok)
    epoch = math.floor(entries.t_s[idx[0]]) if len(idx) else 0
    lines = [f"# uavloc sense: t_s counts from UNIX time {epoch} s",
             "t_s,vehicle_id,lat_deg,lon_deg,alt_m,emitter_id,rssi_dbm,n_samples,address,fingerprint,channel,radio"]
    for k in idx.tolist():
        a = int(entries.address[k])
        lines.append(f"{entries.t_s[k] - epoch:.3f},{track.vehicle},{pos[k, 0]:.8f},{pos[k, 1]:.8f},{pos[k, 2]:.2f},"
                     f"{a},{entries.rssi_dbm[k]:.2f},{entries.n_frames[k]},{format_mac(a)},"
                     f"{int(entries.fingerprint[k])},{entries.channel[k]},{RADIO_NAMES[entries.radio[k]]}")
    return "\n".join(lines) + "\n", int(len(entries) - len(idx))
