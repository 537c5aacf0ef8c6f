"""Mission model and its MAVLink encoding: the ArduPilot/PX4 rules, degE7, round trips."""

import math

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from uavloc_gcs import mission as M

HOME = (47.3977, 8.5456)


def _flight(autopilot, **kw):
    return M.flight_mission([(47.3980, 8.5460), (47.3990, 8.5470)], alt_m=60.0, speed_m_s=15.0,
                            autopilot=autopilot, home_latlon_deg=HOME, **kw)


def test_flight_mission_content():
    plan = _flight("px4")
    assert [it.command for it in plan.items] == [M.NAV_TAKEOFF, M.DO_CHANGE_SPEED, M.NAV_WAYPOINT,
                                                 M.NAV_WAYPOINT, M.NAV_RETURN_TO_LAUNCH]
    takeoff, speed, wp, _, rtl = plan.items
    assert (takeoff.lat_deg, takeoff.lon_deg, takeoff.alt_m) == (*HOME, 60.0)
    assert speed.frame == M.FRAME_MISSION and speed.params[:3] == (M.SPEED_TYPE_GROUNDSPEED, 15.0, -1.0)
    assert wp.params[0] == 0.0 and math.isnan(wp.params[3]) and wp.frame == M.FRAME_GLOBAL_RELATIVE_ALT
    assert rtl.frame == M.FRAME_MISSION and not rtl.is_positional
    assert (plan.home_lat_deg, plan.home_lon_deg) == HOME and math.isnan(plan.home_alt_m)
    assert plan.cruise_speed_m_s == 15.0
    bare = _flight("px4", include_takeoff=False, return_home=False)
    assert [it.command for it in bare.items] == [M.DO_CHANGE_SPEED, M.NAV_WAYPOINT, M.NAV_WAYPOINT]


def test_ardupilot_puts_home_at_seq_0():
    wire = M.to_wire(_flight("ardupilot"))
    home = wire[0]
    assert (home.seq, home.frame, home.command) == (0, M.FRAME_GLOBAL, M.NAV_WAYPOINT)
    assert (home.x, home.y) == (473977000, 85456000)
    assert [w.seq for w in wire] == list(range(6))
    assert wire[1].command == M.NAV_TAKEOFF
    assert [w.current for w in wire] == [1, 0, 0, 0, 0, 0]


def test_ardupilot_without_planned_home_sends_a_zero_placeholder():
    plan = M.flight_mission([(47.0, 8.0)], alt_m=50, speed_m_s=10, autopilot="ardupilot")
    home = M.to_wire(plan)[0]
    assert (home.x, home.y, home.z) == (0, 0, 0.0)


def test_px4_has_no_home_and_uses_frame_mission_for_commands():
    plan = _flight("px4")
    wire = M.to_wire(plan)
    assert len(wire) == len(plan.items) and wire[0].command == M.NAV_TAKEOFF and wire[0].current == 1
    by_cmd = {w.command: w for w in wire}
    assert by_cmd[M.DO_CHANGE_SPEED].frame == M.FRAME_MISSION
    assert by_cmd[M.NAV_RETURN_TO_LAUNCH].frame == M.FRAME_MISSION



@pytest.mark.parametrize("command", [M.DO_CHANGE_SPEED, M.NAV_RETURN_TO_LAUNCH, M.DO_JUMP])
def test_mission_planner_style_frames_are_fixed_for_px4(command):
    """Mission Planner writes RTL/DO_CHANGE_SPEED with the plan's frame 3; PX4 needs frame 2."""
    odd = M.MissionPlan((M.MissionItem(command, M.FRAME_GLOBAL_RELATIVE_ALT, (1, 5, -1, 0)),))
    assert M.to_wire(odd, "ardupilot")[1].frame == M.FRAME_GLOBAL_RELATIVE_ALT  # ArduPilot accepts it
    px4 = M.to_wire(odd, "px4")[0]
    assert (px4.frame, px4.x, px4.y) == (M.FRAME_MISSION, 0, 0)


def test_same_plan_encodes_for_either_autopilot():
    plan = _flight("ardupilot")
    ap, px4 = M.to_wire(plan, "ardupilot"), M.to_wire(plan, "px4")
    assert len(ap) == len(px4) + 1
    for a, p in zip(ap[1:], px4):
        assert a.same_as(p)


@pytest.mark.parametrize("deg, e7", [(69.69, 696900000), (-33.8688197, -338688197), (180.0, 1800000000),
                                     (0.00000005, 0), (0.00000015, 2), (-122.4194155, -1224194155)])
def test_degE7(deg, e7):
    assert M.deg_to_e7(deg) == e7
    assert abs(M.e7_to_deg(M.deg_to_e7(deg)) - deg) <= 0.5e-7 + 1e-15


@pytest.mark.parametrize(
    "item, fragment",
    [
        (M.MissionItem(M.NAV_WAYPOINT, params=(math.inf, 0, 0, 0), lat_deg=1, lon_deg=1, alt_m=10), "param1"),
        (M.MissionItem(M.NAV_WAYPOINT, lat_deg=95.0, lon_deg=1.0, alt_m=10), "not a valid lat/lon"),
        (M.MissionItem(M.NAV_WAYPOINT, lat_deg=10.0, lon_deg=-181.0, alt_m=10), "not a valid lat/lon"),
        (M.MissionItem(M.NAV_WAYPOINT, lat_deg=10.0, lon_deg=1.0, alt_m=math.nan), "altitude"),
    ],
)
def test_unencodable_items_raise(item, fragment):
    with pytest.raises(M.MissionEncodingError, match=fragment) as ei:
        M.to_wire(M.MissionPlan((item,)), "px4")
    assert "item 1" in str(ei.value)


def test_unknown_autopilot():
    with pytest.raises(M.MissionEncodingError, match="unknown autopilot"):
        M.to_wire(_flight("px4"), "inav")


lat = st.floats(-90, 90, allow_nan=False)
lon = st.floats(-180, 180, allow_nan=False)
fparam = st.one_of(st.floats(-1e6, 1e6, allow_nan=False, width=32), st.just(math.nan))
positional = st.builds(M.MissionItem, command=st.sampled_from([16, 22, 21, 19]),
                       frame=st.sampled_from([0, 3, 10]), params=st.tuples(fparam, fparam, fparam, fparam),
                       lat_deg=lat, lon_deg=lon, alt_m=st.floats(-100, 5000, width=32), autocontinue=st.booleans())
command = st.builds(M.MissionItem, command=st.sampled_from([178, 20, 183]), frame=st.just(2),
                    params=st.tuples(fparam, fparam, fparam, fparam), autocontinue=st.booleans())


@settings(max_examples=200, deadline=None)
@given(st.lists(st.one_of(positional, command), max_size=10), st.sampled_from(["ardupilot", "px4"]), lat, lon)
def test_wire_round_trip(items, autopilot, hlat, hlon):
    # 0, 0 is ArduPilot's "here"; PX4 refuses it (tests/mission_io/test_real_tool_files.py)
    assume(autopilot == "ardupilot" or not any(M.deg_to_e7(it.lat_deg) == 0 == M.deg_to_e7(it.lon_deg)
                                               for it in items))
    plan = M.MissionPlan(tuple(items), hlat, hlon, 12.5, autopilot=autopilot)
    wire = M.to_wire(plan)
    assert [w.seq for w in wire] == list(range(len(wire)))
    back = M.from_wire(wire, autopilot)
    assert back.same_as(plan)
    if autopilot == "ardupilot":
        assert abs(back.home_lat_deg - hlat) <= 0.5e-7 + 1e-12 and back.home_alt_m == 12.5
    assert all(a.same_as(b) for a, b in zip(M.to_wire(back), wire))


def test_item_same_as_detects_differences():
    a = M.pass_through_waypoint(47.0, 8.0, 50.0)
    assert a.same_as(M.pass_through_waypoint(47.0 + 1e-7, 8.0, 50.0))
    assert not a.same_as(M.pass_through_waypoint(47.0 + 5e-7, 8.0, 50.0))
    assert not a.same_as(M.pass_through_waypoint(47.0, 8.0, 51.0))
    assert not a.same_as(M.MissionItem(M.NAV_WAYPOINT, a.frame, (0.0, 0.0, 0.0, 0.0), 47.0, 8.0, 50.0))  # NaN yaw
