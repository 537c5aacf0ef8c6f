"""What the mission upload, download and clear exchanges share: the devguide's timing numbers and
the MISSION_ITEM(_INT) <-> :class:`~uavloc_gcs.mission.WireItem` conversion.

Timing (MAVLink devguide ``services/mission.md``; QGC ``PlanManager.h`` uses the same values):

* ``DEFAULT_TIMEOUT_S`` 1.5 s -- waiting for the answer to MISSION_COUNT / REQUEST_LIST /
  CLEAR_ALL before re-sending it.
* ``ITEM_TIMEOUT_S`` 0.25 s -- waiting for the next request (upload) or the requested item
  (download) before re-sending the last item / request.
* ``MAX_RETRIES`` 5 -- re-sends of the default timeout without progress; an exchange gives up
  when it has made no progress for ``GIVE_UP_S = MAX_RETRIES * DEFAULT_TIMEOUT_S`` = 7.5 s, which
  is 30 re-sends at the item timeout. Counting the item re-sends themselves (5 x 0.25 s) would
  abort a 500-item upload on a 20 %-loss link most of the time (P(6 lost round trips in a row)
  = 0.36^6 per item); 7.5 s is just under ArduPilot's own 8 s upload timeout, so both ends give
  up at about the same time.
"""

from __future__ import annotations

from ..dialect import mavlink
from ..mission import GLOBAL_FRAMES, MISSION_TYPE_MISSION, WireItem

DEFAULT_TIMEOUT_S = 1.5
ITEM_TIMEOUT_S = 0.25
MAX_RETRIES = 5
GIVE_UP_S = MAX_RETRIES * DEFAULT_TIMEOUT_S

ACCEPTED = mavlink.MAV_MISSION_ACCEPTED
INVALID_SEQUENCE = mavlink.MAV_MISSION_INVALID_SEQUENCE
GENERIC_ERROR = mavlink.MAV_MISSION_ERROR
OPERATION_CANCELLED = mavlink.MAV_MISSION_OPERATION_CANCELLED


def result_name(code: int) -> str:
    """MAV_MISSION_RESULT name for ``code`` (e.g. 13 -> 'MAV_MISSION_INVALID_SEQUENCE')."""
    entry = mavlink.enums["MAV_MISSION_RESULT"].get(code)
    return entry.name if entry is not None else f"MAV_MISSION_RESULT({code})"


def item_message(mav: mavlink.MAVLink, target_system: int, target_component: int, item: WireItem):
    """MISSION_ITEM_INT carrying ``item``."""
    return mav.mission_item_int_encode(
        target_system, target_component, item.seq, item.frame, item.command, item.current, item.autocontinue,
        item.param1, item.param2, item.param3, item.param4, item.x, item.y, item.z, item.mission_type)


def item_from_message(msg) -> WireItem:
    """WireItem from a MISSION_ITEM_INT, or from a legacy float MISSION_ITEM (x/y scaled to degE7
    for global frames)."""
    x, y = msg.x, msg.y
    if msg.get_type() == "MISSION_ITEM":
        if msg.frame in GLOBAL_FRAMES:
            x, y = round(x * 1e7), round(y * 1e7)
        else:
            x, y = round(x), round(y)
    return WireItem(msg.seq, msg.frame, msg.command, msg.current, msg.autocontinue, msg.param1, msg.param2,
                    msg.param3, msg.param4, int(x), int(y), float(msg.z),
                    getattr(msg, "mission_type", MISSION_TYPE_MISSION))


def for_us(msg, our_system: int) -> bool:
    """A vehicle's mission message addressed to us (or broadcast), not to another GCS."""
    return getattr(msg, "target_system", 0) in (0, our_system)
