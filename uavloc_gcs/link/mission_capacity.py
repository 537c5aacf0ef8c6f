"""How many mission items an autopilot can hold, so a mission too long is refused before a byte of
it is sent (issue 40: a 10,001-item upload was refused by the vehicle, exit 3).

The count is MISSION_COUNT's: the items on the wire, ArduPilot's home at seq 0 included. Two
figures per autopilot: the most any build of it can hold (refused before connecting), and what
common boards hold (named when a vehicle answers MISSION_COUNT with MAV_MISSION_NO_SPACE, which
ArduPilot and PX4 both do before touching the mission they hold).

ArduPilot (master of 2026-03-20, the shared SITL's commit 64a9c78): a mission item takes 15 bytes
of mission storage after a 4-byte header, ``num_commands_max = (size - 4) / 15``
(``libraries/AP_Mission/AP_Mission.cpp``, ``AP_MISSION_EEPROM_COMMAND_SIZE``). StorageManager's
Copter layouts give the mission 2,422 bytes on 4 KB boards, 4,554 on 8 KB, 9,758 on 16 KB and 19,600 on
32 KB (``libraries/StorageManager/StorageManager.cpp``): 161, 303, 650 and 1,306 items. With
``BRD_SD_MISSION`` the mission moves to a file on the SD card of at most 65,535 bytes
(``StorageAccess::attach_file``): 4,368 items, the most any ArduPilot holds. SITL builds are 16 KB
(``libraries/AP_HAL/board/sitl.h``): the shared ArduCopter SITL answered MISSION_COUNT 651 with
NO_SPACE and "Only 650 items are supported", and 650 with a request for item 0 (measured
2026-11-28).

PX4 (main of 2025-07-24, the shared SITL's commit 752ecd3): dataman holds
``CONFIG_NUM_MISSION_ITMES_SUPPORTED`` items (``src/modules/dataman/Kconfig``: 500 by default,
1,000 on 13 boards such as ``px4/fmu-v6x``, 10,000 in SITL, the most of any board's configuration);
``MavlinkMissionManager`` answers a larger MISSION_COUNT with NO_SPACE. The shared PX4 SITL
answered 10,001 with NO_SPACE and 10,000 with a request (measured 2026-11-28).
"""

from __future__ import annotations

from dataclasses import dataclass

MAVLINK_COUNT_MAX = 65535  # MISSION_COUNT.count is a uint16


@dataclass(frozen=True)
class Capacity:
    """``most``: no build of the autopilot holds more items; ``common``: what boards hold;
    ``many`` items and more are refused by ``many_refused_by``."""

    label: str
    most: int
    common: str
    many: int = MAVLINK_COUNT_MAX + 1
    many_refused_by: str = ""


CAPACITY = {
    "ardupilot": Capacity("ArduPilot", 4368,
                          "ArduPilot boards hold 650 items with 16 KB of storage (SITL too), 1,306 with 32 KB, up to "
                          "4,368 with BRD_SD_MISSION on the SD card", 651, "ArduPilot boards with 16 KB of storage "
                          "(and SITL)"),
    "px4": Capacity("PX4", 10_000, "PX4 holds 500 items by default, 1,000 on boards such as Pixhawk 6X, 10,000 in SITL",
                    501, "PX4 builds with the default configuration"),
    "generic": Capacity("MAVLink", MAVLINK_COUNT_MAX, "MAVLink numbers at most 65,535 items"),
}


def too_long(n_items: int, autopilot: str) -> str | None:
    """None when ``n_items`` (on the wire) fits some build of ``autopilot`` ("ardupilot", "px4",
    "generic"); else the sentence saying why it cannot be sent."""
    cap = CAPACITY.get(autopilot, CAPACITY["generic"])
    if n_items <= min(cap.most, MAVLINK_COUNT_MAX):
        return None
    if cap.most >= MAVLINK_COUNT_MAX:
        return (f"{n_items:,} mission items (on the wire) are more than MAVLink's mission protocol can number "
                f"({MAVLINK_COUNT_MAX:,}); split the mission")
    return (f"{n_items:,} mission items (on the wire) are more than any {cap.label} vehicle holds ({cap.most:,}; "
            f"{cap.common}); split the mission")


def many_note(n_items: int, autopilot: str) -> str | None:
    """A sentence when ``n_items`` fit some builds of ``autopilot`` but not common ones, else None."""
    cap = CAPACITY.get(autopilot, CAPACITY["generic"])
    if n_items < cap.many or too_long(n_items, autopilot):
        return None
    return f"{n_items:,} mission items: {cap.many_refused_by} refuse more than {cap.many - 1:,}"


def no_space(n_items: int, autopilot: str, who: str, vehicle_said: str | None) -> str:
    """The sentence for a vehicle (``who``) that answered MISSION_COUNT ``n_items`` with NO_SPACE,
    quoting what it said about it (ArduPilot: "Only 650 items are supported"). Without its words
    the answer may also be a vehicle in its first seconds after boot (ArduCopter SITL does so)."""
    cap = CAPACITY.get(autopilot, CAPACITY["generic"])
    if vehicle_said:
        return (f"{who} has no room for {n_items:,} mission items (it says \"{vehicle_said}\") and keeps the mission "
                f"it had; {cap.common}: split the mission")
    return (f"{who} has no room for {n_items:,} mission items (MISSION_COUNT answered NO_SPACE) and keeps the "
            f"mission it had; {cap.common}: split the mission, or, if it has only just booted, try again in a few "
            "seconds")
