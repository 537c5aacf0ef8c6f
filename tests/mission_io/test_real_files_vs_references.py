"""Each file of tests/data/files read by uavloc, by pymavlink's ``mavwp`` and by MAVSDK's
importers, compared item by item.

Where the references agree with us the items must match exactly (to the degE7/float32 precision
of the encodings). Where they differ, the test pins the difference and says who follows
QGroundControl (the tool that writes these files):

- MAVSDK sends a DO_JUMP's doJumpId unchanged to PX4; QGroundControl's plan manager subtracts
  one when it drops home (PX4 has no home item), and so do we.
- MAVSDK refuses the older ``.plan`` item form that QGroundControl still converts; we convert.
- Unset (null) x/y of a frameless item: both MAVSDK and we send 0; MAVSDK keeps z NaN, we send
  0, what the autopilots store for an unused field.
- Fence and rally WPL files: mavwp and MAVSDK load their items as if they were a mission; we refuse.
"""

import math
from pathlib import Path

import pytest
from pymavlink import mavwp

from mission_io import mission_file
from uavloc_gcs import mission as M
from uavloc_gcs.errors import FileFormatError

FILES = Path(__file__).resolve().parents[1] / "data" / "files"
WPL = sorted(p.name for p in FILES.glob("*.waypoints"))
PLANS = sorted(p.name for p in FILES.glob("*.plan")) + ["legacy.mission"]
REFUSED = {"fence_polygon.waypoints", "fence_circle.waypoints", "rally.waypoints", "mixed_fence_item.waypoints",
           "above_terrain_unresolved.plan", "survey_unexpanded.plan", "legacy.mission"}


def _ours(name, autopilot="ardupilot"):
    return mission_file.read(FILES / name, autopilot=autopilot)[0]


def _as_item(w) -> M.MissionItem:
    """A reference tool's row (mavwp MISSION_ITEM floats or MAVSDK degE7 ints) as a MissionItem."""
    scale = 1e-7 if isinstance(w.x, int) and w.frame in M.GLOBAL_FRAMES else 1.0
    return M.MissionItem(w.command, w.frame, (w.param1, w.param2, w.param3, w.param4), w.x * scale, w.y * scale,
                         float(w.z), bool(w.autocontinue))


def _same(a: M.MissionItem, b: M.MissionItem) -> bool:
    both_nan = all(math.isnan(v) for v in (a.lat_deg, b.lat_deg)) and all(math.isnan(v) for v in (a.lon_deg, b.lon_deg))
    if both_nan:
        a = M.MissionItem(a.command, a.frame, a.params, 0.0, 0.0, a.alt_m, a.autocontinue)
        b = M.MissionItem(b.command, b.frame, b.params, 0.0, 0.0, b.alt_m, b.autocontinue)
    if math.isnan(a.alt_m) and math.isnan(b.alt_m):
        b = M.MissionItem(b.command, b.frame, b.params, b.lat_deg, b.lon_deg, a.alt_m, b.autocontinue)
    return a.same_as(b, latlon_tol_deg=5e-6) if not math.isnan(a.alt_m) else (
        (a.command, a.frame) == (b.command, b.frame) and math.isnan(b.alt_m))


def _mavwp(name):
    loader = mavwp.MAVWPLoader()
    n = loader.load(str(FILES / name))
    return [loader.wp(k) for k in range(n)]


@pytest.mark.parametrize("name", WPL)
def test_waypoints_files_against_pymavlink_mavwp(name):
    theirs = _mavwp(name)
    assert [w.seq for w in theirs] == list(range(len(theirs)))  # mavwp renumbers too
    if name in REFUSED:
        with pytest.raises(FileFormatError, match="geofence|rally"):
            _ours(name)
        assert any(w.command in M.FENCE_COMMANDS | M.RALLY_COMMANDS for w in theirs)  # mavwp took them as items
        return
    ours = _ours(name)
    has_home = not math.isnan(ours.home_lat_deg) or (theirs and theirs[0].command == 16 and theirs[0].frame == 0)
    rows = theirs[1:] if has_home else theirs
    if has_home and not math.isnan(ours.home_lat_deg):
        assert (theirs[0].x, theirs[0].y) == pytest.approx((ours.home_lat_deg, ours.home_lon_deg), abs=5e-6)
    assert len(rows) == len(ours.items)
    for k, (w, it) in enumerate(zip(rows, ours.items)):
        theirs_item = _as_item(w)
        if it.command == M.DO_JUMP and not has_home:
            assert it.params[0] == w.param1 + 1  # our items count from 1 after a (missing) home
            continue
        assert _same(theirs_item, it), f"{name} item {k + 1}: mavwp {theirs_item} != ours {it}"


@pytest.mark.mavsdk
@pytest.mark.parametrize("name", WPL)
def test_waypoints_files_against_mavsdk(name, mission_raw):
    from mavsdk.plugins.mission_raw import MissionRawError

    try:  # the PX4 flavour: MAVSDK keeps every line, in order, renumbered (no home item of its own)
        theirs = list(mission_raw["px4"].import_mission_planner_mission(str(FILES / name)).mission_items)
    except MissionRawError:
        theirs = None
    if name in REFUSED:
        with pytest.raises(FileFormatError):
            _ours(name)
        assert theirs is not None and any(w.command in M.FENCE_COMMANDS | M.RALLY_COMMANDS for w in theirs)
        return
    assert theirs is not None, f"MAVSDK refused {name}"
    ours = _ours(name)
    assert [w.seq for w in theirs] == list(range(len(theirs)))
    first_is_home = len(theirs) == len(ours.items) + 1
    rows = theirs[1:] if first_is_home else theirs
    assert len(rows) == len(ours.items)
    for k, (w, it) in enumerate(zip(rows, ours.items)):
        assert _same(_as_item(w), it), f"{name} item {k + 1}: MAVSDK {_as_item(w)} != ours {it}"


def _wire(w) -> M.WireItem:
    return M.WireItem(w.seq, w.frame, w.command, w.current, w.autocontinue, w.param1, w.param2, w.param3, w.param4,
                      w.x, w.y, w.z, w.mission_type)


@pytest.mark.mavsdk
@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
@pytest.mark.parametrize("name", PLANS)
def test_plan_files_against_mavsdk(name, autopilot, mission_raw):
    from mavsdk.plugins.mission_raw import MissionRawError

    try:
        data = mission_raw[autopilot].import_qgroundcontrol_mission(str(FILES / name))
    except MissionRawError:
        data = None
    if name == "older_item_forms.plan":
        assert data is None  # MAVSDK does not convert the older form; QGroundControl does, and we do
        assert len(_ours(name).items) == 4
        return
    if name in REFUSED:
        with pytest.raises(FileFormatError):
            _ours(name)
        if name == "above_terrain_unresolved.plan":  # MAVSDK takes it, with an altitude nobody can fly
            assert any(math.isnan(w.z) for w in data.mission_items if w.command == 16)
        else:
            assert data is None
        return
    plan = _ours(name)
    theirs = [_wire(w) for w in data.mission_items]
    ours = M.to_wire(plan, autopilot)
    if autopilot == "ardupilot":  # both put the planned home (or 0, 0) at seq 0
        assert (theirs[0].command, theirs[0].x, theirs[0].y) == (ours[0].command, ours[0].x, ours[0].y)
        theirs, ours = theirs[1:], ours[1:]
    assert len(theirs) == len(ours)
    for a, b in zip(theirs, ours):
        if a.command == M.DO_JUMP and autopilot == "px4":
            assert b.param1 == a.param1 - 1  # QGroundControl's shift for PX4; MAVSDK skips it
            continue
        if b.frame == M.FRAME_MISSION and math.isnan(a.z):
            a = M.WireItem(**{**a.__dict__, "z": 0.0})  # unset z: MAVSDK NaN, we (and the autopilots) 0
        assert a.same_as(b), f"{name}: MAVSDK {a} != ours {b}"
    fence = [(w.command, w.x, w.y, w.param1) for w in data.geofence_items]
    expected = []
    for inc, ring in plan.geofence_polygons:
        expected += [(5001 if inc else 5002, M.deg_to_e7(a), M.deg_to_e7(b), float(len(ring))) for a, b in ring]
    expected += [(5003 if inc else 5004, M.deg_to_e7(a), M.deg_to_e7(b), r) for inc, (a, b), r in plan.geofence_circles]
    assert fence == expected
    assert [(w.x, w.y, w.z) for w in data.rally_items] == [(M.deg_to_e7(a), M.deg_to_e7(b), h)
                                                          for a, b, h in plan.rally_points]
