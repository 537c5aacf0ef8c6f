"""The ArduPilot/PX4 registry: modes both ways, and what each autopilot stores of an item."""

import dataclasses
import math

import pytest

from uavloc_gcs.dialect import mavlink as M
from uavloc_gcs.link import ARDUPILOT, PX4, flavour_for, flavour_named
from uavloc_gcs.link.autopilots import ARDUCOPTER_MODES, ARDUPLANE_MODES, GENERIC, PX4_MODES
from uavloc_gcs.mission import WireItem

WP = WireItem(1, 3, 16, 0, 1, 0.0, 0.0, 0.0, math.nan, 473977420, 85455940, 30.123)


def test_registry_is_keyed_by_heartbeat_autopilot():
    assert flavour_for(M.MAV_AUTOPILOT_ARDUPILOTMEGA) is ARDUPILOT
    assert flavour_for(M.MAV_AUTOPILOT_PX4) is PX4
    assert flavour_for(M.MAV_AUTOPILOT_GENERIC) is GENERIC
    assert flavour_named(" PX4 ") is PX4


@pytest.mark.parametrize("name", list(ARDUCOPTER_MODES))
def test_ardupilot_copter_modes_round_trip(name):
    p1, custom, _ = ARDUPILOT.mode_params(name, M.MAV_TYPE_QUADROTOR)
    assert p1 == M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    assert ARDUPILOT.mode_name(int(custom), M.MAV_TYPE_QUADROTOR) == name


def test_plane_modes_differ_from_copter():
    assert ARDUPILOT.mode_params("AUTO", M.MAV_TYPE_FIXED_WING)[1] == ARDUPLANE_MODES["AUTO"] == 10
    assert ARDUPILOT.mode_params("AUTO", M.MAV_TYPE_QUADROTOR)[1] == 3


@pytest.mark.parametrize("name", list(PX4_MODES))
def test_px4_modes_round_trip_through_custom_mode(name):
    _, main, sub = PX4.mode_params(name)
    assert PX4.mode_name(int(main) << 16 | int(sub) << 24) == name


def test_generic_mode_names_map_per_autopilot():
    assert PX4.mode_params("AUTO")[1:] == (4.0, 4.0)  # AUTO.MISSION
    assert PX4.mode_params("RTL")[1:] == (4.0, 5.0)
    assert ARDUPILOT.mode_params("RTL")[1] == 6


def test_ardupilot_read_back_rules():
    # Copter keeps only the hold time of a waypoint (whole seconds), altitude in cm, frames as non-INT numbers
    stored = dataclasses.replace(WP, frame=3, param4=0.0, z=30.12)
    assert ARDUPILOT.stored_equal(WP, stored)
    assert not PX4.stored_equal(WP, stored)
    assert not ARDUPILOT.stored_equal(WP, dataclasses.replace(stored, x=WP.x + 1))
    assert not ARDUPILOT.stored_equal(WP, dataclasses.replace(stored, z=30.2))
    assert ARDUPILOT.stored_equal(dataclasses.replace(WP, param1=2.4), dataclasses.replace(stored, param1=2.0))
    assert not ARDUPILOT.stored_equal(dataclasses.replace(WP, param1=3.0), dataclasses.replace(stored, param1=2.0))


def test_px4_ignores_pass_radius_but_keeps_the_rest():
    got = dataclasses.replace(WP, frame=6, param3=0.0)
    assert PX4.stored_equal(dataclasses.replace(WP, param3=5.0), got)
    assert not PX4.stored_equal(dataclasses.replace(WP, param2=5.0), got)
    assert GENERIC.stored_equal(WP, WP) and not GENERIC.stored_equal(dataclasses.replace(WP, param3=5.0), WP)


def test_px4_may_round_positions_back_by_one_unit_but_no_more():
    assert PX4.stored_equal(WP, dataclasses.replace(WP, x=WP.x - 1, y=WP.y + 1))
    assert not PX4.stored_equal(WP, dataclasses.replace(WP, x=WP.x - 2))
    assert not ARDUPILOT.stored_equal(WP, dataclasses.replace(WP, x=WP.x - 1, param4=0.0))


def test_mode_tables_are_complete_where_uavloc_meets_them():
    # ArduCopter mode.h up to TURTLE; 27 is what a Copter reports in AUTO_RTL (DO_LAND_START return)
    assert ARDUCOPTER_MODES["AUTO_RTL"] == 27 and ARDUPILOT.mode_name(27) == "AUTO_RTL"
    assert sorted(ARDUCOPTER_MODES.values()) == [0, 1, 2, 3, 4, 5, 6, 7, 9, 11, 13] + list(range(14, 29))
    assert ARDUPILOT.mode_name(26, M.MAV_TYPE_FIXED_WING) == "AUTOLAND"
    assert sorted(ARDUPLANE_MODES.values()) == [0, 1, 2, 3, 4, 5, 6, 7, 8] + list(range(10, 27))
    # PX4 sub-modes are told apart, and an unknown POSCTL sub-mode still reads as POSCTL
    orbit = (3 << 16) | (1 << 24)
    assert PX4.mode_name(orbit) == "POSCTL.ORBIT"
    assert PX4.mode_name((3 << 16) | (7 << 24)) == "POSCTL"
    assert PX4.mode_name((4 << 16) | (12 << 24)) == "AUTO.EXTERNAL2"
    assert PX4.mode_name((4 << 16) | (7 << 24)) == "PX4(4.7)"


def test_ardupilot_returns_items_without_a_location_in_frame_0():
    speed = WireItem(2, 2, 178, 0, 1, 1.0, 10.0, -1.0, 0.0, 0, 0, 0.0)
    held = dataclasses.replace(speed, frame=0)
    assert ARDUPILOT.stored_equal(speed, held)
    assert not PX4.stored_equal(speed, held)  # PX4 returns frame 2 as sent
    assert not ARDUPILOT.stored_equal(speed, dataclasses.replace(held, param2=12.0))
    # a waypoint in frame 0 is a different (absolute) altitude: still a difference
    assert not ARDUPILOT.stored_equal(WP, dataclasses.replace(WP, frame=0))


def test_downloads_are_saved_in_qgc_form():
    from uavloc_gcs.link import qgc_form
    px4 = [WireItem(0, 6, 22, 0, 1, 0.0, 0.0, 0.0, math.nan, 1, 2, 30.0),
           WireItem(1, 2, 178, 0, 1, 1.0, 10.0, -1.0, 0.0, 0, 0, 0.0)]
    ap = [WireItem(0, 0, 16, 0, 1, 0.0, 0.0, 0.0, 0.0, 1, 2, 900.0),
          WireItem(1, 0, 20, 0, 1, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0), dataclasses.replace(WP, seq=2)]
    assert [it.frame for it in qgc_form(px4)] == [3, 2]
    assert [it.frame for it in qgc_form(ap)] == [0, 2, 3]  # home stays absolute
