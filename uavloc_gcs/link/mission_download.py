"""Mission download: MISSION_REQUEST_LIST -> MISSION_COUNT, then MISSION_REQUEST_INT(i) ->
MISSION_ITEM_INT(i) for every item, then MISSION_ACK(ACCEPTED) (devguide ``services/mission.md``,
"Download a Mission from the Vehicle").

Every request is re-sent after its timeout (see :mod:`.mission_wire`); items are requested one at
a time and strictly in order, which is what PX4 requires (it aborts a download whose requests
skip ahead). Legacy float MISSION_ITEM replies are accepted and converted.
"""

from __future__ import annotations

import logging
import time
from dataclasses import replace
from typing import Callable

from ..dialect import mavlink
from ..errors import MissionTransferError, UavlocError
from ..mission import FRAME_MISSION, MISSION_TYPE_MISSION, POSITIONAL_COMMANDS, WireItem
from .connection import Link, Subscription
from .mission_wire import (ACCEPTED, DEFAULT_TIMEOUT_S, GENERIC_ERROR, GIVE_UP_S, INVALID_SEQUENCE, ITEM_TIMEOUT_S,
                           MAX_RETRIES, OPERATION_CANCELLED, for_us, item_from_message, result_name)

log = logging.getLogger(__name__)

Progress = Callable[[str, int, int], None]  # (stage, done, total)
REPLY_TYPES = ("MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ITEM", "MISSION_ACK")


async def download_mission(link: Link, target_system: int, target_component: int, *,
                           mission_type: int = MISSION_TYPE_MISSION, progress: Progress | None = None,
                           stage: str = "download") -> list[WireItem]:
    """Read the vehicle's mission (all items, seq 0..n-1 as the vehicle numbers them).

    A vehicle that aborts the transfer (MISSION_ACK ERROR or OPERATION_CANCELLED, e.g. PX4 when a
    late duplicate of an old request arrives out of order) is asked again from the start, up to
    MAX_RETRIES times. Raises MissionTransferError naming the vehicle and the item that could not
    be fetched.
    """
    for attempt in range(MAX_RETRIES + 1):
        try:
            return await _download_once(link, target_system, target_component, mission_type, progress, stage)
        except _Restart as restart:
            if attempt == MAX_RETRIES:
                raise MissionTransferError("vehicle aborted the download every time", vehicle=str(target_system),
                                           operation="mission download", seq=restart.seq, result=restart.result,
                                           result_name=result_name(restart.result)) from None
            log.info("vehicle %d aborted the download at item %s (%s); starting again", target_system,
                     restart.seq, result_name(restart.result))
    raise AssertionError("unreachable")


class _Restart(Exception):
    def __init__(self, seq: int | None, result: int):
        self.seq, self.result = seq, result


async def _download_once(link: Link, target_system: int, target_component: int, mission_type: int,
                         progress: Progress | None, stage: str) -> list[WireItem]:
    mav = link.mav
    with link.subscribe(REPLY_TYPES, source_system=target_system) as replies:
        count_msg = await _exchange(
            link, replies, mav.mission_request_list_encode(target_system, target_component, mission_type),
            lambda m: m.get_type() == "MISSION_COUNT", DEFAULT_TIMEOUT_S, target_system, seq=None)
        count = count_msg.count
        if progress:
            progress(stage, 0, count)
        items: list[WireItem] = []
        for seq in range(count):
            reply = await _exchange(
                link, replies, mav.mission_request_int_encode(target_system, target_component, seq, mission_type),
                lambda m, s=seq: m.get_type() in ("MISSION_ITEM_INT", "MISSION_ITEM") and m.seq == s,
                ITEM_TIMEOUT_S, target_system, seq=seq)
            items.append(item_from_message(reply))
            if progress:
                progress(stage, seq + 1, count)
        await link.send(mav.mission_ack_encode(target_system, target_component, ACCEPTED, mission_type))
    log.info("vehicle %d: downloaded %d mission items", target_system, count)
    return items


async def _exchange(link: Link, replies: Subscription, request, wanted: Callable, timeout_s: float,
                    vehicle: int, *, seq: int | None):
    """Send ``request`` and return the first reply ``wanted`` accepts, re-sending every
    ``timeout_s`` until GIVE_UP_S pass without it. An error MISSION_ACK ends the download."""
    await link.send(request)
    give_up_at = time.monotonic() + GIVE_UP_S
    while True:
        try:
            msg = await replies.get(timeout_s)
        except TimeoutError:
            if time.monotonic() >= give_up_at:
                what = "the mission count" if seq is None else f"item {seq}"
                raise MissionTransferError(f"no answer when requesting {what} for {GIVE_UP_S:g} s",
                                           vehicle=str(vehicle), operation="mission download", seq=seq) from None
            await link.send(request)
            continue
        if not for_us(msg, link.mav.srcSystem):
            continue
        if msg.get_type() == "MISSION_ACK":
            # ACCEPTED / INVALID_SEQUENCE here are late echoes of an upload that just finished.
            if msg.type in (GENERIC_ERROR, OPERATION_CANCELLED):
                raise _Restart(seq, msg.type)
            if msg.type not in (ACCEPTED, INVALID_SEQUENCE):
                raise MissionTransferError("vehicle refused the download", vehicle=str(vehicle),
                                           operation="mission download", seq=seq, result=msg.type,
                                           result_name=result_name(msg.type))
            continue
        if wanted(msg):
            return msg


# ---------------------------------------------------------------------------------------------
# What a downloaded mission looks like once saved: the form QGroundControl writes

_INT_FRAMES = {5: 0, 6: 3, 11: 10}  # MAV_FRAME_GLOBAL_INT / _RELATIVE_ALT_INT / _TERRAIN_ALT_INT
HOME_TIMEOUT_S = 3.0


def qgc_form(items: list[WireItem]) -> list[WireItem]:
    """The items as QGC saves a downloaded mission: the ``_INT`` frames PX4 answers with become
    their plain twins (6 -> 3), and items without a location (DO_CHANGE_SPEED, RTL, ... which
    ArduPilot returns in frame 0) use MAV_FRAME_MISSION with zero x/y/z."""
    out = []
    for it in items:
        frame = _INT_FRAMES.get(it.frame, it.frame)
        changes = {"frame": frame}
        if it.command not in POSITIONAL_COMMANDS:
            changes.update(frame=FRAME_MISSION, x=0, y=0, z=0.0)
        out.append(replace(it, **changes))
    return out


async def home_position(link: Link, target_system: int, target_component: int = 1, *,
                        timeout_s: float = HOME_TIMEOUT_S) -> tuple[float, float, float] | None:
    """The vehicle's home (lat, lon in degrees, altitude AMSL in metres) from HOME_POSITION, asked
    for with MAV_CMD_REQUEST_MESSAGE; None when the vehicle does not say within ``timeout_s``."""
    from .command import command_long  # command.py imports this package's siblings

    with link.subscribe("HOME_POSITION", source_system=target_system) as homes:
        try:
            await command_long(link, target_system, target_component, mavlink.MAV_CMD_REQUEST_MESSAGE,
                               (mavlink.MAVLINK_MSG_ID_HOME_POSITION,), retries=1)
        except MissionTransferError:
            raise
        except UavlocError as err:
            log.info("vehicle %d: %s", target_system, err)
        try:
            msg = await homes.get(timeout_s)
        except TimeoutError:
            return None
    return msg.latitude / 1e7, msg.longitude / 1e7, msg.altitude / 1000.0
