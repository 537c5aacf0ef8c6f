"""The autopilot's clock and track, as the companion learns them over MAVLink (pure, no I/O).

Frames are stamped by the companion's kernel (libpcap: CLOCK_REALTIME), positions by the autopilot
(GLOBAL_POSITION_INT.time_boot_ms). The RSSI entries must carry the autopilot's time, so:

- TIMESYNC (MAVLink's time-synchronisation exchange): the companion sends ``tc1 = 0, ts1 = its
  monotonic ns``; the autopilot answers ``tc1 = its boot ns, ts1`` echoed. With the round trip
  ``rtt = now - ts1`` the offset ``autopilot_boot - companion_monotonic`` is
  ``tc1 - (ts1 + now) / 2``, within ``rtt / 2``. The estimate with the smallest round trip of the
  last :data:`WINDOW` replies is kept (the same rule as MAVROS and PX4's own timesync);
- SYSTEM_TIME pairs the autopilot's boot clock with UNIX time (GPS time once it has a fix): the
  first one with a UNIX time anchors ``unix = anchor_unix + (boot - anchor_boot)``, as in
  ``sim_link.vehicles.companion`` (re-anchoring on each would squeeze a sped-up SITL's track);
- without any TIMESYNC reply, SYSTEM_TIME's arrival gives a cruder offset (biased by the one-way
  link delay), used until a TIMESYNC reply arrives.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np

WINDOW = 16
MAX_GAP_S = 1.0


@dataclass
class AutopilotClock:
    """Maps companion time to the autopilot's UNIX time."""

    offset_s: float | None = None  # autopilot boot - companion monotonic [s]
    rtt_s: float | None = None  # round trip of the kept TIMESYNC estimate; None: from SYSTEM_TIME
    anchor: tuple[float, float] | None = None  # (unix_s, boot_s) from the first SYSTEM_TIME
    _samples: deque = field(default_factory=lambda: deque(maxlen=WINDOW))

    def on_timesync(self, tc1_ns: int, ts1_ns: int, now_mono_s: float) -> None:
        """An autopilot's TIMESYNC reply, received at companion monotonic ``now_mono_s``."""
        sent_s = ts1_ns / 1e9
        rtt = now_mono_s - sent_s
        if rtt < 0 or rtt > 10.0:
            return  # not a reply to one of ours
        self._samples.append((rtt, tc1_ns / 1e9 - (sent_s + now_mono_s) / 2.0))
        self.rtt_s, self.offset_s = min(self._samples)

    def on_system_time(self, time_unix_usec: int, time_boot_ms: int, now_mono_s: float) -> None:
        if time_unix_usec > 0 and self.anchor is None:
            self.anchor = (time_unix_usec / 1e6, time_boot_ms / 1e3)
        if self.rtt_s is None:  # no TIMESYNC yet: the arrival time, one link delay late
            self.offset_s = time_boot_ms / 1e3 - now_mono_s

    @property
    def ready(self) -> bool:
        return self.offset_s is not None and self.anchor is not None

    def boot_to_unix(self, boot_s):
        unix0, boot0 = self.anchor
        return unix0 + (np.asarray(boot_s, dtype=float) - boot0)

    def companion_to_unix(self, mono_s):
        """Companion monotonic seconds -> autopilot UNIX seconds."""
        return self.boot_to_unix(np.asarray(mono_s, dtype=float) + self.offset_s)


@dataclass
class TrackBuffer:
    """Recent positions on the autopilot's UNIX clock: (t, lat, lon, rel_alt_m), time ordered."""

    horizon_s: float = 30.0
    _rows: deque = field(default_factory=deque)

    def add(self, t_unix_s: float, lat_deg: float, lon_deg: float, alt_m: float) -> None:
        if self._rows and t_unix_s <= self._rows[-1][0]:
            return  # a repeated or older report
        self._rows.append((t_unix_s, lat_deg, lon_deg, alt_m))
        while self._rows and self._rows[0][0] < t_unix_s - self.horizon_s:
            self._rows.popleft()

    @property
    def last_t(self) -> float | None:
        return self._rows[-1][0] if self._rows else None

    def at(self, t_s: np.ndarray, max_gap_s: float = MAX_GAP_S) -> tuple[np.ndarray, np.ndarray]:
        """(ok mask, (K, 3) lat/lon/alt) interpolated at ``t_s``; not ok outside the buffer or in a gap."""
        t_s = np.asarray(t_s, dtype=float)
        if len(self._rows) < 2:
            return np.zeros(len(t_s), dtype=bool), np.zeros((len(t_s), 3))
        a = np.array(self._rows)
        t = a[:, 0]
        i = np.clip(np.searchsorted(t, t_s, side="right"), 1, len(t) - 1)
        t0, t1 = t[i - 1], t[i]
        ok = (t_s >= t[0]) & (t_s <= t[-1]) & (t1 - t0 <= max_gap_s)
        w = ((t_s - t0) / np.where(t1 > t0, t1 - t0, 1.0))[:, None]
        return ok, a[i - 1, 1:] + w * (a[i, 1:] - a[i - 1, 1:])
