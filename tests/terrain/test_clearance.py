"""Terrain-safe missions: clearance along every leg, climb limits, refusals, .plan terrain fields."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from mission_io import plan as plan_file
from uavloc_gcs.errors import InfeasibleError
from uavloc_gcs.mission import FRAME_GLOBAL, FRAME_GLOBAL_RELATIVE_ALT, NAV_WAYPOINT, ROUTE_COMMANDS, flight_mission
from uavloc_gcs.scan import plan_scan, scan_missions
from uavloc_gcs.scenario import load_scenario, loads_scenario
from uavloc_gcs.terrain_missions import TRACK_TOLERANCE_M, clearance_along, terrain_safe

from .dems import EXAMPLES, ridge_dem

RIDGE_AREA = """
[area]
origin_lat_deg = 42.63
origin_lon_deg = 13.29
width_m = 800
height_m = 300

[fleet]
vehicles = 1
altitude_m = 100
speed_m_s = 10
"""


def ridge_scenario(tmp_path, extra: str = ""):
    from uavloc_gcs.geo import LocalFrame
    ridge_dem(tmp_path / "ridge.tif", LocalFrame(42.63, 13.29))
    return loads_scenario(RIDGE_AREA + '\n[terrain]\ndem = "ridge.tif"\n' + extra, source=str(tmp_path / "r.toml"),
                          base_dir=tmp_path)


def east_west_mission(sc):
    # launch (0, 0) -> 800 m east over the ridge at 400 m -> home: a flat plan at 100 m
    latlon = sc.frame.to_wgs84_latlon(np.array([[700.0, 150.0], [700.0, 200.0]]))
    return flight_mission(latlon.tolist(), alt_m=100.0, speed_m_s=10.0, autopilot="px4",
                          home_latlon_deg=sc.launch_latlon_deg, home_alt_amsl_m=0.0)


def test_the_mountain_scan_keeps_its_clearance_on_every_leg_sampled_finer_than_the_dem():
    sc = load_scenario(EXAMPLES / "mountains.toml")
    plan = plan_scan(sc)
    for v, m in zip(plan.vehicles, scan_missions(sc, plan)):
        safe = terrain_safe(m, sc, name=f"uav{v.index + 1}")
        c = clearance_along(safe, sc, step_m=sc.dem.resolution_m / 4)
        assert c.min() >= sc.terrain.min_clearance_m - 0.5, (v.index, c.min())
        # and it follows the ground: the flat plan over this slope would be far off
        assert np.median(c) < 250.0
        # every waypoint is absolute (AMSL), and the way home is flown before the RTL
        wps = [it for it in safe.items if it.command in ROUTE_COMMANDS]
        assert {it.frame for it in wps} == {FRAME_GLOBAL}
        assert safe.items[-1].command == 20 and safe.items[-2].command == NAV_WAYPOINT


def test_a_ridge_higher_than_the_flight_altitude_is_climbed_over_within_the_climb_rate(tmp_path):
    sc = ridge_scenario(tmp_path, "min_clearance_m = 50\nmax_climb_m_s = 3\nmax_descent_m_s = 2\n")
    flat = east_west_mission(sc)
    home_g = sc.dem.height_at(0.0, 0.0)
    # the flat plan at 100 m above launch flies into the 300 m ridge
    assert min(clearance_along(flat, sc)) < -150.0
    safe = terrain_safe(flat, sc, name="uav1")
    c = clearance_along(safe, sc, step_m=5.0)
    assert c.min() >= 50.0 - 0.5
    # consecutive waypoints climb no steeper than 3 m/s and descend no steeper than 2 m/s at 10 m/s
    pts = [(*sc.frame.to_local_xy(np.array([[it.lat_deg, it.lon_deg]]))[0], it.alt_m)
           for it in safe.items if it.command in ROUTE_COMMANDS]
    pts = [(0.0, 0.0, safe.items[0].alt_m + home_g)] + pts
    for a, b in zip(pts[:-1], pts[1:]):
        d = math.hypot(b[0] - a[0], b[1] - a[1])
        if d > 1.0:
            assert (b[2] - a[2]) / d <= 3.0 / 10.0 + 1e-4  # altitudes are rounded to the centimetre
            assert (a[2] - b[2]) / d <= 2.0 / 10.0 + 1e-4
    # waypoints were added where the ground rises: more route points than the flat plan's
    assert sum(it.command == NAV_WAYPOINT for it in safe.items) > sum(it.command == NAV_WAYPOINT for it in flat.items) + 2
    assert max(it.alt_m for it in safe.items if it.frame == FRAME_GLOBAL) > home_g + 300.0 + 50.0


def test_a_ridge_above_the_ceiling_is_refused_in_one_sentence_naming_the_leg_and_the_ground(tmp_path):
    sc = ridge_scenario(tmp_path, "max_height_above_launch_m = 250\n")
    with pytest.raises(InfeasibleError) as ei:
        terrain_safe(east_west_mission(sc), sc, name="uav1")
    msg = str(ei.value)
    import re
    # the ridge's crest (800 m, 300 m above the launch point) as the leg's samples see it
    assert re.match(r"uav1: the leg 1 \(launch to waypoint 1\) crosses ground (7[5-9]\d|800) m above sea level", msg)
    assert "\n" not in msg
    assert "m above sea level" in msg and "terrain.max_height_above_launch_m = 250 m" in msg


def test_a_leg_leaving_the_dem_is_refused(tmp_path):
    sc = ridge_scenario(tmp_path)
    latlon = sc.frame.to_wgs84_latlon(np.array([[700.0, 150.0], [5000.0, 150.0]]))
    m = flight_mission(latlon.tolist(), alt_m=100.0, speed_m_s=10.0, autopilot="ardupilot",
                       home_latlon_deg=sc.launch_latlon_deg)
    with pytest.raises(InfeasibleError, match=r"uav2: the leg 2 \(waypoint 1 to waypoint 2\) leaves the DEM ridge\.tif"):
        terrain_safe(m, sc, name="uav2")


def test_relative_altitudes_are_above_the_launch_point_from_the_dem(tmp_path):
    sc = ridge_scenario(tmp_path, 'altitude_frame = "relative"\n')
    safe = terrain_safe(east_west_mission(sc), sc)
    wps = [it for it in safe.items if it.command in ROUTE_COMMANDS]
    assert {it.frame for it in wps} == {FRAME_GLOBAL_RELATIVE_ALT}
    assert max(it.alt_m for it in wps) > 300.0 + 30.0  # over the 300 m ridge, relative to the 500 m launch
    assert clearance_along(safe, sc).min() >= 30.0 - 0.5


def test_without_a_dem_the_mission_is_unchanged():
    sc = load_scenario(EXAMPLES / "paper.toml")
    m = scan_missions(sc, plan_scan(sc))[0]
    assert terrain_safe(m, sc) is m


def test_a_look_without_takeoff_starts_where_the_vehicle_is(tmp_path):
    sc = ridge_scenario(tmp_path)
    latlon = sc.frame.to_wgs84_latlon(np.array([[700.0, 150.0]]))
    m = flight_mission(latlon.tolist(), alt_m=100.0, speed_m_s=10.0, autopilot="px4",
                       home_latlon_deg=sc.launch_latlon_deg, include_takeoff=False)
    safe = terrain_safe(m, sc, start_xy_m=np.array([100.0, 150.0]))
    assert safe.items[0].command == 178  # the speed change stays first
    assert clearance_along(safe, sc).min() >= sc.terrain.min_clearance_m - 0.5


def test_the_plan_file_carries_qgroundcontrol_s_terrain_fields(tmp_path):
    sc = load_scenario(EXAMPLES / "mountains.toml")
    m = terrain_safe(scan_missions(sc, plan_scan(sc))[0], sc, name="uav1")
    p = plan_file.write(tmp_path / "uav1.plan", m)
    doc = json.loads(p.read_text())
    items = doc["mission"]["items"]
    wps = [it for it in items if it["command"] == NAV_WAYPOINT]
    assert wps and all(it["AltitudeMode"] == 3 and it["frame"] == 0 for it in wps)
    for it in wps:
        assert it["AMSLAltAboveTerrain"] == it["params"][6]
        assert sc.terrain.min_clearance_m - TRACK_TOLERANCE_M <= it["Altitude"] < 400.0
    assert doc["mission"]["plannedHomePosition"][2] == pytest.approx(sc.dem.height_at(0, 0), abs=0.01)
    back = plan_file.read(p)
    assert back.same_as(m)


def test_look_points_are_found_among_the_waypoints_terrain_added(tmp_path):
    from uavloc_gcs.mission import to_wire
    from uavloc_gcs.terrain_missions import point_seqs
    sc = ridge_scenario(tmp_path)
    looks = sc.frame.to_wgs84_latlon(np.array([[700.0, 150.0], [100.0, 100.0], [750.0, 250.0]]))
    flat = flight_mission(looks.tolist(), alt_m=100.0, speed_m_s=10.0, autopilot="ardupilot",
                          home_latlon_deg=sc.launch_latlon_deg, include_takeoff=False)
    safe = terrain_safe(flat, sc, start_xy_m=np.array([50.0, 50.0]))
    wire = to_wire(safe, "ardupilot")
    seqs = point_seqs(wire, looks)
    assert len(seqs) == 3 and list(seqs) == sorted(seqs)
    assert seqs[1] - seqs[0] > 1  # waypoints over the ridge between the first two looks
    for s, (lat, lon) in zip(seqs, looks):
        assert abs(wire[s].x - round(lat * 1e7)) <= 0 and abs(wire[s].y - round(lon * 1e7)) <= 0
    # flat: the look points are consecutive, as the daemon's count of passed looks assumes
    assert point_seqs(to_wire(flat, "ardupilot"), looks) == (2, 3, 4)


def test_a_mission_with_a_jump_is_refused_rather_than_checked_wrongly(tmp_path):
    import dataclasses
    from uavloc_gcs.mission import DO_JUMP, FRAME_MISSION, MissionItem
    sc = ridge_scenario(tmp_path)
    m = east_west_mission(sc)
    jump = MissionItem(DO_JUMP, FRAME_MISSION, (3.0, 2.0, 0.0, 0.0))
    looped = dataclasses.replace(m, items=m.items[:-1] + (jump,) + m.items[-1:])
    with pytest.raises(InfeasibleError, match=r"^uav1: the mission has a DO_JUMP"):
        terrain_safe(looped, sc, name="uav1")
