"""Shared fixtures for the mission file tests: MAVSDK's importers without any network.

MAVSDK (pip ``mavsdk`` 4.x, ctypes over libcmavsdk) needs a "system" for its MissionRaw plugin;
we make one by feeding a HEARTBEAT into a ``raw://`` connection.
"""

import pytest

AUTOPILOT_IDS = {"ardupilot": 3, "px4": 12}


@pytest.fixture(scope="module")
def mission_raw():
    """A MissionRaw plugin per autopilot flavour, each bound to a fake system seen via one HEARTBEAT."""
    pytest.importorskip("mavsdk", reason="MAVSDK is in the test extra: pip install -e '.[test]'")
    from mavsdk import ComponentType, Configuration, Mavsdk
    from mavsdk.plugins.mission_raw import MissionRaw
    from pymavlink.dialects.v20 import common as mavlink

    made, plugins = [], {}
    for name, ap in AUTOPILOT_IDS.items():
        mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        heartbeat = mav.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, ap, 0, 0, 0).pack(mav)
        sdk = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
        sdk.add_any_connection("raw://")
        sdk.pass_received_raw_bytes(heartbeat)
        system = sdk.first_autopilot(5.0)
        assert system is not None, "MAVSDK did not see the fake autopilot"
        plugins[name] = MissionRaw(system)
        made.append(sdk)
    yield plugins
    plugins.clear()
    for sdk in made:
        sdk.destroy()
