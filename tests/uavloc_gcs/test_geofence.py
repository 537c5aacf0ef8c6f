"""The scenario's geofence (issue 26 item 4): scan, looks, orbits and the legs between them stay
inside it; a fence that cannot hold the search is refused in one sentence naming the key."""

import json

import numpy as np
import pytest
from shapely.geometry import LineString, Point, Polygon

from uavloc_gcs import geofence, scan
from uavloc_gcs.errors import ConfigError, InfeasibleError
from uavloc_gcs.examples import scenario_path
from uavloc_gcs.scenario import load_scenario
from uavloc_gcs.search.orbit import OrbitLook, look_mission
from uavloc_gcs.search.policy import SearchPolicy

# An L: the field area (1120 m x 640 m, launch at its south-west corner) less its north-east
# quarter, where the team may not fly.
L_XY = np.array([(-10, -10), (1130, -10), (1130, 300), (600, 300), (600, 650), (-10, 650)], float)


def _fenced(xy=L_XY, **area):
    sc = load_scenario(scenario_path("field"))
    return sc.replace(area={"geofence_deg": sc.frame.to_wgs84_latlon(xy).tolist(), **area})


def _legs_inside(fence_xy, route_xy, tol_m=0.5) -> bool:
    return Polygon(fence_xy).buffer(tol_m).covers(LineString(np.asarray(route_xy, float)))


def test_a_scenario_geofence_is_read_and_resolved():
    sc = _fenced()
    f = geofence.for_scenario(sc)
    assert f is not None and f.margin_m == 30.0
    assert np.allclose(f.polygon_xy_m, L_XY, atol=0.05)
    assert geofence.for_scenario(load_scenario(scenario_path("field"))) is None  # none given: none


def test_a_geofence_file_may_be_a_qgc_plan(tmp_path):
    sc = load_scenario(scenario_path("field"))
    ring = sc.frame.to_wgs84_latlon(L_XY).tolist()
    plan = {"fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
            "mission": {"version": 2, "items": [], "plannedHomePosition": ring[0], "cruiseSpeed": 15,
                        "hoverSpeed": 5, "firmwareType": 3, "vehicleType": 2},
            "geoFence": {"version": 2, "circles": [], "polygons": [{"inclusion": True, "polygon": ring,
                                                                      "version": 1}]},
            "rallyPoints": {"version": 2, "points": []}}
    path = tmp_path / "cleared.plan"
    path.write_text(json.dumps(plan))
    fenced = sc.replace(area={"geofence_file": str(path)})
    assert np.allclose(geofence.for_scenario(fenced).polygon_xy_m, L_XY, atol=0.05)


@pytest.mark.parametrize("xy, area, words", [
    (L_XY + 50.0, {}, "the launch point"),  # the launch corner (0, 0) is outside
    (np.array([(-5, -5), (40, -5), (40, 40), (-5, 40)], float), {}, "no part of the search area lies 30 m inside"),
    (L_XY, {"geofence_margin_m": -1.0}, "must be 0-1000 m"),
    (np.array([(-10, -10), (500, 500), (500, -10), (-10, 500)], float), {}, "crosses itself"),
])
def test_a_fence_that_cannot_hold_the_search_is_refused_naming_the_key(xy, area, words):
    with pytest.raises(ConfigError) as exc:
        _fenced(xy, **area)
    text = str(exc.value)
    assert words in text and "area.geofence" in text, text


def test_both_forms_of_geofence_are_refused():
    sc = load_scenario(scenario_path("field"))
    with pytest.raises(ConfigError, match="not both"):
        sc.replace(area={"geofence_deg": sc.frame.to_wgs84_latlon(L_XY).tolist(), "geofence_file": "x.plan"})


def test_the_scan_stays_inside_a_concave_fence_and_the_exported_fence_is_the_scenarios():
    sc = _fenced()
    plan = scan.plan_scan(sc)
    inner = Polygon(L_XY).buffer(-sc.area.geofence_margin_m + 1.0, join_style="mitre")  # within half a metre
    for v in plan.vehicles:
        route = np.vstack([[0.0, 0.0], v.waypoints_xy_m, [0.0, 0.0]])
        assert _legs_inside(L_XY, route), v
        for q in v.waypoints_xy_m:  # every planned point keeps the margin
            assert inner.covers(Point(q)), q
    assert np.allclose(scan.fence_xy_m(sc, plan), geofence.for_scenario(sc).polygon_xy_m)
    # without the fence the same scan flies over the forbidden quarter
    free = scan.plan_scan(load_scenario(scenario_path("field")))
    assert not all(_legs_inside(L_XY, np.vstack([[0.0, 0.0], v.waypoints_xy_m, [0.0, 0.0]])) for v in free.vehicles)


def test_look_points_and_orbit_centres_go_inside_the_fence_by_its_margin():
    sc = _fenced()
    policy = SearchPolicy(sc, seed=0)
    pts = np.array([[900.0, 500.0], [300.0, 300.0], [2000.0, 2000.0], [-400.0, 100.0]])
    out = policy._inside_reach(pts)
    inner = Polygon(L_XY).buffer(-30.0 + 0.01, join_style="mitre")
    for q in out:
        assert inner.covers(Point(q)), q
    assert np.allclose(out[1], pts[1])  # a point already inside stays
    assert out[0][1] == pytest.approx(270.0, abs=0.5)  # the predicted person in the forbidden quarter: its edge
    centre = policy._inside_reach(np.array([[900.0, 500.0]]), inset_m=60.0)[0]
    assert inner.covers(Point(centre).buffer(60.0)), centre  # the whole circle


def test_a_look_mission_goes_around_the_notch_and_home_inside_the_fence():
    sc = _fenced()
    f = geofence.for_scenario(sc)
    looks = np.array([[1000.0, 200.0], [200.0, 550.0], [1050.0, 250.0]])
    lm = look_mission(sc.frame, looks, (1, 2, 3), None, alt_m=100.0, speed_m_s=15.0, autopilot="ardupilot",
                      home_latlon_deg=sc.launch_latlon_deg, start_xy_m=(1000.0, 100.0), fence=f)
    nav = [it for it in lm.plan.items if it.command == 16]
    xy = sc.frame.to_local_xy(np.array([[it.lat_deg, it.lon_deg] for it in nav]))
    route = np.vstack([[1000.0, 100.0], xy, [0.0, 0.0]])
    assert _legs_inside(L_XY, route)
    assert len(nav) > len(looks), "corners were added around the notch"
    assert not _legs_inside(L_XY, np.vstack([[1000.0, 100.0], looks, [0.0, 0.0]]))  # the straight legs cut it
    # each look is where the mission says it is (the daemon counts looks at these items)
    items = lm.plan.items
    got = sc.frame.to_local_xy(np.array([[items[k].lat_deg, items[k].lon_deg] for k in lm.look_items]))
    assert np.allclose(got, lm.look_xy_m, atol=0.05) and np.allclose(lm.look_xy_m, looks, atol=0.5)


def test_an_orbit_that_does_not_fit_inside_the_fence_is_flown_as_a_ring_kept_inside():
    sc = _fenced()
    f = geofence.for_scenario(sc)
    orb = OrbitLook(centre_xy_m=(1000.0, 240.0), radius_m=120.0, speed_m_s=8.0, dwell_s=100.0,
                    form="loiter-turns")
    lm = look_mission(sc.frame, np.array([[1000.0, 240.0]]), (1,), (orb,), alt_m=100.0, speed_m_s=15.0,
                      autopilot="ardupilot", home_latlon_deg=sc.launch_latlon_deg, start_xy_m=(500.0, 100.0),
                      fence=f)
    assert all(it.command != 18 for it in lm.plan.items)  # no NAV_LOITER_TURNS circle leaving the fence
    nav = [it for it in lm.plan.items if it.command == 16]
    xy = sc.frame.to_local_xy(np.array([[it.lat_deg, it.lon_deg] for it in nav]))
    assert _legs_inside(L_XY, np.vstack([[500.0, 100.0], xy, [0.0, 0.0]]))


def test_a_route_that_cannot_stay_inside_is_refused_not_flown():
    # two rooms joined by a corridor narrower than twice the margin: no path keeps the margin
    rooms = np.array([(-10, -10), (300, -10), (300, 200), (320, 200), (320, -10), (700, -10), (700, 300),
                      (320, 300), (320, 230), (300, 230), (300, 300), (-10, 300)], float)
    f = geofence.Geofence(rooms, 30.0)
    with pytest.raises(InfeasibleError, match="geofence"):
        f.detour((100.0, 100.0), (500.0, 100.0))


def test_a_fence_that_is_the_area_moves_the_outer_lanes_in_and_keeps_the_scan_whole():
    """The most common fence is the area itself. The outer lanes run half a metre inside its edge,
    inside the fence but not its margin: they move in by the margin, parallel, instead of being cut
    down to nothing (the first try kept 0.59 of 0.99 km and dropped a vehicle's lane)."""
    sc = load_scenario(scenario_path("field"))
    area = sc.area_xy_m()
    fenced = sc.replace(area={"geofence_deg": sc.frame.to_wgs84_latlon(area).tolist()})
    free, plan = scan.plan_scan(sc), scan.plan_scan(fenced)
    for v0, v in zip(free.vehicles, plan.vehicles):
        assert _legs_inside(area, np.vstack([[0.0, 0.0], v.waypoints_xy_m, [0.0, 0.0]]))
        assert v.length_m > 0.9 * v0.length_m, (v.length_m, v0.length_m)
        legs = np.diff(v.waypoints_xy_m, axis=0)
        lanes = legs[np.abs(legs[:, 0]) > 500.0]  # the lanes run east-west, up to 1,060 m long
        assert len(lanes) >= 1 and np.all(np.abs(lanes[:, 1]) < 1.0), lanes  # and stay so


@pytest.mark.parametrize("value", [20.0, 30.0, float("nan"), 6000.0])
def test_a_default_fence_not_wider_than_the_margin_kept_inside_it_is_refused_in_one_sentence(value):
    sc = load_scenario(scenario_path("field"))
    with pytest.raises(ConfigError) as exc:
        sc.replace(area={"default_geofence_m": value})
    text = str(exc.value)
    assert "area.default_geofence_m" in text and "must be more than area.geofence_margin_m (30 m)" in text, text


def test_without_a_geofence_a_look_mission_stays_within_the_area_plus_the_default_margin():
    """Issue 42 item 5: looks left the field world's area by up to 111 m with no fence set."""
    sc = load_scenario(scenario_path("field"))
    assert geofence.for_scenario(sc) is None
    fence = geofence.flight_fence(sc)
    area = Polygon(sc.area_xy_m())
    far = np.array([[500.0, 900.0], [1400.0, 300.0], [-300.0, -300.0]])  # north, east, south-west of the area
    m = look_mission(sc.frame, far, (1, 2, 3), None, alt_m=40.0, speed_m_s=10.0, autopilot="ardupilot",
                     home_latlon_deg=sc.launch_latlon_deg, start_xy_m=(100.0, 100.0), fence=fence)
    beyond = [area.distance(Point(*p)) for p in m.look_xy_m]
    allowed = sc.area.default_geofence_m - sc.area.geofence_margin_m
    assert max(beyond) <= allowed + 0.5 and min(beyond) > allowed - 5.0, beyond  # moved in, not further
    assert _legs_inside(fence.polygon_xy_m, np.vstack([[100.0, 100.0], m.look_xy_m, [0.0, 0.0]]))
    assert "No geofence given: the search area plus 50 m" in geofence.describe(sc)


def test_the_preview_sentence_says_how_far_the_scan_reaches_beyond_the_default_fence():
    sc = load_scenario(scenario_path("mountains"))
    plan = scan.plan_scan(sc)
    reach = geofence.scan_beyond_m(sc, plan)
    assert reach > 30.0  # its lanes are lengthened past the area's edges to cover them
    assert f"reach up to {reach:.0f} m beyond the area" in geofence.describe(sc, plan)
    field = load_scenario(scenario_path("field"))
    assert "reach up to" not in geofence.describe(field, scan.plan_scan(field))
