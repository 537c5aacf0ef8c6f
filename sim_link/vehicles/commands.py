"""COMMAND_LONG / COMMAND_INT / SET_MODE handling of a fake vehicle, each answered by COMMAND_ACK.

Supported: COMPONENT_ARM_DISARM (400; param2 21196 forces), NAV_TAKEOFF (22; ArduPilot: GUIDED
mode, param7 metres above home; PX4: param7 AMSL, NaN = MIS_TAKEOFF_ALT, switches to Takeoff),
DO_SET_MODE (176) and SET_MODE, MISSION_START (300; PX4 also arms a disarmed vehicle),
NAV_RETURN_TO_LAUNCH (20), NAV_LAND (21),
DO_SET_MISSION_CURRENT (224; param1 -1 = keep, FAILED if out of range), DO_CHANGE_SPEED (178),
SET_MESSAGE_INTERVAL (511), REQUEST_MESSAGE (512), REQUEST_AUTOPILOT_CAPABILITIES (520),
GET_HOME_POSITION (410), PREFLIGHT_REBOOT_SHUTDOWN (246, param1 = 1), BATTERY_RESET (42651; ArduPilot:
param1 battery mask, param2 percentage, battery.py; PX4: UNSUPPORTED), DO_REPOSITION (192, COMMAND_INT
x/y degE7, z metres above home; the vehicle flies there and holds). SET_POSITION_TARGET_GLOBAL_INT
(position bits) does the same in GUIDED. Anything else: UNSUPPORTED. NaN parameters mean "unset".
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from uavloc_gcs.dialect import mavlink as mav

from .battery import MAV_CMD_BATTERY_RESET
from .mission_server import Peer, Reply

if TYPE_CHECKING:  # pragma: no cover
    from .vehicle import FakeVehicle

ACCEPTED, DENIED, UNSUPPORTED, FAILED = (
    mav.MAV_RESULT_ACCEPTED, mav.MAV_RESULT_DENIED, mav.MAV_RESULT_UNSUPPORTED, mav.MAV_RESULT_FAILED)
FORCE_MAGIC = 21196


def _i(x: float, default: int = 0) -> int:
    """An integer parameter; NaN (MAVLink's "unset", which MAVSDK sends for unused params) -> default."""
    return int(round(x)) if math.isfinite(x) else default


def _ack(peer: Peer, command: int, result: int) -> Reply:
    return Reply(mav.MAVLink_command_ack_message(command, result, 0, 0, peer.sysid, peer.compid), peer)


def handle_command(v: "FakeVehicle", msg, peer: Peer) -> list[Reply]:
    cmd = int(msg.command)
    p = [msg.param1, msg.param2, msg.param3, msg.param4]
    if msg.get_type() == "COMMAND_INT":
        p += [msg.x, msg.y, msg.z]
    else:
        p += [msg.param5, msg.param6, msg.param7]
    extra: list[Reply] = []
    is_int = msg.get_type() == "COMMAND_INT"
    result = _dispatch(v, cmd, p, extra, is_int)
    out = [_ack(peer, cmd, result)] + extra
    if cmd == mav.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN and result == ACCEPTED and v.on_reboot_request:
        v.on_reboot_request()
    return out


def handle_position_target(v: "FakeVehicle", msg, peer: Peer) -> list[Reply]:
    """SET_POSITION_TARGET_GLOBAL_INT in GUIDED: fly there (position only; no ack in MAVLink)."""
    if v.mode == "GUIDED" and v.armed and not v.landed and not (msg.type_mask & 0b111):
        v.goto(msg.lat_int, msg.lon_int, msg.alt, degE7=True)
    return []


def handle_set_mode(v: "FakeVehicle", msg, peer: Peer) -> list[Reply]:
    mode = v.flavour.mode_from_custom(int(msg.custom_mode)) if msg.base_mode & 1 else None
    ok = mode is not None and v.set_mode(mode)
    return [_ack(peer, mav.MAVLINK_MSG_ID_SET_MODE, ACCEPTED if ok else FAILED)]


def _dispatch(v: "FakeVehicle", cmd: int, p: list, extra: list, is_int: bool = False) -> int:
    px4 = v.flavour.name == "px4"
    if cmd == mav.MAV_CMD_COMPONENT_ARM_DISARM:
        force = _i(p[1]) == FORCE_MAGIC
        if p[0] >= 0.5:
            refusal = None if force or v.armed else v.arm_refusal()
            return ACCEPTED if v.arm(force) else (refusal[0] if refusal else FAILED)
        return ACCEPTED if v.disarm(force) else FAILED
    if cmd == mav.MAV_CMD_NAV_TAKEOFF:
        if not v.armed:
            return DENIED
        if px4:
            alt = v.flavour.takeoff_alt_default_m if math.isnan(p[6]) else p[6] - v.cfg.home_alt_amsl_m
            if not v.landed or not v.takeoff(alt):
                return FAILED
            v.mode = "TAKEOFF"
            return ACCEPTED
        if v.mode != "GUIDED":
            return FAILED
        return ACCEPTED if v.takeoff(p[6]) else FAILED
    if cmd == mav.MAV_CMD_DO_SET_MODE:
        if not _i(p[0]) & mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return UNSUPPORTED
        mode = v.flavour.mode_from_custom(_i(p[1]), _i(p[2]) if px4 else None)
        if mode is None:
            return FAILED
        return ACCEPTED if v.set_mode(mode) else FAILED
    if cmd == mav.MAV_CMD_MISSION_START:
        first = _i(p[0])
        if v.t_s - v.mission_changed_t_s < v.flavour.mission_valid_after_upload_s:
            v.say_later(v.flavour.refusal_text_delay_s, mav.MAV_SEVERITY_CRITICAL, "Mission start denied! No valid mission")
            return DENIED  # PX4: the new mission is still being checked
        if (first or _i(p[1])) and v.flavour.mission_start_first_item_denied:
            return DENIED  # ArduPilot: only 0, 0 (it resumes from its current item)
        if first > 0 and not v.set_current(first):
            return FAILED
        if not v.set_mode("AUTO"):
            return FAILED
        if v.flavour.mission_start_arms and not v.armed:
            return ACCEPTED if v.arm() else DENIED  # PX4: "switch to AUTO_MISSION and ARM"
        return ACCEPTED
    if cmd == mav.MAV_CMD_NAV_RETURN_TO_LAUNCH:
        return ACCEPTED if v.set_mode("RTL") else FAILED
    if cmd == mav.MAV_CMD_NAV_LAND:
        return ACCEPTED if v.set_mode("LAND") else FAILED
    if cmd == mav.MAV_CMD_DO_SET_MISSION_CURRENT:
        if v.flavour.set_current_command_unsupported:
            return UNSUPPORTED  # PX4: use the MISSION_SET_CURRENT message
        if not v.set_current(_i(p[0], -1), reset=p[1] >= 0.5):
            return FAILED
        extra.append(v.mission_current_reply())
        return ACCEPTED
    if cmd == mav.MAV_CMD_DO_REPOSITION:
        # COMMAND_INT: x/y degE7, z metres above home; param1 ground speed (-1/NaN: keep)
        if not v.armed or v.landed:
            return FAILED
        if math.isfinite(p[0]) and p[0] > 0:
            v.speed_m_s = float(p[0])
        if not v.goto(p[4], p[5], p[6], degE7=is_int):
            return FAILED
        return ACCEPTED
    if cmd == mav.MAV_CMD_DO_CHANGE_SPEED:
        if math.isfinite(p[1]) and p[1] > 0:
            v.speed_m_s = float(p[1])
        return ACCEPTED
    if cmd == mav.MAV_CMD_SET_MESSAGE_INTERVAL:
        v.set_interval(_i(p[0], -1), float(p[1]) if math.isfinite(p[1]) else 0.0)
        return ACCEPTED
    if cmd in (mav.MAV_CMD_REQUEST_MESSAGE, mav.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES,
               mav.MAV_CMD_GET_HOME_POSITION):
        msg_id = {mav.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES: mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
                  mav.MAV_CMD_GET_HOME_POSITION: mav.MAVLINK_MSG_ID_HOME_POSITION}.get(cmd, _i(p[0], -1))
        replies = v.message_replies(msg_id)
        if not replies:
            return UNSUPPORTED
        extra.extend(Reply(r.msg, None, r.component) for r in replies)
        return ACCEPTED
    if cmd == MAV_CMD_BATTERY_RESET:
        return v.battery.reset(_i(p[0]), float(p[1]) if math.isfinite(p[1]) else -1.0)
    if cmd == mav.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN:
        return ACCEPTED if _i(p[0]) == 1 and not v.armed else (DENIED if v.armed else UNSUPPORTED)
    return UNSUPPORTED
