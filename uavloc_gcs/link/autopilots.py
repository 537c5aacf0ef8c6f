"""ArduPilot vs PX4, in one small registry keyed by HEARTBEAT.autopilot (MAV_AUTOPILOT).

What differs and matters to uavloc: flight-mode numbers (HEARTBEAT.custom_mode and
MAV_CMD_DO_SET_MODE parameters), whether mission seq 0 is home, which request message the vehicle
uses during an upload, and which item fields the vehicle stores (so an upload can be verified
by reading it back). Sources: ArduCopter/ArduPlane ``mode.h``, PX4 ``px4_custom_mode.h``,
reference/mavlink.md §1.9-1.11.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..dialect import mavlink
from ..errors import ConfigError
from ..mission import (DO_CHANGE_SPEED, DO_JUMP, FRAME_GLOBAL, FRAME_GLOBAL_INT, FRAME_GLOBAL_RELATIVE_ALT,
                       FRAME_GLOBAL_RELATIVE_ALT_INT, FRAME_GLOBAL_TERRAIN_ALT, FRAME_GLOBAL_TERRAIN_ALT_INT,
                       NAV_LAND, NAV_LOITER_TIME, NAV_RETURN_TO_LAUNCH, NAV_TAKEOFF, NAV_WAYPOINT, POSITIONAL_COMMANDS,
                       WireItem)

MAV_TYPE_FIXED_WING = mavlink.MAV_TYPE_FIXED_WING

# ArduCopter mode.h (Mode::Number), master 2026-03
ARDUCOPTER_MODES = {
    "STABILIZE": 0, "ACRO": 1, "ALT_HOLD": 2, "AUTO": 3, "GUIDED": 4, "LOITER": 5, "RTL": 6,
    "CIRCLE": 7, "LAND": 9, "DRIFT": 11, "SPORT": 13, "FLIP": 14, "AUTOTUNE": 15, "POSHOLD": 16,
    "BRAKE": 17, "THROW": 18, "AVOID_ADSB": 19, "GUIDED_NOGPS": 20, "SMART_RTL": 21, "FLOWHOLD": 22,
    "FOLLOW": 23, "ZIGZAG": 24, "SYSTEMID": 25, "AUTOROTATE": 26, "AUTO_RTL": 27, "TURTLE": 28,
}
# ArduPlane mode.h (Mode::Number)
ARDUPLANE_MODES = {
    "MANUAL": 0, "CIRCLE": 1, "STABILIZE": 2, "TRAINING": 3, "ACRO": 4, "FBWA": 5, "FBWB": 6, "CRUISE": 7,
    "AUTOTUNE": 8, "AUTO": 10, "RTL": 11, "LOITER": 12, "TAKEOFF": 13, "AVOID_ADSB": 14, "GUIDED": 15,
    "INITIALISING": 16, "QSTABILIZE": 17, "QHOVER": 18, "QLOITER": 19, "QLAND": 20, "QRTL": 21,
    "QAUTOTUNE": 22, "QACRO": 23, "THERMAL": 24, "LOITER_ALT_QLAND": 25, "AUTOLAND": 26,
}
# PX4 px4_custom_mode.h: custom_mode = main_mode << 16 | sub_mode << 24
PX4_MODES = {
    "MANUAL": (1, 0), "ALTCTL": (2, 0), "POSCTL": (3, 0), "POSCTL.ORBIT": (3, 1), "POSCTL.SLOW": (3, 2),
    "ACRO": (5, 0), "OFFBOARD": (6, 0), "STABILIZED": (7, 0), "RATTITUDE": (8, 0), "TERMINATION": (10, 0),
    "AUTO.READY": (4, 1), "AUTO.TAKEOFF": (4, 2), "AUTO.LOITER": (4, 3), "AUTO.MISSION": (4, 4),
    "AUTO.RTL": (4, 5), "AUTO.LAND": (4, 6), "AUTO.FOLLOW_TARGET": (4, 8), "AUTO.PRECLAND": (4, 9),
    "AUTO.VTOL_TAKEOFF": (4, 10), **{f"AUTO.EXTERNAL{k}": (4, 10 + k) for k in range(1, 9)},
}
# Generic names the service uses, per flavour.
_PX4_ALIASES = {"AUTO": "AUTO.MISSION", "MISSION": "AUTO.MISSION", "RTL": "AUTO.RTL", "LAND": "AUTO.LAND",
                "LOITER": "AUTO.LOITER", "HOLD": "AUTO.LOITER", "GUIDED": "AUTO.LOITER",
                "TAKEOFF": "AUTO.TAKEOFF"}
_AP_ALIASES = {"MISSION": "AUTO", "HOLD": "LOITER"}

# Parameters ArduPilot (Copter) stores per command; the others come back as 0 on download
# (AP_Mission::mavlink_int_to_mission_cmd). NAV_WAYPOINT p1 is stored as whole seconds.
_AP_STORED_PARAMS = {
    NAV_WAYPOINT: (1,), NAV_TAKEOFF: (), NAV_LAND: (), NAV_RETURN_TO_LAUNCH: (), NAV_LOITER_TIME: (1,),
    DO_CHANGE_SPEED: (1, 2, 3), DO_JUMP: (1, 2),
}
# PX4 ignores NAV_WAYPOINT param3 (pass radius) and stores the rest.
_PX4_STORED_PARAMS = {NAV_WAYPOINT: (1, 2, 4)}

_FRAME_CLASS = {
    FRAME_GLOBAL: 0, FRAME_GLOBAL_INT: 0, FRAME_GLOBAL_RELATIVE_ALT: 3, FRAME_GLOBAL_RELATIVE_ALT_INT: 3,
    FRAME_GLOBAL_TERRAIN_ALT: 10, FRAME_GLOBAL_TERRAIN_ALT_INT: 10,
}


def _feq(a: float, b: float) -> bool:
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return abs(a - b) <= 1e-5 * max(1.0, abs(a))


@dataclass(frozen=True)
class Flavour:
    """What uavloc needs to know about one autopilot family."""

    name: str  # "ardupilot" | "px4" (the names mission.py uses)
    label: str
    mav_autopilot: int
    home_at_seq0: bool
    upload_request: str  # message the vehicle requests items with during an upload
    stored_params: dict[int, tuple[int, ...]] = field(default_factory=dict)
    alt_resolution_m: float = 0.0  # ArduPilot stores altitudes as whole centimetres
    latlon_tolerance_e7: int = 0  # PX4 keeps lat/lon as doubles and may round back off by one
    # Behaviours measured on SITL (tests/sitl); see link/mission_control.py for the sequences.
    positionless_read_back_as_frame0: bool = False  # AP: DO_CHANGE_SPEED/RTL... come back frame 0, x=y=0
    mission_start_takes_first_item: bool = True  # AP DENIES MISSION_START with first item != 0
    set_current_command: bool = True  # PX4 answers DO_SET_MISSION_CURRENT UNSUPPORTED
    upload_restarts_mission: bool = False  # PX4 flies a mission uploaded in AUTO.MISSION from item 0
    finished_mission_needs_start: bool = False  # AP AUTO holds after set-current on a finished mission
    # The start arms only in these modes, switching to ``arm_mode`` first from any other (issue 26:
    # ArduCopter armed in STABILIZE, then refused AUTO "requires position" and disarmed; GUIDED
    # itself requires a position, so it is not armed before it knows where it is. PX4 refuses to
    # arm in Return, which it stays in after landing). Empty: arm as it is.
    armable_modes: tuple[str, ...] = ()
    arm_mode: str = ""

    @property
    def first_mission_seq(self) -> int:
        """Wire seq of the first real item (1 after ArduPilot's home item)."""
        return 1 if self.home_at_seq0 else 0

    # -- modes ----------------------------------------------------------------------------

    def mode_params(self, mode: str, vehicle_type: int | None = None) -> tuple[float, float, float]:
        """MAV_CMD_DO_SET_MODE param1..3 for ``mode`` (name like "AUTO", "GUIDED", "RTL")."""
        name = mode.strip().upper()
        custom = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        if self.name == "px4":
            name = _PX4_ALIASES.get(name, name)
            if name not in PX4_MODES:
                raise ConfigError(f"unknown PX4 mode {mode!r} (known: {', '.join(PX4_MODES)})", key="mode")
            main, sub = PX4_MODES[name]
            return float(custom), float(main), float(sub)
        table = ARDUPLANE_MODES if vehicle_type == MAV_TYPE_FIXED_WING else ARDUCOPTER_MODES
        name = _AP_ALIASES.get(name, name)
        if name not in table:
            raise ConfigError(f"unknown ArduPilot mode {mode!r} (known: {', '.join(table)})", key="mode")
        return float(custom), float(table[name]), 0.0

    def mode_name(self, custom_mode: int, vehicle_type: int | None = None) -> str:
        """Readable mode from HEARTBEAT.custom_mode."""
        if self.name == "px4":
            main, sub = (custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF
            for name, (m, s) in PX4_MODES.items():
                if (m, s) == (main, sub):
                    return name
            for name, (m, s) in PX4_MODES.items():  # a sub mode we do not know of a known main mode
                if m == main and s == 0 and main != 4:
                    return name
            return f"PX4({main}.{sub})"
        table = ARDUPLANE_MODES if vehicle_type == MAV_TYPE_FIXED_WING else ARDUCOPTER_MODES
        for name, number in table.items():
            if number == custom_mode:
                return name
        return f"MODE({custom_mode})"

    # -- missions -------------------------------------------------------------------------

    def stored_equal(self, sent: WireItem, got: WireItem) -> bool:
        """Whether ``got`` (downloaded) is what this autopilot stores for ``sent`` (uploaded)."""
        if sent.command != got.command or sent.autocontinue != got.autocontinue:
            return False
        if (self.positionless_read_back_as_frame0 and sent.command not in POSITIONAL_COMMANDS
                and got.frame == FRAME_GLOBAL and got.x == 0 and got.y == 0):
            sent = WireItem(**{**sent.__dict__, "frame": FRAME_GLOBAL, "x": 0, "y": 0})
        if _FRAME_CLASS.get(sent.frame, sent.frame) != _FRAME_CLASS.get(got.frame, got.frame):
            return False
        tol = self.latlon_tolerance_e7 if sent.frame in _FRAME_CLASS else 0
        if abs(sent.x - got.x) > tol or abs(sent.y - got.y) > tol:
            return False
        if not (_feq(sent.z, got.z) or abs(sent.z - got.z) <= self.alt_resolution_m / 2 + 1e-6):
            return False
        kept = self.stored_params.get(sent.command, (1, 2, 3, 4))
        sent_p = (sent.param1, sent.param2, sent.param3, sent.param4)
        got_p = (got.param1, got.param2, got.param3, got.param4)
        for k in kept:
            a, b = sent_p[k - 1], got_p[k - 1]
            if self.name == "ardupilot" and sent.command == NAV_WAYPOINT and k == 1 and not math.isnan(a):
                a = float(round(a))
            if not (_feq(a, b) or (math.isnan(a) and b == 0.0)):
                return False
        return True


ARDUPILOT = Flavour("ardupilot", "ArduPilot", mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, home_at_seq0=True,
                    upload_request="MISSION_REQUEST", stored_params=_AP_STORED_PARAMS, alt_resolution_m=0.01,
                    positionless_read_back_as_frame0=True, mission_start_takes_first_item=False,
                    finished_mission_needs_start=True,
                    armable_modes=("GUIDED",), arm_mode="GUIDED")
PX4 = Flavour("px4", "PX4", mavlink.MAV_AUTOPILOT_PX4, home_at_seq0=False,
              upload_request="MISSION_REQUEST_INT", stored_params=_PX4_STORED_PARAMS, latlon_tolerance_e7=1,
              set_current_command=False, upload_restarts_mission=True,
              armable_modes=("AUTO.LOITER",), arm_mode="AUTO.LOITER")
GENERIC = Flavour("generic", "MAVLink vehicle", mavlink.MAV_AUTOPILOT_GENERIC, home_at_seq0=False,
                  upload_request="MISSION_REQUEST_INT")

_BY_AUTOPILOT = {f.mav_autopilot: f for f in (ARDUPILOT, PX4)}
_BY_NAME = {f.name: f for f in (ARDUPILOT, PX4, GENERIC)}


def flavour_for(mav_autopilot: int) -> Flavour:
    """The flavour for HEARTBEAT.autopilot; anything unknown is treated as a generic vehicle
    (no home item, strict read-back comparison)."""
    return _BY_AUTOPILOT.get(mav_autopilot, GENERIC)


def flavour_named(name: str) -> Flavour:
    """'ardupilot', 'px4' or 'generic'; ConfigError otherwise."""
    try:
        return _BY_NAME[name.strip().lower()]
    except KeyError:
        raise ConfigError(f"unknown autopilot {name!r} (expected ardupilot or px4)", key="autopilot") from None
