"""Our files, read by independent implementations: MAVSDK's importers and pymavlink's mavwp.

MAVSDK (pip ``mavsdk`` 4.x, ctypes over libcmavsdk) needs a "system" for its MissionRaw plugin;
we make one without any network by feeding a HEARTBEAT into a ``raw://`` connection. Its QGC
importer inserts the planned home as seq 0 for ArduPilot (not for PX4); its Mission Planner
importer keeps line 0 as an item and, for ArduPilot, puts its own home item in front of it too.
"""

from pathlib import Path

import pytest
from pymavlink import mavwp

from mission_io import plan as P
from mission_io import waypoints as W
from uavloc_gcs import mission as M
from uavloc_gcs import scan
from uavloc_gcs.scenario import load_scenario

mavsdk = pytest.importorskip("mavsdk", reason="MAVSDK is in the test extra: pip install -e '.[test]'")

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _missions(autopilot):
    sc = load_scenario(EXAMPLES / "small.toml").replace(fleet={"autopilot": autopilot})
    return scan.scan_missions(sc, scan.plan_scan(sc))


def _wire(item) -> M.WireItem:
    return M.WireItem(item.seq, item.frame, item.command, item.current, item.autocontinue, item.param1,
                      item.param2, item.param3, item.param4, item.x, item.y, item.z, item.mission_type)


def _assert_same(theirs, ours):
    assert len(theirs) == len(ours)
    for k, (a, b) in enumerate(zip(theirs, ours)):
        assert a.same_as(b), f"item {k}: MAVSDK {a} != ours {b}"


@pytest.mark.mavsdk
@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_mavsdk_imports_our_plan_with_the_same_items(tmp_path, mission_raw, autopilot):
    mission = _missions(autopilot)[0]
    path = P.write(tmp_path / "uav1.plan", mission)
    data = mission_raw[autopilot].import_qgroundcontrol_mission(str(path))
    theirs = [_wire(it) for it in data.mission_items]
    ours = M.to_wire(mission, autopilot)
    if autopilot == "ardupilot":
        home = theirs.pop(0)
        assert (home.x, home.y, home.z) == (ours[0].x, ours[0].y, 0.0)  # planned home as seq 0
        ours = ours[1:]
    _assert_same(theirs, ours)
    assert [it.seq for it in data.mission_items] == list(range(len(data.mission_items)))
    fence = mission.geofence_polygons[0][1]
    assert [(it.x, it.y) for it in data.geofence_items] == [(M.deg_to_e7(a), M.deg_to_e7(b)) for a, b in fence]


@pytest.mark.mavsdk
@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_mavsdk_imports_our_waypoints_with_the_same_items(tmp_path, mission_raw, autopilot):
    mission = _missions(autopilot)[0]
    path = W.write(tmp_path / "uav1.waypoints", mission)
    data = mission_raw[autopilot].import_mission_planner_mission(str(path))
    theirs = [_wire(it) for it in data.mission_items]
    if autopilot == "ardupilot":
        theirs.pop(0)  # MAVSDK's own home item, in front of our line 0
    line0 = theirs.pop(0)
    assert (line0.command, line0.x, line0.y) == (M.NAV_WAYPOINT, M.deg_to_e7(mission.home_lat_deg),
                                                 M.deg_to_e7(mission.home_lon_deg))
    # Items keep the frames written in the file (no PX4/ArduPilot rewriting in the importer).
    _assert_same(theirs, M.to_wire(mission, "px4"))


@pytest.mark.mavsdk
def test_mavsdk_rejects_a_broken_plan(mission_raw):
    from mavsdk.plugins.mission_raw import MissionRawError

    with pytest.raises(MissionRawError):
        mission_raw["px4"].import_qgroundcontrol_mission_from_string('{"fileType": "Plan"')


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_pymavlink_mavwp_loads_our_waypoints(tmp_path, autopilot):
    mission = _missions(autopilot)[1]
    path = W.write(tmp_path / "uav2.waypoints", mission)
    loader = mavwp.MAVWPLoader()
    assert loader.load(str(path)) == len(mission.items) + 1
    home = loader.wp(0)
    assert (home.seq, home.current, home.frame, home.command) == (0, 1, 0, M.NAV_WAYPOINT)
    assert (home.x, home.y) == (mission.home_lat_deg, mission.home_lon_deg)
    for k, it in enumerate(mission.items, start=1):
        w = loader.wp(k)
        theirs = M.MissionItem(w.command, w.frame, (w.param1, w.param2, w.param3, w.param4), w.x, w.y, w.z,
                               bool(w.autocontinue))
        assert w.seq == k and w.current == 0
        # mavwp keeps float32 MISSION_ITEM fields: equal to float32 precision (~0.5 m in lat/lon).
        assert theirs.same_as(it, latlon_tol_deg=5e-6), f"line {k}: {theirs} != {it}"
