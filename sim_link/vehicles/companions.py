"""The companions of a fleet of real autopilots: one simulated world, one world clock.

One :class:`~sim_link.vehicles.companion.CompanionEmulator` per vehicle, all asking the same
:class:`sim_link.world.World` and all on one time origin: the first UNIX time any of them computes
from its autopilot's clock is mission time 0 for every one. Companions started separately (one
``uavloc sim --companion`` per vehicle) each take their own first position as t = 0, so the same
phone's bursts fall at different moments for different vehicles. Used by ``uavloc sitl`` and the
SITL tests.
"""

from __future__ import annotations

import asyncio

from .companion import CompanionEmulator


class _Clock:
    epoch_unix_s: float | None = None


class _Member(CompanionEmulator):
    def __init__(self, *args, clock: _Clock, **kw):
        super().__init__(*args, **kw)
        self._clock = clock

    def _on_position(self, msg) -> None:
        if self.epoch_unix_s is None:
            if self._clock.epoch_unix_s is None:
                self._clock.epoch_unix_s = self._unix_s(int(msg.time_boot_ms))
            self.epoch_unix_s = self._clock.epoch_unix_s
        super()._on_position(msg)


class CompanionGroup:
    """``links``: per vehicle, (where its companion talks to the autopilot, where it sends RSSI
    beside the autopilot or None)."""

    def __init__(self, scenario, links: list[tuple[str, str | None]], *, seed: int | None = None,
                 signing_key: bytes | None = None):
        from ..world import World

        self.world = World(scenario, seed=scenario.simulation.seed if seed is None else seed)
        self.clock = _Clock()
        self.emulators = [_Member(scenario, url, world=self.world, rssi_url=rssi, signing_key=signing_key,
                                  clock=self.clock) for url, rssi in links]

    @property
    def epoch_unix_s(self) -> float | None:
        return self.clock.epoch_unix_s

    async def run(self, stop: asyncio.Event) -> None:
        await asyncio.gather(*(e.run(stop) for e in self.emulators))
