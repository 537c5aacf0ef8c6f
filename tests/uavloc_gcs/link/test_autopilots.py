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
