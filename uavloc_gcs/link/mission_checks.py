"""What an autopilot refuses in a mission item, checked before the upload starts.

A refusal comes back in the middle of a transfer (MISSION_ACK with INVALID_PARAMn or
UNSUPPORTED_FRAME), and ArduPilot has by then truncated its mission to the new count and written
the items before the bad one: the vehicle is left with half a mission. Checking first turns a bad
file into one sentence naming the item and the field, with nothing sent (issue 40).

ArduPilot (``AP_Mission::sanity_check_params`` and ``mavlink_int_to_mission_cmd``, master of
2026-03-20, commit 64a9c78): an infinite parameter, or a NaN one except param4 of NAV_WAYPOINT,
LOITER_UNLIM, LAND, TAKEOFF and VTOL_TAKEOFF (param2-4 of ARC_WAYPOINT, param3-4 of VTOL_LAND), is
INVALID_PARAMn; a location item's altitude that is NaN or at least ``LOCATION_ALT_MAX_M`` = 83,000
m (``AP_Common/Location.h``: centimetres in 24 bits) is INVALID_PARAM7; its frame must be MISSION,
GLOBAL, GLOBAL_RELATIVE_ALT or GLOBAL_TERRAIN_ALT (or their _INT forms), else UNSUPPORTED_FRAME.

PX4 (``MavlinkMissionManager::parse_mavlink_mission_item``, main of 2025-07-24, commit 752ecd3):
a location item must use GLOBAL or GLOBAL_RELATIVE_ALT (or their _INT forms); terrain and local
frames are UNSUPPORTED_FRAME. (Items without a location travel in MAV_FRAME_MISSION, which
``mission.to_wire`` sets.) The fake vehicles of ``sim_link`` refuse the same.
"""

from __future__ import annotations

import math

from ..mission import LOCATION_COMMANDS, WireItem

LOCATION_ALT_MAX_M = 83_000.0
# ArduPilot: which params may be NaN, per command (0-based param index)
_AP_NAN_OK = {16: {3}, 17: {3}, 21: {3}, 22: {3}, 84: {3}, 36: {1, 2, 3}, 85: {2, 3}}
_AP_LOCATION_FRAMES = {2, 0, 5, 3, 6, 10, 11}
_PX4_LOCATION_FRAMES = {0, 5, 3, 6}
_FRAME_NAMES = {0: "GLOBAL", 1: "LOCAL_NED", 2: "MISSION", 3: "GLOBAL_RELATIVE_ALT", 4: "LOCAL_ENU", 5: "GLOBAL_INT",
                6: "GLOBAL_RELATIVE_ALT_INT", 7: "LOCAL_OFFSET_NED", 8: "BODY_NED", 9: "BODY_OFFSET_NED",
                10: "GLOBAL_TERRAIN_ALT", 11: "GLOBAL_TERRAIN_ALT_INT"}


def _frame(frame: int) -> str:
    return f"{frame} ({_FRAME_NAMES[frame]})" if frame in _FRAME_NAMES else str(frame)


def refusal(item: WireItem, autopilot: str, file_frame: int | None = None) -> tuple[str, str] | None:
    """``(field, reason)`` when ``autopilot`` ("ardupilot", "px4") would refuse ``item`` during
    an upload; None when it takes it (other autopilots: None).
    ``file_frame``: the frame the file gave the item (named instead of the one it is sent in)."""
    params = (item.param1, item.param2, item.param3, item.param4)
    located = item.command in LOCATION_COMMANDS
    if autopilot == "ardupilot":
        for k, p in enumerate(params):
            if math.isinf(p):
                return f"param{k + 1}", f"{p} is infinite, which ArduPilot refuses"
            if math.isnan(p) and k not in _AP_NAN_OK.get(item.command, set()):
                return f"param{k + 1}", "is NaN (empty), which ArduPilot refuses for this command"
        if located:
            if item.frame not in _AP_LOCATION_FRAMES:
                return "frame", f"ArduPilot takes no location item in frame {_frame(item.frame)}"
            if not math.isfinite(item.z) or abs(item.z) >= LOCATION_ALT_MAX_M:
                return "altitude", (f"{item.z:g} m is beyond ArduPilot's altitudes (less than "
                                    f"{LOCATION_ALT_MAX_M:,.0f} m either way)")
    elif autopilot == "px4" and located and item.frame not in _PX4_LOCATION_FRAMES:
        return "frame", (f"PX4 takes location items only in frames GLOBAL and GLOBAL_RELATIVE_ALT (or their _INT "
                         f"forms), not {_frame(item.frame if file_frame is None else file_frame)}")
    return None
