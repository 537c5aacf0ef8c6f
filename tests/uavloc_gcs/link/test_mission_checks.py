"""What each autopilot refuses in an item (link/mission_checks.py), against the same rules the fake
vehicles apply (sim_link/vehicles/mission_server.py, kept to the real autopilots by
tests/sitl/test_behaviours.py): whatever the checker passes, the fake takes; whatever it refuses,
the fake refuses."""

import math

import pytest

from sim_link.vehicles.flavour import ARDUPILOT, PX4
from sim_link.vehicles.mission_server import MissionServer
from uavloc_gcs.link.mission_checks import refusal
from uavloc_gcs.mission import WireItem

NAN = math.nan


def _item(command=16, frame=3, params=(0.0, 0.0, 0.0, NAN), z=50.0, seq=1):
    return WireItem(seq, frame, command, 0, 1, *params, 473977000, 85456000, z)


CASES = [
    _item(),  # a pass-through waypoint, yaw unset
    _item(params=(NAN, 0.0, 0.0, 0.0)),  # hold unset
    _item(params=(0.0, math.inf, 0.0, 0.0)),
    _item(z=83_000.0), _item(z=-83_000.0), _item(z=82_999.0), _item(z=NAN),
    _item(frame=10), _item(frame=11), _item(frame=1), _item(frame=2), _item(frame=0), _item(frame=6),
    _item(command=178, frame=2, params=(1.0, 8.0, -1.0, 0.0), z=0.0),  # DO_CHANGE_SPEED
    _item(command=178, frame=2, params=(NAN, 8.0, -1.0, 0.0), z=0.0),
    _item(command=20, frame=2, params=(0.0, 0.0, 0.0, 0.0), z=0.0),  # RTL
    _item(command=22, params=(0.0, 0.0, 0.0, NAN), z=30.0),  # TAKEOFF, yaw unset
]


@pytest.mark.parametrize("flavour", [ARDUPILOT, PX4], ids=lambda f: f.name)
@pytest.mark.parametrize("k", range(len(CASES)))
def test_the_checker_and_the_fake_agree(flavour, k):
    from uavloc_gcs.dialect import mavlink as mav

    item = CASES[k]
    fake = MissionServer(flavour, 1, lambda: item)._validate(item)
    mine = refusal(item, flavour.name)
    assert (mine is None) == (fake == mav.MAV_MISSION_ACCEPTED), (item, mine, fake)


def test_the_refusal_names_the_field():
    assert refusal(_item(z=1e30), "ardupilot")[0] == "altitude"
    assert refusal(_item(frame=10), "px4") == ("frame", "PX4 takes location items only in frames GLOBAL and "
                                                        "GLOBAL_RELATIVE_ALT (or their _INT forms), not 10 "
                                                        "(GLOBAL_TERRAIN_ALT)")
    assert refusal(_item(command=178, frame=2, params=(NAN, 8.0, -1.0, 0.0), z=0.0), "ardupilot")[0] == "param1"
