"""QGroundControl .plan: structure QGC requires, lossless round trips, malformed input."""

import json
import math

import pytest
from hypothesis import given, settings

from mission_io import plan as P
from uavloc_gcs import mission as M
from uavloc_gcs.errors import FileFormatError

from .strategies import plans, plans_equal


def _mission(autopilot="ardupilot"):
    m = M.flight_mission([(47.1, 8.1), (47.2, 8.2)], alt_m=80.0, speed_m_s=12.5, autopilot=autopilot,
                         home_latlon_deg=(47.0, 8.0))
    return M.MissionPlan(m.items, m.home_lat_deg, m.home_lon_deg, m.home_alt_m, autopilot=autopilot,
                         cruise_speed_m_s=12.5, hover_speed_m_s=5.0,
                         geofence_polygons=((True, ((47.0, 8.0), (47.3, 8.0), (47.3, 8.3))),),
                         rally_points=((47.05, 8.05, 30.0),))


def test_written_plan_has_every_key_qgc_requires():
    doc = json.loads(P.dumps(_mission("px4")))
    assert doc["fileType"] == "Plan" and doc["version"] == 1 and isinstance(doc["groundStation"], str)
    assert doc["geoFence"]["version"] == 2 and doc["geoFence"]["circles"] == []
    assert doc["geoFence"]["polygons"][0] == {"inclusion": True, "version": 1,
                                              "polygon": [[47.0, 8.0], [47.3, 8.0], [47.3, 8.3]]}
    assert doc["rallyPoints"] == {"points": [[47.05, 8.05, 30]], "version": 2}
    m = doc["mission"]
    assert m["version"] == 2 and m["firmwareType"] == 12 and m["vehicleType"] == 2
    assert m["cruiseSpeed"] == 12.5 and m["hoverSpeed"] == 5 and m["globalPlanAltitudeMode"] == 1
    assert m["plannedHomePosition"] == [47.0, 8.0, None]  # unknown AMSL altitude -> null
    takeoff, speed, wp1, wp2, rtl = m["items"]
    assert [it["doJumpId"] for it in m["items"]] == [1, 2, 3, 4, 5]
    assert all(it["type"] == "SimpleItem" and it["autoContinue"] is True for it in m["items"])
    assert wp1["params"] == [0, 0, 0, None, 47.1, 8.1, 80]  # hold 0: pass through; yaw NaN -> null
    assert wp1["frame"] == 3 and wp1["Altitude"] == 80 and wp1["AltitudeMode"] == 1
    assert "AMSLAltAboveTerrain" in wp1 and wp1["AMSLAltAboveTerrain"] is None
    assert speed["command"] == 178 and speed["frame"] == 2 and speed["params"][:2] == [1, 12.5]
    assert "Altitude" not in speed and "Altitude" not in rtl
    assert rtl["command"] == 20


def test_output_is_deterministic_and_sorted():
    a, b = P.dumps(_mission()), P.dumps(_mission())
    assert a == b and a.endswith("\n")
    assert list(json.loads(a)) == sorted(json.loads(a))


@settings(max_examples=150, deadline=None)
@given(plans())
def test_round_trip_is_exact(plan):
    back = P.loads(P.dumps(plan))
    assert plans_equal(back, plan)
    assert P.dumps(back) == P.dumps(plan)


def test_read_write_files(tmp_path):
    p = P.write(tmp_path / "m.plan", _mission())
    assert plans_equal(P.read(p), _mission())
    assert [f.name for f in tmp_path.iterdir()] == ["m.plan"]


def test_do_jump_refers_to_do_jump_id():
    doc = json.loads(P.dumps(_mission()))
    items = doc["mission"]["items"]
    for k, it in enumerate(items):
        it["doJumpId"] = 100 + k
    items.insert(4, {"type": "SimpleItem", "command": 177, "frame": 2, "autoContinue": True, "doJumpId": 200,
                     "params": [102, 3, 0, 0, 0, 0, 0]})
    plan = P.loads(json.dumps(doc))
    jump = plan.items[4]
    assert jump.command == M.DO_JUMP and jump.params[:2] == (3.0, 3.0)  # item 3 (the first waypoint)


def test_survey_complex_item_is_expanded():
    doc = json.loads(P.dumps(_mission()))
    wp = doc["mission"]["items"][2]
    doc["mission"]["items"][2] = {"type": "ComplexItem", "complexItemType": "survey", "version": 5,
                                  "TransectStyleComplexItem": {"Items": [wp, wp]}}
    plan = P.loads(json.dumps(doc))
    assert [it.command for it in plan.items] == [22, 178, 16, 16, 16, 20]


def _doc():
    return json.loads(P.dumps(_mission()))


def _set(path, value):
    def edit(doc):
        node = doc
        for k in path[:-1]:
            node = node[k]
        if value is _DEL:
            del node[path[-1]]
        else:
            node[path[-1]] = value
        return doc
    return edit


_DEL = object()
ITEM = ("mission", "items", 2)


@pytest.mark.parametrize(
    "edit, item, field, fragment",
    [
        (_set(("fileType",), "Mission"), None, "fileType", "legacy QGroundControl .mission file"),
        (_set(("fileType",), "GeoFence"), None, "fileType", "must be \"Plan\""),
        (_set(("version",), 2), None, "version", "must be 1"),
        (_set(("groundStation",), _DEL), None, "groundStation", "missing"),
        (_set(("mission",), []), None, "mission", "not an object"),
        (_set(("mission", "version"), 1), None, "mission.version", "must be 2"),
        (_set(("mission", "firmwareType"), 8), None, "mission.firmwareType", "ArduPilot"),
        (_set(("mission", "plannedHomePosition"), [1, 2]), None, "mission.plannedHomePosition", "3 entries"),
        (_set(("mission", "plannedHomePosition"), [1, "x", 3]), None, "mission.plannedHomePosition", "number"),
        (_set(("mission", "items"), {}), None, "mission.items", "not a list"),
        (_set(("mission", "cruiseSpeed"), -3), None, "mission.cruiseSpeed", "positive"),
        (_set(("mission", "items", 2), 7), 3, "mission.items", "object"),
        (_set(ITEM + ("type",), "Waypoint"), 3, "type", "SimpleItem"),
        (_set(ITEM + ("command",), "16"), 3, "command", "whole number"),
        (_set(ITEM + ("frame",), _DEL), 3, "frame", "whole number"),
        (_set(ITEM + ("autoContinue",), 1), 3, "autoContinue", "true or false"),
        (_set(ITEM + ("params",), [0, 0, 0, 0, 47, 8]), 3, "params", "exactly 7"),
        (_set(ITEM + ("params", 1), "fast"), 3, "params[1]", "number"),
        (_set(ITEM + ("params", 4), None), 3, "params[4]", "latitude"),
        (_set(ITEM + ("params", 4), 91.0), 3, "params[4]", "outside -90..90"),
        (_set(ITEM + ("params", 5), 181.0), 3, "params[5]", "outside -180..180"),
        (_set(ITEM + ("doJumpId",), "a"), 3, "doJumpId", "whole number"),
        (_set(("mission", "items", 2), {"type": "ComplexItem", "complexItemType": "StructureScan"}), 3,
         "complexItemType", "not supported"),
        (_set(("geoFence",), _DEL), None, "geoFence", "QGroundControl requires it"),
        (_set(("geoFence", "polygons", 0, "polygon"), [[1, 2]]), None, "geoFence.polygons[0].polygon", "at least 3"),
        (_set(("geoFence", "polygons", 0, "inclusion"), "yes"), None, "geoFence.polygons[0].inclusion", "true"),
        (_set(("geoFence", "polygons", 0, "polygon", 1), [95, 8]), None, "geoFence.polygons[0].polygon",
         "valid lat/lon"),
        (_set(("rallyPoints",), _DEL), None, "rallyPoints", "QGroundControl requires it"),
        (_set(("rallyPoints", "points", 0), [1, 2]), None, "rallyPoints.points[0]", "[lat, lon, alt]"),
    ],
)
def test_malformed_plan_names_file_item_and_field(edit, item, field, fragment):
    text = json.dumps(edit(_doc()))
    with pytest.raises(FileFormatError) as ei:
        P.loads(text, path="uav1.plan")
    err = ei.value
    assert str(err).startswith("uav1.plan")
    assert err.field == field and err.item == item
    assert fragment in str(err)


def test_bad_do_jump_target():
    doc = _doc()
    doc["mission"]["items"].append({"type": "SimpleItem", "command": 177, "frame": 2, "autoContinue": True,
                                    "params": [42, 1, 0, 0, 0, 0, 0]})
    with pytest.raises(FileFormatError, match="item 6, field 'params\\[0\\]': DO_JUMP target 42"):
        P.loads(json.dumps(doc), path="x.plan")


def test_not_json_names_the_line(tmp_path):
    f = tmp_path / "broken.plan"
    f.write_text('{\n  "fileType": "Plan",\n  oops\n}')
    with pytest.raises(FileFormatError) as ei:
        P.read(f)
    assert ei.value.line == 3 and "not valid JSON" in str(ei.value) and str(f) in str(ei.value)


@pytest.mark.parametrize("make", [lambda d: d / "missing.plan", lambda d: d])
def test_unreadable_paths(tmp_path, make):
    with pytest.raises(FileFormatError, match="not found|directory"):
        P.read(make(tmp_path))


def test_geofence_circles_are_kept_through_a_round_trip():
    doc = _doc()
    doc["geoFence"]["circles"] = [{"circle": {"center": [47, 8], "radius": 100}, "inclusion": True, "version": 1},
                                  {"circle": {"center": [47.5, 8.25], "radius": 12.5}, "inclusion": False,
                                   "version": 1}]
    plan = P.loads(json.dumps(doc), path="c.plan")
    assert plan.geofence_circles == ((True, (47.0, 8.0), 100.0), (False, (47.5, 8.25), 12.5))
    again = json.loads(P.dumps(plan))["geoFence"]["circles"]
    assert again == doc["geoFence"]["circles"]


def test_nan_home_altitude_is_null_not_nan():
    text = P.dumps(M.MissionPlan((), math.nan, math.nan, math.nan))
    assert "NaN" not in text and '"plannedHomePosition": [\n            null' in text


QGC_STYLE = """{
    "fileType": "Plan",
    "geoFence": {"circles": [], "polygons": [], "version": 2},
    "groundStation": "QGroundControl",
    "mission": {
        "cruiseSpeed": 15, "firmwareType": 12, "globalPlanAltitudeMode": 1, "hoverSpeed": 5,
        "items": [
            {"AMSLAltAboveTerrain": null, "Altitude": 40, "AltitudeMode": 1, "autoContinue": true,
             "command": 22, "doJumpId": 1, "frame": 3, "params": [0, 0, 0, null, 46.5, 7.25, 40],
             "type": "SimpleItem"},
            {"AMSLAltAboveTerrain": null, "Altitude": 40, "AltitudeMode": 1, "autoContinue": true,
             "command": 16, "doJumpId": 2, "frame": 3,
             "params": [0, 0, 0, null, 46.50123456789012, 7.251234567890123, 40], "type": "SimpleItem"},
            {"autoContinue": true, "command": 20, "doJumpId": 3, "frame": 2, "params": [0, 0, 0, 0, 0, 0, 0],
             "type": "SimpleItem"}
        ],
        "plannedHomePosition": [46.5, 7.25, 512.3], "vehicleType": 2, "version": 2
    },
    "rallyPoints": {"points": [], "version": 2},
    "version": 1
}"""


def test_reads_a_plan_as_qgroundcontrol_writes_it():
    plan = P.loads(QGC_STYLE, path="qgc.plan")
    assert plan.autopilot == "px4" and plan.cruise_speed_m_s == 15 and plan.hover_speed_m_s == 5
    assert (plan.home_lat_deg, plan.home_lon_deg, plan.home_alt_m) == (46.5, 7.25, 512.3)
    assert [it.command for it in plan.items] == [22, 16, 20]
    wp = plan.items[1]
    assert (wp.lat_deg, wp.lon_deg, wp.alt_m) == (46.50123456789012, 7.251234567890123, 40.0)
    assert math.isnan(wp.params[3]) and wp.frame == M.FRAME_GLOBAL_RELATIVE_ALT
    assert P.loads(P.dumps(plan)).same_as(plan)
