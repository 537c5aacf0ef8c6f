"""Initial scan: coverage by sampling, lane spacing, balance, energy, missions."""

import itertools
import math
from pathlib import Path

import numpy as np
import pytest
import shapely
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from shapely.geometry import Polygon

from uavloc_gcs import mission as M
from uavloc_gcs import scan
from uavloc_gcs.energy import path_length_m, route_cost
from uavloc_gcs.errors import ConfigError, InfeasibleError
from uavloc_gcs.scenario import load_scenario, loads_scenario, scenario_from_dict

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

U_SHAPE = """
name = "u"
[area]
polygon_deg = [[42.6250, 13.2830], [42.6250, 13.2950], [42.6340, 13.2950], [42.6340, 13.2910],
               [42.6280, 13.2910], [42.6280, 13.2870], [42.6340, 13.2870], [42.6340, 13.2830]]
[fleet]
vehicles = 3
"""

ACUTE = """
name = "acute"
[area]
polygon_deg = [[47.0000, 8.0000], [47.0020, 8.0140], [47.0060, 8.0030], [47.0035, 8.0045]]
[fleet]
vehicles = 2
"""

ROTATED = """
name = "rotated"
[area]
origin_lat_deg = 47.0
origin_lon_deg = 8.0
width_m = 900
height_m = 420
heading_deg = 30
[launch]
lat_deg = 46.9990
lon_deg = 8.0020
[fleet]
vehicles = 3
"""


GEOJSON_AREA = f"""
name = "amatrice"
[area]
polygon_file = "{(EXAMPLES / 'amatrice_area.geojson').as_posix()}"
[fleet]
vehicles = 3
"""


def _scenarios():
    out = {p.stem: load_scenario(p) for p in sorted(EXAMPLES.glob("*.toml"))}
    for text in (U_SHAPE, ACUTE, ROTATED, GEOJSON_AREA):
        sc = loads_scenario(text)
        out[sc.name] = sc
    return out


SCENARIOS = _scenarios()


def _samples(sc, n=20000, seed=0):
    poly = Polygon(sc.area_xy_m())
    x0, y0, x1, y1 = poly.bounds
    p = np.random.default_rng(seed).uniform([x0, y0], [x1, y1], (n, 2))
    inside = p[shapely.contains_xy(poly, p[:, 0], p[:, 1])]
    ring = poly.exterior
    edge = np.array([ring.interpolate(t, normalized=True).coords[0] for t in np.linspace(0, 1, 400)])
    return np.vstack([inside, edge, sc.area_xy_m()])


@pytest.mark.parametrize("name", sorted(SCENARIOS))
@pytest.mark.parametrize("coverage, need", [("double", 2), ("single", 1)])
def test_every_point_is_heard_from_enough_lanes(name, coverage, need):
    sc = SCENARIOS[name].replace(scan={"coverage": coverage})
    plan = scan.plan_scan(sc)
    lanes = [seg for v in plan.vehicles for seg in v.lanes_xy_m]
    counts = scan.coverage_counts(_samples(sc), lanes, sc.horizontal_range_m)
    assert counts.min() >= need, f"{(counts < need).sum()} sample points heard from fewer than {need} lanes"


def test_coverage_counter_detects_a_gap():
    lanes = [np.array([[0.0, 0.0], [100.0, 0.0]])]
    counts = scan.coverage_counts(np.array([[50.0, 10.0], [50.0, 30.0], [120.0, 0.0]]), lanes, 20.0)
    assert counts.tolist() == [1, 0, 1]


def test_lane_spacing_defaults_and_override():
    sc = SCENARIOS["paper"]
    r = sc.horizontal_range_m
    double = scan.plan_scan(sc)
    single = scan.plan_scan(sc.replace(scan={"coverage": "single"}))
    assert double.coverage == "double" and double.lane_spacing_m <= r
    assert r < single.lane_spacing_m <= math.sqrt(2) * r + 1e-9
    fixed = scan.plan_scan(sc.replace(scan={"lane_spacing_m": 60.0}))
    assert fixed.lane_spacing_m <= 60.0
    assert sum(len(v.lanes_xy_m) for v in fixed.vehicles) > sum(len(v.lanes_xy_m) for v in double.vehicles)


@pytest.mark.parametrize("coverage, spacing", [("double", 120.0), ("single", 230.0)])
def test_too_wide_lane_spacing_is_a_config_error(coverage, spacing):
    sc = SCENARIOS["paper"].replace(scan={"coverage": coverage, "lane_spacing_m": spacing})
    with pytest.raises(ConfigError, match="scan.lane_spacing_m"):
        scan.plan_scan(sc)


@pytest.mark.parametrize("name", ["paper", "polygon", "rotated"])
def test_routes_start_and_end_at_launch_and_costs_add_up(name):
    sc = SCENARIOS[name]
    plan = scan.plan_scan(sc)
    assert [v.index for v in plan.vehicles] == list(range(sc.fleet.vehicles))
    for v in plan.vehicles:
        assert len(v.waypoints_xy_m) >= 2
        route = v.route_xy_m()
        assert np.allclose(route[0], 0) and np.allclose(route[-1], 0)
        rc = route_cost(route, sc.fleet.speed_m_s)
        assert v.length_m == pytest.approx(path_length_m(route))
        assert v.duration_s == pytest.approx(rc.duration_s)
        assert v.energy_j == pytest.approx(rc.energy_j)
        # Every lane is flown: both ends of each lane are consecutive waypoints.
        for seg in v.lanes_xy_m:
            k = np.nonzero(np.all(np.isclose(v.waypoints_xy_m, seg[0]), axis=1))[0]
            assert len(k) and np.allclose(v.waypoints_xy_m[k[0] + 1], seg[1])


@pytest.mark.parametrize("name", ["paper", "polygon", "u"])
def test_subareas_tile_the_area(name):
    sc = SCENARIOS[name]
    plan = scan.plan_scan(sc)
    area = Polygon(sc.area_xy_m())
    parts = [Polygon(p) for v in plan.vehicles for p in v.subarea_parts_xy_m]
    assert sum(p.area for p in parts) == pytest.approx(area.area, rel=1e-6)
    for a, b in itertools.combinations(parts, 2):
        assert a.intersection(b).area < 1e-3


def test_partition_is_the_best_contiguous_split():
    rng = np.random.default_rng(3)
    n, m = 7, 3
    cost = np.triu(rng.uniform(1, 10, (n, n)).cumsum(axis=1))
    cost[np.tril_indices(n, -1)] = np.inf
    groups = scan._partition(cost, m)
    got = max(cost[i, j] for i, j in groups)
    best = math.inf
    for used in range(1, m + 1):  # a vehicle may stay idle
        for cuts in itertools.combinations(range(1, n), used - 1):
            bounds = (0, *cuts, n)
            best = min(best, max(cost[bounds[k], bounds[k + 1] - 1] for k in range(used)))
    assert got == pytest.approx(best)
    assert [g[0] for g in groups][0] == 0 and groups[-1][1] == n - 1


def test_split_balances_flight_time_from_launch():
    """Farther sub-areas get less scanning so that flight times (with transit) are close."""
    plan = scan.plan_scan(SCENARIOS["small"].replace(fleet={"vehicles": 3}, scan={"lane_spacing_m": 40.0}))
    times = [v.duration_s for v in plan.vehicles]
    assert max(times) / min(times) < 1.25
    far = max(plan.vehicles, key=lambda v: np.min(np.linalg.norm(v.waypoints_xy_m, axis=1)))
    near = min(plan.vehicles, key=lambda v: np.min(np.linalg.norm(v.waypoints_xy_m, axis=1)))
    lane_len = lambda v: sum(np.linalg.norm(s[1] - s[0]) for s in v.lanes_xy_m)  # noqa: E731
    assert lane_len(far) < lane_len(near)


def test_more_vehicles_than_lanes_still_shortens_the_scan():
    sc = SCENARIOS["small"]
    few, many = scan.plan_scan(sc), scan.plan_scan(sc.replace(fleet={"vehicles": 12}))
    assert 1 <= len(many.vehicles) <= 12
    assert [v.index for v in many.vehicles] == list(range(len(many.vehicles)))
    assert many.makespan_s < few.makespan_s


def test_serpentine_split_balances_to_the_metre():
    """The paper area: four vehicles, flights equal (cut mid-lane where needed)."""
    plan = scan.plan_scan(SCENARIOS["paper"])
    lengths = [v.length_m for v in plan.vehicles]
    assert max(lengths) - min(lengths) < 1.0
    # Better than the best split into whole lanes (132 s for this area).
    assert plan.makespan_s < 130.0


def test_energy_budget_exceeded_says_so_with_numbers():
    sc = SCENARIOS["paper"].replace(fleet={"energy_budget_j": 20000.0})
    with pytest.raises(InfeasibleError) as ei:
        scan.plan_scan(sc)
    msg = str(ei.value)
    assert "uav" in msg and "17.0 kJ" in msg and "kJ for its" in msg and "fleet.vehicles" in msg


def test_plan_is_deterministic():
    a, b = scan.plan_scan(SCENARIOS["u"]), scan.plan_scan(SCENARIOS["u"])
    for va, vb in zip(a.vehicles, b.vehicles):
        assert np.array_equal(va.waypoints_xy_m, vb.waypoints_xy_m)


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_scan_missions_content(autopilot):
    sc = SCENARIOS["small"].replace(fleet={"autopilot": autopilot})
    plan = scan.plan_scan(sc)
    missions = scan.scan_missions(sc, plan)
    assert len(missions) == len(plan.vehicles)
    for v, m in zip(plan.vehicles, missions):
        cmds = [it.command for it in m.items]
        n = len(v.waypoints_xy_m)
        assert cmds == [M.NAV_TAKEOFF, M.DO_CHANGE_SPEED] + [M.NAV_WAYPOINT] * n + [M.NAV_RETURN_TO_LAUNCH]
        assert m.items[1].params[1] == sc.fleet.speed_m_s
        assert all(it.params[0] == 0.0 and it.alt_m == sc.fleet.altitude_m for it in m.waypoints())
        assert (m.home_lat_deg, m.home_lon_deg) == sc.launch_latlon_deg
        assert m.autopilot == autopilot
        latlon = np.array([[it.lat_deg, it.lon_deg] for it in m.waypoints()])
        assert np.allclose(sc.frame.to_local_xy(latlon), v.waypoints_xy_m, atol=1e-6)
        (inclusion, fence), = m.geofence_polygons
        assert inclusion
        fence_xy = sc.frame.to_local_xy(np.array(fence))
        assert not Polygon(fence_xy).exterior.is_ccw  # clockwise, as QGC writes fences


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_geofence_holds_the_area_and_every_route_with_margin(name):
    """PX4 rejects missions with waypoints outside the fence; ArduPilot would breach it."""
    sc = SCENARIOS[name]
    plan = scan.plan_scan(sc)
    (_, fence), = scan.scan_missions(sc, plan)[0].geofence_polygons
    poly = Polygon(sc.frame.to_local_xy(np.array(fence)))
    assert poly.is_valid and len(fence) <= 40  # autopilots hold a few dozen fence vertices
    assert poly.buffer(1e-6).contains(Polygon(sc.area_xy_m()))
    for v in plan.vehicles:
        for p in v.route_xy_m():
            assert poly.contains(shapely.Point(p).buffer(scan.FENCE_MARGIN_M - 1e-3))


@st.composite
def star_polygons(draw):
    """Random simple (star-shaped, often concave) polygons of 4-9 vertices, 300-1500 m across."""
    n = draw(st.integers(4, 9))
    gaps = np.array(draw(st.lists(st.floats(0.3, 1.0), min_size=n, max_size=n)))
    angles = draw(st.floats(0, 1)) + 2 * math.pi * np.cumsum(gaps) / gaps.sum()  # no spikes
    radii = np.array(draw(st.lists(st.floats(150, 650), min_size=n, max_size=n)))
    return np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])


@settings(max_examples=15, deadline=None)
@given(star_polygons(), st.integers(1, 4), st.sampled_from(["double", "single"]))
def test_random_areas_are_covered_and_tiled(xy, vehicles, coverage):
    poly = Polygon(xy)
    assume(poly.is_valid and poly.area > 5e4 and min(np.ptp(xy, axis=0)) > 100)
    frame = SCENARIOS["paper"].frame
    latlon = frame.to_wgs84_latlon(xy + [400.0, 300.0])
    sc = scenario_from_dict({"area": {"polygon_deg": latlon.tolist()}, "launch": {
        "lat_deg": SCENARIOS["paper"].launch_latlon_deg[0], "lon_deg": SCENARIOS["paper"].launch_latlon_deg[1]},
        "fleet": {"vehicles": vehicles}, "scan": {"coverage": coverage}})
    plan = scan.plan_scan(sc)
    lanes = [seg for v in plan.vehicles for seg in v.lanes_xy_m]
    need = 2 if coverage == "double" else 1
    assert scan.coverage_counts(_samples(sc, n=4000), lanes, sc.horizontal_range_m).min() >= need
    parts = [Polygon(p) for v in plan.vehicles for p in v.subarea_parts_xy_m]
    assert sum(p.area for p in parts) == pytest.approx(Polygon(sc.area_xy_m()).area, rel=1e-6)
