"""Commands: COMMAND_LONG -> COMMAND_ACK (devguide ``services/command.md``), and the few
commands uavloc sends (mode, arm, takeoff, mission start, set current item, RTL, stream rates).

The sender re-sends a command whose ACK does not arrive, with ``confirmation`` incremented so the
vehicle can tell a re-send from a new command. MAV_RESULT_IN_PROGRESS means "still working": we
keep waiting without re-sending. Anything but ACCEPTED raises CommandError naming the command.
"""

from __future__ import annotations

import logging
import math
import time
from typing import Sequence

from ..dialect import mavlink
from ..errors import CommandError
from .autopilots import Flavour, flavour_for, flavour_named
from .connection import Link

log = logging.getLogger(__name__)

COMMAND_TIMEOUT_S = 1.5  # devguide default timeout (services/mission.md), as QGC/MAVSDK use for commands
COMMAND_RETRIES = 5  # devguide's default retry count
IN_PROGRESS_TIMEOUT_S = 10.0  # how long a command may stay MAV_RESULT_IN_PROGRESS

MAV_RESULT_ACCEPTED = mavlink.MAV_RESULT_ACCEPTED
MAV_RESULT_IN_PROGRESS = mavlink.MAV_RESULT_IN_PROGRESS
MAV_RESULT_UNSUPPORTED = mavlink.MAV_RESULT_UNSUPPORTED
ARM_FORCE_MAGIC = 21196  # param2 of COMPONENT_ARM_DISARM that bypasses pre-arm checks


def command_name(command: int) -> str:
    entry = mavlink.enums["MAV_CMD"].get(command)
    return entry.name if entry is not None else f"MAV_CMD({command})"


def result_name(result: int) -> str:
    entry = mavlink.enums["MAV_RESULT"].get(result)
    return entry.name if entry is not None else f"MAV_RESULT({result})"


async def command_long(link: Link, target_system: int, target_component: int, command: int,
                       params: Sequence[float] = (0, 0, 0, 0, 0, 0, 0), *,
                       timeout_s: float = COMMAND_TIMEOUT_S, retries: int = COMMAND_RETRIES) -> int:
    """Send COMMAND_LONG and return MAV_RESULT_ACCEPTED; raise CommandError on any other result
    or when ``retries`` re-sends (every ``timeout_s``) get no COMMAND_ACK."""
    p = [float(x) for x in params] + [0.0] * (7 - len(params))
    name = command_name(command)
    vehicle = str(target_system)

    def is_ours(m) -> bool:
        return m.command == command and getattr(m, "target_system", 0) in (0, link.mav.srcSystem)

    with link.subscribe("COMMAND_ACK", source_system=target_system, predicate=is_ours) as acks:
        confirmation = 0
        await link.send(link.mav.command_long_encode(target_system, target_component, command, confirmation, *p[:7]))
        in_progress_until = None
        while True:
            try:
                ack = await acks.get(timeout_s)
            except TimeoutError:
                if in_progress_until is not None and time.monotonic() < in_progress_until:
                    continue
                if confirmation >= retries:
                    raise CommandError(f"{name}: no COMMAND_ACK after {retries + 1} tries {timeout_s:g} s apart",
                                       vehicle=vehicle, operation="command") from None
                confirmation += 1
                await link.send(link.mav.command_long_encode(target_system, target_component, command,
                                                             confirmation, *p[:7]))
                continue
            if ack.result == MAV_RESULT_IN_PROGRESS:
                in_progress_until = time.monotonic() + IN_PROGRESS_TIMEOUT_S
                continue
            if ack.result == MAV_RESULT_ACCEPTED:
                log.info("vehicle %s: %s accepted", vehicle, name)
                return MAV_RESULT_ACCEPTED
            err = CommandError(f"{name} refused: {result_name(ack.result)}", vehicle=vehicle, operation="command")
            err.result = ack.result
            raise err


# ---------------------------------------------------------------------------------------------
# The commands uavloc uses


def _flavour(link: Link, target_system: int, autopilot: str | Flavour | None) -> Flavour:
    if isinstance(autopilot, Flavour):
        return autopilot
    if autopilot is not None:
        return flavour_named(autopilot)
    hb = link.heartbeats.get(target_system)
    if hb is None:
        raise CommandError("autopilot type unknown (no HEARTBEAT yet); pass autopilot=",
                           vehicle=str(target_system), operation="set mode")
    return flavour_for(hb.autopilot)


async def set_mode(link: Link, target_system: int, target_component: int, mode_name: str,
                   autopilot: str | Flavour | None = None) -> int:
    """MAV_CMD_DO_SET_MODE with the autopilot's custom mode for ``mode_name`` ("AUTO", "GUIDED",
    "RTL", "LOITER", "LAND"; PX4 names like "AUTO.MISSION" work too)."""
    flavour = _flavour(link, target_system, autopilot)
    hb = link.heartbeats.get(target_system)
    params = flavour.mode_params(mode_name, hb.type if hb is not None else None)
    return await command_long(link, target_system, target_component, mavlink.MAV_CMD_DO_SET_MODE, params)


async def arm(link: Link, target_system: int, target_component: int, *, force: bool = False) -> int:
    return await command_long(link, target_system, target_component, mavlink.MAV_CMD_COMPONENT_ARM_DISARM,
                              (1, ARM_FORCE_MAGIC if force else 0))


async def disarm(link: Link, target_system: int, target_component: int, *, force: bool = False) -> int:
    return await command_long(link, target_system, target_component, mavlink.MAV_CMD_COMPONENT_ARM_DISARM,
                              (0, ARM_FORCE_MAGIC if force else 0))


async def takeoff(link: Link, target_system: int, target_component: int, alt_m: float) -> int:
    """MAV_CMD_NAV_TAKEOFF to ``alt_m`` above home at the current position (lat/lon NaN)."""
    return await command_long(link, target_system, target_component, mavlink.MAV_CMD_NAV_TAKEOFF,
                              (0, 0, 0, math.nan, math.nan, math.nan, alt_m))


async def start_mission(link: Link, target_system: int, target_component: int, first_item: int = 0,
                        last_item: int = 0) -> int:
    """MAV_CMD_MISSION_START (both autopilots switch to their mission mode)."""
    return await command_long(link, target_system, target_component, mavlink.MAV_CMD_MISSION_START,
                              (first_item, last_item))


async def return_to_launch(link: Link, target_system: int, target_component: int) -> int:
    return await command_long(link, target_system, target_component, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH)


async def set_current_item(link: Link, target_system: int, target_component: int, seq: int, *,
                           reset: bool = False) -> int:
    """Make ``seq`` the current mission item without changing mode.

    MAV_CMD_DO_SET_MISSION_CURRENT (ArduPilot since 2021, PX4 since 2026); if the vehicle answers
    UNSUPPORTED, falls back to the legacy MISSION_SET_CURRENT, which has no ACK and is confirmed
    by the MISSION_CURRENT the vehicle broadcasts.
    """
    try:
        return await command_long(link, target_system, target_component, mavlink.MAV_CMD_DO_SET_MISSION_CURRENT,
                                  (seq, 1 if reset else 0))
    except CommandError as err:
        if getattr(err, "result", None) != MAV_RESULT_UNSUPPORTED:
            raise
    # PX4 passes a DO_CHANGE_SPEED at once: reaching the item or a later one confirms it
    with link.subscribe("MISSION_CURRENT", source_system=target_system, predicate=lambda m: m.seq >= seq) as cur:
        for _ in range(COMMAND_RETRIES + 1):
            await link.send(link.mav.mission_set_current_encode(target_system, target_component, seq))
            try:
                await cur.get(COMMAND_TIMEOUT_S)
                return MAV_RESULT_ACCEPTED
            except TimeoutError:
                continue
    raise CommandError(f"MISSION_SET_CURRENT {seq}: vehicle never reported it as current",
                       vehicle=str(target_system), operation="command")


async def set_message_interval(link: Link, target_system: int, target_component: int, message_id: int,
                               interval_s: float) -> int:
    """MAV_CMD_SET_MESSAGE_INTERVAL: stream ``message_id`` every ``interval_s`` (-1: stop)."""
    interval_us = -1 if interval_s < 0 else int(interval_s * 1e6)
    return await command_long(link, target_system, target_component, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL,
                              (message_id, interval_us))
