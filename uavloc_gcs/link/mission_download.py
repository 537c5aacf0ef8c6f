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
from typing import Callable

from ..errors import MissionTransferError
from ..mission import MISSION_TYPE_MISSION, WireItem
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
