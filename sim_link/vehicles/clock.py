"""The simulated clock of a fleet: t = 0 at start, advancing ``speedup`` times real time -- or
slower, when the machine cannot compute the simulation that fast (:meth:`SimClock.slip`).

Mission time ``t_s`` is what the world, the physics and every time stamp use; the UNIX time a
vehicle reports (SYSTEM_TIME, UAVLOC_RSSI_BATCH.time_usec) is ``epoch_unix_s + t_s``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable


@dataclass
class SimClock:
    speedup: float = 20.0
    epoch_unix_s: float = field(default_factory=lambda: float(int(time.time())))
    wall: Callable[[], float] = time.monotonic
    _wall0: float | None = None
    _t0_s: float = 0.0

    def __post_init__(self) -> None:
        if not self.speedup > 0:
            raise ValueError(f"speedup must be > 0, got {self.speedup}")

    def start(self) -> None:
        self._wall0 = self.wall()

    def now_s(self) -> float:
        """Mission time [s] (0 before :meth:`start`)."""
        if self._wall0 is None:
            return self._t0_s
        return self._t0_s + (self.wall() - self._wall0) * self.speedup

    def unix_s(self) -> float:
        return self.epoch_unix_s + self.now_s()

    def slip(self, sim_s: float) -> None:
        """Fall back ``sim_s`` of mission time for good: what the simulation could not compute in
        time is not skipped but happens later (the clock runs slower than ``speedup`` for a while)."""
        if sim_s > 0:
            self._t0_s -= float(sim_s)

    def sim_to_wall_s(self, sim_s: float) -> float:
        """How long ``sim_s`` of mission time takes in real time."""
        return sim_s / self.speedup
