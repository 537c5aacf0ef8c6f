"""Which clock a time is in (issue 42 item 7).

The search keeps time as *mission seconds*: the vehicles' own clock (SYSTEM_TIME, advanced by
their boot clock) since the search began. Real vehicles' clocks are GPS time, so mission time
plus the epoch is UTC. A simulator running faster than real time (SITL ``--speedup 5``, the fake
fleet at 20x) advances the vehicles' clock that much faster: read as UTC, "positions at 17:55 to
18:17 UTC" came out of a demo drawn at 17:47 UTC.

:class:`MissionClock` maps mission seconds to UTC either way: from the vehicles' clock when it ran
at the host's rate (real vehicles, GPS time: right even on a field laptop whose own clock is off),
else through anchors the daemon records as it runs -- (mission s, this computer's UNIX s) pairs --
so a time is the UTC moment, by this computer's clock, at which the simulated vehicles were there.
Its ``label`` says which.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import datetime, timezone
from typing import Sequence

import numpy as np

# The vehicles' clock counts as real time when it ran within this fraction of the host's rate
# (real vehicles: GPS against NTP, well under 1e-4; a simulator's speed-up is 2x or more, and PX4
# lockstep under load runs slower than its factor but still far from 1).
REAL_TIME_TOLERANCE = 0.05
MIN_ANCHOR_SPAN_S = 5.0  # host seconds of anchors before their rate is believed


@dataclass(frozen=True)
class MissionClock:
    """Mission seconds to UNIX time. ``epoch_unix_s``: the vehicles' clock at mission time 0;
    ``anchors``: (mission s, host UNIX s) pairs in time order (the daemon's, every few seconds)."""

    epoch_unix_s: float | None
    anchors: tuple[tuple[float, float], ...] = ()

    @classmethod
    def of(cls, epoch_unix_s: float | None, anchors: Sequence[Sequence[float]] = ()) -> "MissionClock":
        pts = sorted((float(t), float(u)) for t, u in anchors if math.isfinite(t) and math.isfinite(u))
        return cls(None if epoch_unix_s is None else float(epoch_unix_s), tuple(pts))

    @property
    def rate(self) -> float:
        """Mission seconds per host second over the anchors (1.0 until they span MIN_ANCHOR_SPAN_S)."""
        if len(self.anchors) < 2 or self.anchors[-1][1] - self.anchors[0][1] < MIN_ANCHOR_SPAN_S:
            return 1.0
        t = np.array([a[0] for a in self.anchors])
        u = np.array([a[1] for a in self.anchors])
        return float(np.polyfit(u, t, 1)[0])

    @property
    def simulated(self) -> bool:
        """The vehicles' clock did not run at the host's rate: a simulator's speed-up."""
        return abs(self.rate - 1.0) > REAL_TIME_TOLERANCE

    @property
    def label(self) -> str:
        """Which clock the UTC times are: the vehicles' (GPS) or this computer's."""
        if not self.simulated:
            return "UTC"
        return f"UTC by this computer's clock (the simulated vehicles' clock ran {self.rate:.1f}x)"

    def unix_s(self, t_s: float) -> float:
        """UNIX time of mission time ``t_s`` (NaN when unknown)."""
        if t_s is None or not math.isfinite(t_s):
            return math.nan
        if not self.simulated:
            return self.epoch_unix_s + t_s if self.epoch_unix_s is not None else math.nan
        t = np.array([a[0] for a in self.anchors])
        u = np.array([a[1] for a in self.anchors])
        if t[0] <= t_s <= t[-1]:
            return float(np.interp(t_s, t, u))
        rate = self.rate  # beyond the anchors: at the rate they show
        k = 0 if t_s < t[0] else -1
        return float(u[k] + (t_s - t[k]) / rate)


def utc_text(clock, t_s: float) -> str:
    """ISO 8601 UTC ('2026-11-23T22:10:05.3Z') of mission time ``t_s``; '' when unknown.
    ``clock``: a :class:`MissionClock`, or (as before issue 42) the epoch's UNIX time, taken as the
    vehicles' real-time clock."""
    if not isinstance(clock, MissionClock):
        clock = MissionClock.of(clock)
    unix = clock.unix_s(t_s)
    if not math.isfinite(unix):
        return ""
    stamp = datetime.fromtimestamp(unix, tz=timezone.utc)
    return stamp.strftime("%Y-%m-%dT%H:%M:%S.") + f"{stamp.microsecond // 100000}Z"


def clock_label(clock) -> str:
    """``clock``'s label ('UTC' for a bare epoch)."""
    return clock.label if isinstance(clock, MissionClock) else "UTC"
