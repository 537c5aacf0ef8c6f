"""Looks at their own height (issue 41 item 2; search/look_mission.py, mission.flight_mission): the
descent at the entry, the look flown at its height, the climb back, the floor, both autopilots'
encodings, the file round trips -- and, with no height asked, the very missions of before."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from mission_io import plan as plan_file
from mission_io import waypoints as wpl_file
from uavloc_gcs import geofence
from uavloc_gcs.errors import InfeasibleError
from uavloc_gcs.examples import scenario_path
from uavloc_gcs.mission import (DO_CHANGE_SPEED, NAV_RETURN_TO_LAUNCH, NAV_WAYPOINT, MissionEncodingError,
                                flight_mission, from_wire, to_wire)
from uavloc_gcs.scenario import load_scenario
from uavloc_gcs.search.orbit import OrbitLook, look_mission, orbit_speed_m_s

GOLDEN = Path(__file__).resolve().parents[2] / "data" / "look_missions_before_heights.json"
L_XY = np.array([(-10, -10), (1130, -10), (1130, 300), (600, 300), (600, 650), (-10, 650)], float)


@pytest.fixture(scope="module")
def field():
    return load_scenario(scenario_path("field"))


def _wp_rows(plan, frame):
    """(east, north, alt) of every NAV_WAYPOINT in order."""
    wps = [it for it in plan.items if it.command == NAV_WAYPOINT]
    xy = frame.to_local_xy(np.array([[it.lat_deg, it.lon_deg] for it in wps]))
    return np.column_stack([xy, [it.alt_m for it in wps]])


def missions_without_heights():
    """The missions of uavloc's builders for a fixed set of looks, none asking a height: fly-bys,
    rings, NAV_LOITER_TURNS, points after the looks, a geofence with a notch, an airborne start.
    Only the public API of before issue 41 is used, so main's code can write the golden file."""
    sc = load_scenario(scenario_path("field"))
    fenced = sc.replace(area={"geofence_deg": sc.frame.to_wgs84_latlon(L_XY).tolist()})
    f = geofence.for_scenario(fenced)
    out = {}
    ring = OrbitLook((300.0, 200.0), 100.0, 200.0, orbit_speed_m_s("ring", 100.0, 25.0), "ring")
    loit = OrbitLook((700.0, 400.0), 90.0, 150.0, orbit_speed_m_s("loiter-turns", 90.0, 25.0), "loiter-turns")
    pts = [[100.0, 0.0], [300.0, 100.0], [700.0, 310.0], [900.0, 500.0], [950.0, 100.0]]
    for ap in ("ardupilot", "px4"):
        lm = look_mission(sc.frame, pts, (1, 2, 3), [None, ring, loit], alt_m=100.0, speed_m_s=25.0, autopilot=ap,
                          home_latlon_deg=sc.launch_latlon_deg, start_xy_m=(20.0, 30.0))
        out[f"looks {ap}"] = lm
        lm = look_mission(fenced.frame, [[1000.0, 200.0], [200.0, 550.0], [1050.0, 250.0]], (1, 2, 3),
                          [None, None, ring], alt_m=100.0, speed_m_s=15.0, autopilot=ap,
                          home_latlon_deg=fenced.launch_latlon_deg, start_xy_m=(1000.0, 100.0), fence=f,
                          include_takeoff=False)
        out[f"fenced {ap}"] = lm
        out[f"flight {ap}"] = flight_mission(sc.frame.to_wgs84_latlon(np.array(pts)).tolist(), alt_m=100.0,
                                             speed_m_s=25.0, autopilot=ap, home_latlon_deg=sc.launch_latlon_deg)
    return out


def _canonical(out) -> dict:
    rows = {}
    for name, m in out.items():
        plan = getattr(m, "plan", m)
        rows[name] = {
            "items": [[it.command, it.frame, *[None if np.isnan(p) else round(p, 9) for p in it.params],
                       round(it.lat_deg, 10), round(it.lon_deg, 10), round(it.alt_m, 6)] for it in plan.items],
            "look_items": list(getattr(m, "look_items", ())),
            "look_xy_m": np.round(getattr(m, "look_xy_m", np.zeros((0, 2))), 6).tolist(),
        }
    return rows


def test_with_no_height_asked_the_missions_are_those_of_before():
    """tests/data/look_missions_before_heights.json was written by main's code of 2026-11-28
    (9a84237) with this module's missions_without_heights (UAVLOC_REGEN_GOLDEN=1 with main's code
    on PYTHONPATH rewrites it)."""
    got = _canonical(missions_without_heights())
    if os.environ.get("UAVLOC_REGEN_GOLDEN"):
        GOLDEN.write_text(json.dumps(got, indent=1) + "\n")
    assert got == json.loads(GOLDEN.read_text())


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_a_ring_at_30_m_descends_at_its_entry_and_climbs_back_there(field, autopilot):
    orb = OrbitLook((300.0, 200.0), 60.0, 100.0, orbit_speed_m_s("ring", 60.0, 10.0), "ring", alt_m=30.0)
    lm = look_mission(field.frame, [[300.0, 140.0], [600.0, 100.0]], (1, 2), [orb, None], alt_m=100.0,
                      speed_m_s=10.0, autopilot=autopilot, home_latlon_deg=field.launch_latlon_deg,
                      start_xy_m=(0.0, 0.0), look_alts_m=[None, 45.0], floor_m=30.0)
    assert lm.look_alt_m == (30.0, 45.0)
    rows = _wp_rows(lm.plan, field.frame)
    entry = lm.look_xy_m[0]
    # arrive above the entry at 100 m, straight down to 30 m, the ring at 30 m back to the entry, up to 100 m
    assert np.allclose(rows[0], [*entry, 100.0], atol=0.05) and np.allclose(rows[1], [*entry, 30.0], atol=0.05)
    ring = rows[2:2 + orb.turns * 12]
    assert np.all(ring[:, 2] == 30.0)
    assert np.allclose(np.hypot(ring[:, 0] - 300.0, ring[:, 1] - 200.0), 60.0, atol=0.05)
    up = rows[2 + orb.turns * 12]
    assert np.allclose(up, [*entry, 100.0], atol=0.05) and np.allclose(ring[-1, :2], entry, atol=0.05)
    # the fly-by at 45 m: above it at 100 m, down, up, then home at 100 m
    assert np.allclose(rows[-3:], [[600.0, 100.0, 100.0], [600.0, 100.0, 45.0], [600.0, 100.0, 100.0]], atol=0.05)
    # the look is reported where it begins: arriving above its entry at the transit altitude
    items = lm.plan.items
    assert [items[k].alt_m for k in lm.look_items] == [100.0, 100.0]
    # the orbit speed is asked after the descent, the cruise speed again before the climb
    kinds = [(it.command, it.alt_m) for it in items]
    k_slow = next(i for i, it in enumerate(items) if it.command == DO_CHANGE_SPEED and it.params[1] < 9.0)
    assert kinds[k_slow - 1] == (NAV_WAYPOINT, 30.0)
    wire = to_wire(lm.plan, autopilot)
    assert wire[-1].command == NAV_RETURN_TO_LAUNCH  # the vehicle comes home without uavloc
    assert (wire[0].seq, wire[0].frame) == ((0, 0) if autopilot == "ardupilot" else (0, 3))  # AP's home / PX4's takeoff
    assert from_wire(wire, autopilot).same_as(lm.plan)


def test_loiter_turns_at_a_height(field):
    orb = OrbitLook((300.0, 200.0), 60.0, 100.0, orbit_speed_m_s("loiter-turns", 60.0, 10.0), "loiter-turns",
                    alt_m=40.0)
    lm = look_mission(field.frame, [[300.0, 140.0]], (1,), [orb], alt_m=100.0, speed_m_s=10.0,
                      autopilot="ardupilot", home_latlon_deg=field.launch_latlon_deg, start_xy_m=(0.0, 0.0),
                      floor_m=30.0)
    got = [(it.command, it.alt_m) for it in lm.plan.items[2:-1]]
    assert got == [(NAV_WAYPOINT, 100.0), (NAV_WAYPOINT, 40.0), (18, 40.0), (NAV_WAYPOINT, 100.0)]
    assert lm.plan.items[lm.look_items[0]].alt_m == 100.0


def test_a_look_below_the_floor_is_refused_in_one_sentence(field):
    orb = OrbitLook((300.0, 200.0), 60.0, 100.0, 5.0, "ring", alt_m=20.0)
    with pytest.raises(InfeasibleError, match=r"^look 1: a look at 20 m is below the look floor of 30 m; not flown$"):
        look_mission(field.frame, [[300.0, 140.0]], (1,), [orb], alt_m=100.0, speed_m_s=10.0, autopilot="px4",
                     home_latlon_deg=field.launch_latlon_deg, floor_m=30.0)
    # without a floor nothing may go below the transit altitude
    with pytest.raises(InfeasibleError, match="below the transit altitude 100 m and no look floor was given"):
        look_mission(field.frame, [[300.0, 140.0]], (1,), None, alt_m=100.0, speed_m_s=10.0, autopilot="px4",
                     home_latlon_deg=field.launch_latlon_deg, look_alts_m=[50.0])
    with pytest.raises(MissionEncodingError, match="point 2: a look at 10 m is below the look floor of 30 m"):
        flight_mission([[42.62, 13.28], [42.63, 13.29]], alt_m=100.0, speed_m_s=10.0, autopilot="px4",
                       point_alts_m=[None, 10.0], floor_m=30.0)
    with pytest.raises(MissionEncodingError, match="1 look heights for 2 points"):
        flight_mission([[42.62, 13.28], [42.63, 13.29]], alt_m=100.0, speed_m_s=10.0, autopilot="px4",
                       point_alts_m=[40.0], floor_m=30.0)


def test_the_scenario_floor_obstacles_and_the_airborne_floor(field):
    from uavloc_gcs import heights

    # no look height asked: looks fly the survey altitude, and the airborne floor is half of it (the rule of before)
    assert heights.look_floor_m(field) == 30.0 and heights.airborne_floor_m(field) == 50.0
    assert heights.airborne_floor_m(field.replace(search={"look_height_m": 30.0})) == 15.0
    sc = field.replace(search={"look_min_height_m": 25.0}, terrain={"obstacle_height_m": 12.0})
    assert heights.look_floor_m(sc) == 37.0 and heights.airborne_floor_m(sc) == 50.0
    assert heights.airborne_floor_m(sc.replace(search={"look_height_m": 37.0})) == 18.5
    with pytest.raises(InfeasibleError, match=r"below the look floor of 37 m above the ground \(search.look_min_height_m"
                                              r" = 25 m above terrain.obstacle_height_m = 12 m\); not flown"):
        heights.check_look_alt(sc, 36.0, "the look at P03")
    low = field.replace(fleet={"altitude_m": 20.0})  # a survey below the look floor is flown as it is
    assert heights.airborne_floor_m(low) == 10.0


@pytest.mark.parametrize("value, words", [
    (29.0, "between the look floor of 30 m"),
    (120.0, "and the survey altitude fleet.altitude_m = 100 m, got 120"),
    (float("nan"), "got nan"),
])
def test_a_look_height_off_the_floor_or_above_the_survey_is_refused_naming_the_key(field, value, words):
    from uavloc_gcs.errors import ConfigError

    with pytest.raises(ConfigError, match=f"search.look_height_m.*{words}"):
        field.replace(search={"look_height_m": value})


def test_the_policys_orbits_are_planned_at_the_look_height_and_pay_its_descent_and_climb(field):
    """search.look_height_m: plan_orbit's look carries the height, its radius is that height's
    D-optimal one (a circle nearer the person), and orbit_targets add the descent and climb to the
    look's service time and energy; with no height asked the look is the survey altitude's."""
    from uavloc_gcs import heights
    from uavloc_gcs.planning.problem import Target
    from uavloc_gcs.search import SearchPolicy
    from uavloc_gcs.search.orbit import orbit_targets, plan_orbit

    high = plan_orbit(field, (300.0, 200.0), 40.0)
    low_sc = field.replace(search={"look_height_m": 30.0})
    low = plan_orbit(low_sc, (300.0, 200.0), 40.0)
    assert high.alt_m is None and low.alt_m == 30.0
    assert low.radius_m < high.radius_m
    assert plan_orbit(field.replace(search={"look_height_m": 100.0}), (300.0, 200.0), 40.0) == high

    def served(sc):
        pol = SearchPolicy(sc)
        (t,) = orbit_targets(pol, 0.0, [Target("7", (300.0, 200.0))])
        return t, pol._orbit_plan[7]

    (t_hi, o_hi), (t_lo, o_lo) = served(field), served(low_sc)
    assert o_hi.alt_m is None and t_hi.service_s == o_hi.flown_s  # as before: the turns alone
    assert o_lo.alt_m == 30.0
    down_up = 70 / 1.5 + 70 / 2.5
    assert t_lo.service_s == pytest.approx(o_lo.flown_s + down_up)
    assert t_lo.service_energy_j == pytest.approx(
        low_sc.power_model.power_w(o_lo.speed_m_s) * o_lo.flown_s + heights.vertical_energy_j(low_sc, 30.0))


@pytest.mark.parametrize("key, value, words", [
    ("search", {"look_min_height_m": 0.0}, "search.look_min_height_m.*must be a positive height"),
    ("terrain", {"obstacle_height_m": -1.0}, "terrain.obstacle_height_m.*0 or more"),
    ("search", {"look_min_height_m": 150.0}, "beyond the communication range fleet.comm_range_m = 150 m"),
])
def test_bad_floors_are_refused_naming_the_key(field, key, value, words):
    from uavloc_gcs.errors import ConfigError

    with pytest.raises(ConfigError, match=words):
        field.replace(**{key: value})


def test_time_and_energy_of_the_descent_and_climb(field):
    from uavloc_gcs import heights

    # 70 m down at 1.5 m/s and up at 2.5 m/s, hovering at P(0) = 168.48 W, plus W dh = 20 N x 70 m
    assert heights.vertical_s(field, 30.0) == pytest.approx(70 / 1.5 + 70 / 2.5)
    e = heights.vertical_energy_j(field, 30.0)
    assert e == pytest.approx(168.48 * (70 / 1.5 + 70 / 2.5) + 20.0 * 70.0, rel=1e-3)
    assert heights.vertical_s(field, None) == 0.0 == heights.vertical_energy_j(field, 100.2)


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_missions_with_heights_round_trip_through_plan_and_waypoints_files(field, autopilot, tmp_path):
    orb = OrbitLook((300.0, 200.0), 60.0, 100.0, 5.0, "ring", alt_m=35.5)
    lm = look_mission(field.frame, [[300.0, 140.0], [600.0, 100.0]], (1, 2), [orb, None], alt_m=100.0,
                      speed_m_s=10.0, autopilot=autopilot, home_latlon_deg=field.launch_latlon_deg,
                      look_alts_m=[None, 62.25], floor_m=30.0)
    plan_file.write(tmp_path / "m.plan", lm.plan)
    wpl_file.write(tmp_path / "m.waypoints", lm.plan)
    a = plan_file.read(tmp_path / "m.plan")
    b = wpl_file.read(tmp_path / "m.waypoints", autopilot=autopilot)
    assert a.same_as(lm.plan) and b.same_as(lm.plan)
    assert sorted({it.alt_m for it in a.items if it.command == NAV_WAYPOINT}) == [35.5, 62.25, 100.0]


def test_a_vehicle_low_in_its_orbit_goes_on_with_it_and_one_low_elsewhere_climbs_first(field):
    orb = OrbitLook((300.0, 200.0), 60.0, 100.0, 5.0, "ring", alt_m=30.0)
    on_circle = (360.0, 200.0)
    lm = look_mission(field.frame, [[360.0, 200.0]], (1,), [orb], alt_m=100.0, speed_m_s=10.0, autopilot="px4",
                      home_latlon_deg=field.launch_latlon_deg, start_xy_m=on_circle, include_takeoff=False,
                      floor_m=30.0, start_alt_m=31.0)
    rows = _wp_rows(lm.plan, field.frame)
    assert rows[0, 2] == 30.0 and np.all(rows[:-1, 2] == 30.0) and rows[-1, 2] == 100.0  # no climb out and back
    far = look_mission(field.frame, [[600.0, 100.0]], (1,), None, alt_m=100.0, speed_m_s=10.0, autopilot="px4",
                       home_latlon_deg=field.launch_latlon_deg, start_xy_m=on_circle, include_takeoff=False,
                       floor_m=30.0, start_alt_m=31.0)
    rows = _wp_rows(far.plan, field.frame)
    assert np.allclose(rows[0], [*on_circle, 100.0], atol=0.05)  # straight up where it is, then on
    assert far.plan.items[far.look_items[0]].alt_m == 100.0 and np.allclose(rows[1, :2], [600.0, 100.0], atol=0.05)
