"""What makes a fake vehicle ArduPilot-like or PX4-like, in one table.

Values follow the autopilots' sources as summarised in ``reference/mavlink.md`` (§1.5 timeouts,
§1.8 sequence errors, §1.10 item 0, §1.11 validation) and the flight-mode encodings each autopilot
puts in HEARTBEAT.custom_mode.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from uavloc_gcs.dialect import mavlink as mav

# Our own vehicle modes; each flavour maps them to HEARTBEAT custom_mode values.
Mode = Literal["STABILIZE", "GUIDED", "AUTO", "RTL", "LAND", "LOITER", "TAKEOFF"]

# ArduCopter custom modes (ArduCopter/mode.h).
AP_COPTER_MODES: dict[str, int] = {
    "STABILIZE": 0, "AUTO": 3, "GUIDED": 4, "LOITER": 5, "RTL": 6, "LAND": 9, "BRAKE": 17,
}

# PX4 custom_mode = main_mode << 16 | sub_mode << 24 (px4_custom_mode.h).
PX4_MAIN_AUTO, PX4_MAIN_POSCTL, PX4_MAIN_MANUAL = 4, 3, 1
PX4_SUB = {"READY": 1, "TAKEOFF": 2, "LOITER": 3, "MISSION": 4, "RTL": 5, "LAND": 6}


def px4_custom_mode(main: int, sub: int = 0) -> int:
    return (main << 16) | (sub << 24)


PX4_MODES: dict[str, int] = {
    "STABILIZE": px4_custom_mode(PX4_MAIN_MANUAL),
    "GUIDED": px4_custom_mode(PX4_MAIN_AUTO, PX4_SUB["LOITER"]),  # PX4 "Hold"
    "LOITER": px4_custom_mode(PX4_MAIN_AUTO, PX4_SUB["LOITER"]),
    "AUTO": px4_custom_mode(PX4_MAIN_AUTO, PX4_SUB["MISSION"]),
    "RTL": px4_custom_mode(PX4_MAIN_AUTO, PX4_SUB["RTL"]),
    "LAND": px4_custom_mode(PX4_MAIN_AUTO, PX4_SUB["LAND"]),
    "TAKEOFF": px4_custom_mode(PX4_MAIN_AUTO, PX4_SUB["TAKEOFF"]),
}


@dataclass(frozen=True)
class Flavour:
    """Autopilot-specific behaviour of a fake vehicle."""

    name: Literal["ardupilot", "px4"]
    mav_autopilot: int
    home_is_item0: bool  # ArduPilot: mission seq 0 is home, execution starts at 1
    request_int: bool  # PX4 requests items with MISSION_REQUEST_INT, ArduPilot with MISSION_REQUEST
    nack_out_of_sequence: bool  # ArduPilot answers MAV_MISSION_INVALID_SEQUENCE and keeps going
    atomic_upload: bool  # PX4 swaps in the new plan at the end; ArduPilot writes in place
    item_retry_s: float  # vehicle re-sends the pending item request after this (wall seconds)
    upload_timeout_s: float  # gives up an upload after this long without an item (wall seconds)
    max_items: int
    keep_mission_on_reboot: bool
    modes: dict
    takeoff_alt_default_m: float  # PX4 MIS_TAKEOFF_ALT; ArduPilot needs the altitude given
    # Real PX4 aborts a download (MAV_MISSION_ERROR) when asked for anything but the next item or
    # a repeat of the last one -- e.g. a late duplicate of an older request on a lossy link. Off
    # by default (lenient) so ground stations that do not retry downloads still verify uploads.
    strict_download_order: bool = False
    # What the real autopilots do, measured on SITL (tests/sitl/test_behaviours.py
    # checks each against the fake and, when present, the real SITL):
    positionless_download_frame0: bool = False  # AP: DO_CHANGE_SPEED, RTL ... come back frame 0, x=y=0
    download_int_frames: bool = False  # PX4: positions come back in the _INT frames (6 for 3)
    mission_start_first_item_denied: bool = False  # AP: MISSION_START with first item != 0 is DENIED
    set_current_command_unsupported: bool = False  # PX4: DO_SET_MISSION_CURRENT -> UNSUPPORTED
    set_current_on_finished_holds: bool = False  # AP: AUTO holds after set-current on a finished mission
    upload_restarts_leg: bool = False  # AP: a mission uploaded in flight restarts the current leg
    # AP (ArduCopter ModeAuto::init): armed on the ground, AUTO is refused ("Auto: Missing Takeoff
    # Cmd", MISSION_START FAILED) unless the mission goes on with a NAV_TAKEOFF
    auto_needs_takeoff_on_ground: bool = False
    # PX4 (Commander, VEHICLE_CMD_MISSION_START): "switch to AUTO_MISSION and ARM" -- a disarmed
    # vehicle on the ground arms by mission start (DENIED when it cannot arm) and climbs to fly it
    mission_start_arms: bool = False
    arm_refused_after_boot_s: float = 0.0  # refuses to arm this long after boot (simulated seconds)
    arm_refusal: tuple[int, str] = (mav.MAV_RESULT_FAILED, "Arm: Accels inconsistent")
    refusal_text_delay_s: float = 0.0  # PX4: the STATUSTEXT saying why comes ~0.6 s after the ACK
    # PX4 checks a new mission in the background: a MISSION_START this soon (simulated s) after the
    # upload is DENIED, "Mission start denied! No valid mission" following the ACK late (SITL,
    # 2026-11-27: DENIED 11 ms after the upload's MISSION_ACK, the retry 0.5 s later ACCEPTED, the
    # denial's text 0.25 s after that ACK)
    mission_valid_after_upload_s: float = 0.0
    # Options the daemon needs other fixes for (see VehicleConfig.realistic_streams /
    # stale_mission_complete): what the real autopilot does, used only when switched on there.
    default_streams: tuple[int, ...] = ()  # streamed without being asked (realistic_streams)
    keeps_mission_complete: bool = False  # PX4: "complete" stays until the next mission starts
    hold_after_mission: bool = False  # PX4: AUTO.LOITER (Hold) when a mission ends in the air
    # PX4: a mission's RTL item ends the mission (MISSION_CURRENT complete at that item) and the
    # vehicle flies home in AUTO.RTL; an upload then reports not started, seq 0, and does not
    # start by itself. Measured on SITL: (complete, 3, AUTO.RTL) -> (not started, 0, AUTO.RTL).
    # ArduPilot flies the RTL item inside AUTO.
    rtl_item_leaves_mission: bool = False
    mission_done_text: str = "Mission complete"  # PX4 SITL says "Mission finished, loitering"
    # Routing a companion's messages to the ground (VehicleConfig.realistic_forwarding): PX4 drops
    # ids its dialect does not know (UAVLOC_RSSI_BATCH); ArduPilot forwards them when MAVn_OPTIONS
    # bit 3 is set on the companion's port, which the fake assumes.
    forwards_unknown_ids: bool = True
    # Landing, measured on SITL (``python -m tests.sitl.landing_measure``, issue 42): after touching
    # down the vehicle is still armed in LANDING until its land detector says ON_GROUND
    # (land_detect_s), then armed on the ground for disarm_after_landed_s before it disarms by
    # itself. A ground station that says "landed" before the disarm says it of a vehicle whose
    # motors still turn (and, on PX4, whose height wanders by +-1 m meanwhile).
    land_detect_s: float = 0.0
    disarm_after_landed_s: float = 0.0

    def custom_mode(self, mode: str) -> int:
        return self.modes[mode]

    def mode_from_custom(self, custom_mode: int, sub_mode: int | None = None) -> str | None:
        """Our mode name for a SET_MODE/DO_SET_MODE request, or None if unknown/unsupported."""
        if self.name == "px4":
            if sub_mode is not None:  # DO_SET_MODE: param2 = main mode, param3 = sub mode
                custom_mode = px4_custom_mode(int(custom_mode), int(sub_mode))
            main, sub = (custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF
            if main == PX4_MAIN_POSCTL:
                return "LOITER"
            if main == PX4_MAIN_MANUAL:
                return "STABILIZE"
            if main == PX4_MAIN_AUTO:
                for name, value in PX4_SUB.items():
                    if value == sub:
                        return {"READY": "LOITER", "MISSION": "AUTO"}.get(name, name)
            return None
        for name, value in self.modes.items():
            if value == custom_mode:
                return "LOITER" if name == "BRAKE" else name
        return None


ARDUPILOT = Flavour(
    name="ardupilot", mav_autopilot=mav.MAV_AUTOPILOT_ARDUPILOTMEGA, home_is_item0=True,
    request_int=False, nack_out_of_sequence=True, atomic_upload=False,
    # 650: a 16 KB board's mission storage, as the ArduCopter SITL (uavloc_gcs/link/mission_capacity.py)
    item_retry_s=1.0, upload_timeout_s=8.0, max_items=650, keep_mission_on_reboot=True,
    modes=AP_COPTER_MODES, takeoff_alt_default_m=2.5,
    positionless_download_frame0=True, mission_start_first_item_denied=True, set_current_on_finished_holds=True,
    upload_restarts_leg=True, arm_refused_after_boot_s=3.0, auto_needs_takeoff_on_ground=True,
    arm_refusal=(mav.MAV_RESULT_FAILED, "Arm: Accels inconsistent"),
    default_streams=(mav.MAVLINK_MSG_ID_HEARTBEAT,),  # + HOME_POSITION, STATUSTEXT, TIMESYNC unasked
    # ArduCopter SITL: ON_GROUND 1.7 s after touchdown (its land detector wants a steady climb rate
    # for LAND_DETECTOR_TRIGGER_SEC = 1 s), disarmed 0.7 s later
    land_detect_s=1.7, disarm_after_landed_s=0.7,
)

PX4 = Flavour(
    name="px4", mav_autopilot=mav.MAV_AUTOPILOT_PX4, home_is_item0=False,
    request_int=True, nack_out_of_sequence=False, atomic_upload=True,
    item_retry_s=0.25, upload_timeout_s=5.0, max_items=2000, keep_mission_on_reboot=False,
    modes=PX4_MODES, takeoff_alt_default_m=2.5,
    download_int_frames=True, set_current_command_unsupported=True, arm_refused_after_boot_s=1.0,
    mission_start_arms=True,
    arm_refusal=(mav.MAV_RESULT_TEMPORARILY_REJECTED, "Arming denied: Resolve system health failures first"),
    refusal_text_delay_s=0.6, mission_valid_after_upload_s=0.3,
    default_streams=(mav.MAVLINK_MSG_ID_HEARTBEAT, mav.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
                     mav.MAVLINK_MSG_ID_SYS_STATUS, mav.MAVLINK_MSG_ID_MISSION_CURRENT,
                     mav.MAVLINK_MSG_ID_EXTENDED_SYS_STATE),  # no SYSTEM_TIME unless asked
    keeps_mission_complete=True, hold_after_mission=True, rtl_item_leaves_mission=True,
    mission_done_text="Mission finished, loitering", forwards_unknown_ids=False,
    # PX4 SIH: ON_GROUND 7 s after touchdown (its land detector's stages), disarmed 2.2-2.7 s later
    # (COM_DISARM_LAND, 2 s by default, seen through 1 Hz heartbeats)
    land_detect_s=7.0, disarm_after_landed_s=2.5,
)

FLAVOURS = {"ardupilot": ARDUPILOT, "px4": PX4}
