"""Mission upload: MISSION_COUNT, then the vehicle requests each item and we answer with
MISSION_ITEM_INT, until it sends MISSION_ACK (devguide ``services/mission.md``, "Upload a
Mission to the Vehicle"); then, by default, the mission is downloaded back and compared.

What real vehicles do that this code must survive (reference/mavlink.md §1.8, §1.9, §7):

* ArduPilot requests items with the deprecated MISSION_REQUEST, PX4 with MISSION_REQUEST_INT;
  both get MISSION_ITEM_INT (a float MISSION_ITEM would move waypoints by ~0.5 m).
* When a request is lost we re-send the last item; ArduPilot answers that duplicate with
  MISSION_ACK(INVALID_SEQUENCE) but keeps the transfer going, so that NACK is not an error
  (mavros PR #798; QGC ignores it too).
* Vehicles re-request on their own (PX4 every 250 ms, ArduPilot every 1 s); duplicated and
  reordered requests are simply answered again.
* The final ACK can be lost. The last item is then re-sent; PX4 re-ACKs it, ArduPilot may not
  answer at all. Because the read-back is what counts, a transfer whose final ACK never arrived
  is judged by the verification download (``UploadResult.ack_lost``).
* ArduPilot truncates its mission as soon as it gets MISSION_COUNT (uploads are not atomic), so a
  failed upload is always reported: MissionTransferError names the vehicle, the item and the
  MAV_MISSION_RESULT.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import Callable, Sequence

from ..errors import MissionTransferError
from ..mission import MISSION_TYPE_MISSION, WireItem
from .autopilots import Flavour, flavour_for, flavour_named
from .connection import Link
from .mission_download import download_mission
from .mission_wire import (ACCEPTED, DEFAULT_TIMEOUT_S, GENERIC_ERROR, GIVE_UP_S, INVALID_SEQUENCE, ITEM_TIMEOUT_S,
                           for_us,
                           item_message, result_name)

log = logging.getLogger(__name__)

Progress = Callable[[str, int, int], None]  # (stage "upload" | "verify", done, total)
REQUEST_TYPES = ("MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK")


@dataclass(frozen=True)
class UploadResult:
    """How an upload went. ``resends`` counts messages re-sent after a timeout."""

    vehicle: int
    item_count: int
    duration_s: float
    resends: int
    nacks_ignored: int  # ArduPilot INVALID_SEQUENCE answers to duplicates
    opaque_id: int  # plan id from the final ACK (0: not supported / ACK lost)
    verified: bool
    ack_lost: bool


async def upload_mission(link: Link, target_system: int, target_component: int, items: Sequence[WireItem], *,
                         verify: bool = True, autopilot: str | Flavour | None = None,
                         progress: Progress | None = None) -> UploadResult:
    """Upload ``items`` (seq 0..n-1, one mission type) to the vehicle and, with ``verify``,
    download it back and compare what the autopilot stores.

    ``autopilot`` ("ardupilot"/"px4") decides how the read-back is compared (ArduPilot replaces
    seq 0 with its home); by default it comes from the vehicle's HEARTBEAT on ``link``.
    """
    items = list(items)
    _check_numbering(items, target_system)
    mission_type = items[0].mission_type if items else MISSION_TYPE_MISSION
    vehicle = str(target_system)
    mav = link.mav
    started = time.monotonic()
    n = len(items)
    resends = nacks = 0
    opaque_id = 0
    ack_lost = False

    messages = [item_message(mav, target_system, target_component, it) for it in items]
    with link.subscribe(REQUEST_TYPES, source_system=target_system) as replies:
        last_sent = mav.mission_count_encode(target_system, target_component, n, mission_type)
        await link.send(last_sent)
        timeout_s = DEFAULT_TIMEOUT_S  # until the first request; then the item timeout
        highest_sent = -1
        last_is_resend = False
        last_requested = -1
        pending_error: int | None = None
        give_up_at = time.monotonic() + GIVE_UP_S
        if progress:
            progress("upload", 0, n)
        while True:
            try:
                msg = await replies.get(timeout_s)
            except TimeoutError:
                if time.monotonic() >= give_up_at:
                    if n and highest_sent == n - 1 and verify and pending_error is None:
                        ack_lost = True  # every item went out; the read-back decides
                        break
                    raise MissionTransferError(
                        f"vehicle stopped requesting items for {GIVE_UP_S:g} s", vehicle=vehicle,
                        operation="mission upload", seq=highest_sent + 1 if highest_sent + 1 < n else None,
                        result=pending_error,
                        result_name=result_name(pending_error) if pending_error is not None else None) from None
                await link.send(last_sent)
                log.debug("vehicle %s upload: timeout, re-sent %s", vehicle, last_sent.get_type())
                resends += 1
                last_is_resend = True
                continue
            if not for_us(msg, mav.srcSystem) or getattr(msg, "mission_type", mission_type) != mission_type:
                continue
            if msg.get_type() == "MISSION_ACK":
                if msg.type == ACCEPTED:
                    if highest_sent == n - 1:
                        opaque_id = getattr(msg, "opaque_id", 0)
                        break
                    continue  # a late ACK of an earlier transfer
                if msg.type == INVALID_SEQUENCE:
                    nacks += 1
                    if last_is_resend and highest_sent + 1 < n:
                        # ArduPilot NACKs our re-sent item k because it already has it: its
                        # request for k+1 was lost. Send k+1 now rather than wait ~1 s for its
                        # re-request; if we guessed wrong it NACKs again and re-requests.
                        highest_sent += 1
                        last_sent = messages[highest_sent]
                        link.send_nowait(last_sent)
                        last_is_resend = False
                    continue
                if n and highest_sent == n - 1 and resends and verify:
                    ack_lost = True  # an idle vehicle refusing our re-sent last item
                    break
                if msg.type == GENERIC_ERROR:
                    # PX4 answers a late duplicate of our MISSION_COUNT with ERROR ("Busy") and
                    # carries on; a vehicle that really gave up stops requesting, and the
                    # give-up timeout then reports this result.
                    pending_error = msg.type
                    continue
                raise MissionTransferError(
                    "vehicle rejected the mission", vehicle=vehicle, operation="mission upload",
                    seq=max(highest_sent, 0) if n else None, result=msg.type, result_name=result_name(msg.type))
            seq = msg.seq
            if not 0 <= seq < n:
                log.debug("vehicle %s requested item %d of %d; ignored", vehicle, seq, n)
                continue
            last_is_resend = seq <= highest_sent
            last_sent = messages[seq]
            link.send_nowait(last_sent)
            timeout_s = ITEM_TIMEOUT_S
            if seq != last_requested:  # the vehicle moved on (or restarted): progress
                give_up_at = time.monotonic() + GIVE_UP_S
                last_requested = seq
            if seq > highest_sent:
                highest_sent = seq
                if progress:
                    progress("upload", seq + 1, n)

    verified = False
    if verify:
        flavour = _flavour(link, target_system, autopilot)
        stored = await download_mission(link, target_system, target_component, mission_type=mission_type,
                                        progress=progress, stage="verify")
        _compare(items, stored, flavour, vehicle)
        verified = True
    result = UploadResult(target_system, n, time.monotonic() - started, resends, nacks, opaque_id, verified, ack_lost)
    log.info("vehicle %s: uploaded %d items in %.2f s (%d re-sends, %d NACKs ignored%s)", vehicle, n,
             result.duration_s, resends, nacks, ", verified" if verified else "")
    return result


def _check_numbering(items: list[WireItem], vehicle: int) -> None:
    for i, it in enumerate(items):
        if it.seq != i:
            raise MissionTransferError(f"items must be numbered 0..{len(items) - 1}; position {i} has seq {it.seq}",
                                       vehicle=str(vehicle), operation="mission upload", seq=it.seq)
        if it.mission_type != items[0].mission_type:
            raise MissionTransferError("items mix mission types", vehicle=str(vehicle),
                                       operation="mission upload", seq=it.seq)


def _flavour(link: Link, target_system: int, autopilot: str | Flavour | None) -> Flavour:
    if isinstance(autopilot, Flavour):
        return autopilot
    if autopilot is not None:
        return flavour_named(autopilot)
    hb = link.heartbeats.get(target_system)
    return flavour_for(hb.autopilot) if hb is not None else flavour_named("generic")


def _compare(sent: list[WireItem], stored: list[WireItem], flavour: Flavour, vehicle: str) -> None:
    """Raise MissionTransferError at the first item the vehicle does not hold as sent."""
    if len(stored) != len(sent):
        raise MissionTransferError(f"read-back has {len(stored)} items, {len(sent)} were uploaded",
                                   vehicle=vehicle, operation="mission verify")
    for a, b in zip(sent, stored):
        if flavour.home_at_seq0 and a.seq == 0:
            continue  # ArduPilot reports its own home here
        if not flavour.stored_equal(a, b):
            raise MissionTransferError(f"read-back differs: sent {a}, vehicle holds {b}", vehicle=vehicle,
                                       operation="mission verify", seq=a.seq)
