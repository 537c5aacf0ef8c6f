"""What the daemon does with each vehicle right after its heartbeat, before the scan: ask for the
telemetry it needs, and find the speed it will really fly.

Streams: stock ArduCopter streams nothing but HEARTBEAT and a few others until a ground station
asks, and PX4 does not send SYSTEM_TIME on the ground-station link unless asked; so the daemon
asks (SET_MESSAGE_INTERVAL) instead of waiting. A vehicle that refuses is named in a warning;
one that never gives its time leaves the mission clock to the ground (Daemon).

Speed: see :mod:`uavloc_gcs.link.params`. The fleet is planned at one speed, the slowest vehicle's
limit (or the scenario's, if lower); RTL (the landing wait) at the slowest return speed.
"""

from __future__ import annotations

import asyncio
import logging
from dataclasses import dataclass

from ..errors import LinkError
from ..link.params import SpeedLimits, raise_speed_limits, speed_limits

log = logging.getLogger(__name__)

async def request_streams(link, sysid: int, flavour) -> list[str]:
    """Ask vehicle ``sysid`` for the link layer's DEFAULT_STREAMS (what vehicle.py reads); return
    the names it refused or did not answer."""
    from ..link import request_streams as ask  # noqa: PLC0415

    try:
        accepted = await ask(link, sysid, flavour)
    except LinkError as exc:
        log.info("vehicle %d: streams not requested: %s", sysid, exc)
        return ["all"]
    return [name for name, ok in accepted.items() if not ok]


@dataclass(frozen=True)
class FleetSpeed:
    mission_m_s: float  # plan the fleet at this speed
    return_m_s: float  # RTL speed of the slowest vehicle
    notes: tuple[str, ...]  # one sentence per vehicle whose speed differs from the scenario's


async def fleet_speed(vehicles: list[tuple[int, object, object]], wanted_m_s: float, *,
                      consent: bool) -> FleetSpeed:
    """``vehicles``: [(system id, link, link.Flavour)]. With ``consent`` the speed parameters are
    set to ``wanted_m_s`` first (the operator's ``[link] set_speed_params``)."""

    async def one(sysid, link, flavour) -> SpeedLimits:
        if consent:
            return await raise_speed_limits(link, sysid, flavour, wanted_m_s)
        return await speed_limits(link, sysid, flavour)

    limits = await asyncio.gather(*(one(*v) for v in vehicles))
    notes = []
    for (sysid, _, _), lim in zip(vehicles, limits):
        if lim.max_m_s is None:
            notes.append(f"vehicle {sysid} did not give its speed limits; planning with {wanted_m_s:g} m/s")
        elif lim.mission_speed(wanted_m_s) < wanted_m_s:
            how = ("setting them was refused or clamped" if consent else
                   "set [link] set_speed_params = true to let the daemon raise them")
            notes.append(f"vehicle {sysid} flies at most {lim.max_m_s:g} m/s ({lim.source}), not the scenario's "
                         f"{wanted_m_s:g} m/s; planning with the real speed ({how})")
    mission = min((lim.mission_speed(wanted_m_s) for lim in limits), default=wanted_m_s)
    ret = min((lim.return_speed(wanted_m_s) for lim in limits), default=wanted_m_s)
    return FleetSpeed(mission, ret, tuple(notes))
