"""Mission files as real tools write them (tests/data/files, small files written for these tests):
accepted where the reference tools accept them, refused in one sentence where they are not a
mission, converted where QGroundControl converts."""

import json
import math
from pathlib import Path

import pytest

from mission_io import mission_file
from mission_io import plan as P
from mission_io import waypoints as W
from uavloc_gcs import mission as M
from uavloc_gcs.errors import FileFormatError

from .strategies import plans_equal

FILES = Path(__file__).resolve().parents[1] / "data" / "files"


def read(name, **kw):
    return mission_file.read(FILES / name, **kw)[0]


def test_mission_planner_placeholders_are_not_positions():
    m = read("mp_placeholders.waypoints")
    assert [it.command for it in m.items] == [22, 178, 16, 16, 206, 16, 20]
    assert [it.has_position for it in m.items] == [False, False, True, True, False, True, False]
    assert (m.home_lat_deg, m.home_lon_deg, m.home_alt_m) == (47.397742, 8.545594, 488.0)


@pytest.mark.parametrize("name, kind", [("fence_polygon.waypoints", "geofence"), ("fence_circle.waypoints", "geofence"),
                                        ("rally.waypoints", "rally-point")])
def test_fence_and_rally_files_are_refused_in_one_sentence(name, kind):
    with pytest.raises(FileFormatError) as ei:
        read(name)
    msg = str(ei.value)
    assert f"this is a {kind} file, not a mission" in msg and msg.count(".") <= 3 and "\n" not in msg
    assert ei.value.path.endswith(name)


def test_a_fence_item_inside_a_mission_names_its_line():
    with pytest.raises(FileFormatError) as ei:
        read("mixed_fence_item.waypoints")
    assert (ei.value.line, ei.value.field) == (4, "command") and "5001" in str(ei.value)


def test_line_0_that_is_not_home_is_kept_as_the_first_item():
    m = read("line0_takeoff.waypoints")
    assert math.isnan(m.home_lat_deg)
    assert [it.command for it in m.items] == [M.NAV_TAKEOFF, 16, 16, M.NAV_LAND]
    wire = M.to_wire(m, "ardupilot")  # a placeholder home goes in front for ArduPilot
    assert [w.command for w in wire] == [16, 22, 16, 16, 21] and (wire[0].x, wire[0].y) == (0, 0)


def test_header_only_file_is_an_empty_mission():
    m = read("header_only.waypoints")
    assert m.items == () and math.isnan(m.home_lat_deg)
    assert M.to_wire(m, "px4") == []


def test_index_gaps_and_all_zero_indices_are_renumbered_in_file_order():
    gaps = read("index_gaps.waypoints")
    assert [it.command for it in gaps.items] == [22, 16, 16, 20] and gaps.home_lat_deg == 47.397742
    zeros = read("zero_indices.waypoints")
    assert [(it.lat_deg, it.lon_deg) for it in zeros.items] == [(47.3985, 8.5461), (47.3991, 8.5452),
                                                                (47.3983, 8.5444)]
    assert math.isnan(zeros.home_lat_deg)  # a relative-frame waypoint on line 0 is not a home line
    assert [w.seq for w in M.to_wire(zeros, "px4")] == [0, 1, 2]


def test_trailing_tab_is_accepted():
    assert [it.command for it in read("trailing_tab.waypoints").items] == [22, 16, 20]


def test_do_jump_in_a_waypoints_file_keeps_its_ardupilot_seq():
    m = read("do_jump.waypoints")
    jump = m.items[3]
    assert jump.command == M.DO_JUMP and jump.params[:2] == (2.0, 2.0)  # line 2: the first waypoint
    assert M.to_wire(m, "ardupilot")[4].param1 == 2.0
    assert M.to_wire(m, "px4")[3].param1 == 1.0  # PX4 has no home item: seq 1 is that waypoint


def test_do_jump_target_outside_the_mission_names_the_line():
    text = (FILES / "do_jump.waypoints").read_text().replace("177\t2\t2", "177\t9\t2")
    with pytest.raises(FileFormatError) as ei:
        W.loads(text, path="j.waypoints")
    assert (ei.value.line, ei.value.field) == (6, "param1") and "DO_JUMP target 9" in str(ei.value)


def test_qgc4_survey_with_null_coordinates_reads_and_encodes():
    m = read("survey_qgc4.plan")
    cams = [it for it in m.items if it.command == 206]
    assert len(cams) == 4 and all(math.isnan(it.lat_deg) and math.isnan(it.alt_m) for it in cams)
    for ap in ("ardupilot", "px4"):
        wire = M.to_wire(m, ap)
        cam = [w for w in wire if w.command == 206]
        assert all((w.x, w.y, w.z) == (0, 0, 0.0) for w in cam)  # unset, not NaN -> int
    again = P.loads(P.dumps(m))
    assert plans_equal(again, m)  # null positions stay null
    raw = json.loads(P.dumps(m))["mission"]["items"][3]
    assert raw["command"] == 206 and raw["params"][4:] == [None, None, None]


def test_null_positions_survive_a_waypoints_round_trip():
    m = read("survey_qgc4.plan")
    back = W.loads(W.dumps(m), autopilot="px4")
    assert len(back.items) == len(m.items)
    assert all(a.same_as(b) or (math.isnan(a.lat_deg) and math.isnan(b.lat_deg)) for a, b in zip(m.items, back.items))
    assert all(math.isnan(it.lat_deg) for it in back.items if it.command == 206)


def test_older_plan_item_forms_are_converted_like_qgc():
    m = read("older_item_forms.plan")
    takeoff, wp2, wp3, rtl = m.items
    assert (takeoff.command, takeoff.lat_deg, takeoff.lon_deg, takeoff.alt_m) == (22, 47.3979, 8.5457, 30.0)
    assert math.isnan(takeoff.params[3])
    assert (wp3.params, wp3.lat_deg, wp3.alt_m) == ((3.0, 0.0, 0.0, 0.0), 47.3991, 35.0)  # param1..param4 keys
    assert rtl.command == M.NAV_RETURN_TO_LAUNCH and m.autopilot == "ardupilot"


def test_plan_do_jump_is_shifted_for_px4_only():
    m = read("do_jump_px4.plan")
    assert m.items[3].params[:2] == (2.0, 2.0)  # doJumpId 2 -> item 2
    px4, ap = M.to_wire(m, "px4"), M.to_wire(m, "ardupilot")
    assert (px4[3].command, px4[3].param1) == (M.DO_JUMP, 1.0) and px4[1].command == 16
    assert (ap[4].command, ap[4].param1) == (M.DO_JUMP, 2.0) and ap[2].command == 16
    assert M.from_wire(px4, "px4").items[3].params[0] == 2.0  # and back


def test_fences_circles_and_rally_points_round_trip():
    m = read("fences_rally.plan")
    assert [inc for inc, _ in m.geofence_polygons] == [True, False]
    assert m.geofence_circles == ((True, (47.3977, 8.5456), 500.0), (False, (47.3972, 8.547), 25.0))
    assert len(m.rally_points) == 2
    assert plans_equal(P.loads(P.dumps(m)), m)


def test_zero_home_is_no_home():
    m = read("zero_home.plan")
    assert math.isnan(m.home_lat_deg) and math.isnan(m.home_lon_deg)
    assert (M.to_wire(m, "ardupilot")[0].x, M.to_wire(m, "ardupilot")[0].y) == (0, 0)


def test_empty_plan_is_an_empty_mission():
    m = read("empty.plan")
    assert m.items == () and M.to_wire(m, "px4") == [] and len(M.to_wire(m, "ardupilot")) == 1


@pytest.mark.parametrize("name, field, fragments", [
    ("above_terrain_unresolved.plan", "params[6]", ["calculated above terrain", "never resolved", "save it again"]),
    ("legacy.mission", "fileType", ["legacy QGroundControl .mission", "save it again"]),
    ("survey_unexpanded.plan", "TransectStyleComplexItem", ["no pre-expanded waypoints", "save it again"]),
])
def test_files_uavloc_cannot_use_say_what_they_are_and_what_to_do(name, field, fragments):
    with pytest.raises(FileFormatError) as ei:
        read(name)
    assert ei.value.field == field and str(ei.value).startswith(str(FILES / name))
    assert all(f in str(ei.value) for f in fragments), str(ei.value)
    assert "only survey" not in str(ei.value)


def test_unsupported_complex_item_message_does_not_contradict_itself():
    doc = json.loads((FILES / "survey_unexpanded.plan").read_text())
    doc["mission"]["items"][1]["complexItemType"] = "StructureScan"
    with pytest.raises(FileFormatError) as ei:
        P.loads(json.dumps(doc))
    assert "'StructureScan' is not supported" in str(ei.value) and "expanded" not in str(ei.value)


def test_px4_cannot_take_a_null_takeoff_position():
    plan = M.MissionPlan((M.MissionItem(M.NAV_TAKEOFF, 3, (0, 0, 0, math.nan), math.nan, math.nan, 30.0),))
    assert (M.to_wire(plan, "ardupilot")[1].x, M.to_wire(plan, "ardupilot")[1].y) == (0, 0)
    with pytest.raises(M.MissionEncodingError, match="item 1: the position is unset"):
        M.to_wire(plan, "px4")


def test_not_a_mission_file_at_all(tmp_path):
    f = tmp_path / "area.kml"
    f.write_text("<kml/>")
    with pytest.raises(FileFormatError, match="is not a mission file"):
        mission_file.read(f)


def test_mission_planner_placeholders_for_px4_takeoff_at_home_and_refuse_other_places():
    m = read("mp_placeholders.waypoints")
    with pytest.raises(M.MissionEncodingError, match="item 1: lat/lon 0, 0 means \"here\" to ArduPilot"):
        M.to_wire(M.MissionPlan(m.items[:1] + (M.MissionItem(M.NAV_LAND, 3),), autopilot="px4"))
    wire = M.to_wire(m, "px4")  # takeoff (0, 0) goes at the planned home; DO_* and RTL are frameless
    assert (wire[0].command, wire[0].x, wire[0].y) == (M.NAV_TAKEOFF, 473977420, 85455940)
    assert all(w.frame == M.FRAME_MISSION and (w.x, w.y) == (0, 0) for w in wire if w.command in (178, 20))
    land = M.MissionPlan((M.MissionItem(M.NAV_LAND, 3),), 47.0, 8.0, 400.0)
    with pytest.raises(M.MissionEncodingError, match="PX4 would fly to 0 N 0 E"):
        M.to_wire(land, "px4")
    assert (M.to_wire(land, "ardupilot")[1].x, M.to_wire(land, "ardupilot")[1].y) == (0, 0)


def test_location_commands_are_the_dialects_has_location_commands():
    from uavloc_gcs.dialect import mavlink

    assert M.LOCATION_COMMANDS == {k for k, e in mavlink.enums["MAV_CMD"].items() if e.has_location}
