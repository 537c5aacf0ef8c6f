"""Looks at their own height over a DEM (issue 41 item 2): every leg, the descent and the climb
included, keeps terrain.min_clearance_m above the ground plus terrain.obstacle_height_m; a look flies
its height above the ground under it; a vehicle low in the air climbs where it is before it goes on;
the climbs count in the mission's energy."""

from __future__ import annotations

import numpy as np
import pytest

from uavloc_gcs import heights
from uavloc_gcs.errors import InfeasibleError
from uavloc_gcs.mission import NAV_WAYPOINT, ROUTE_COMMANDS
from uavloc_gcs.scenario import load_scenario
from uavloc_gcs.search.orbit import OrbitLook, look_mission
from uavloc_gcs.terrain_missions import TRACK_TOLERANCE_M, clearance_along, climb_energy_j, terrain_safe

from .dems import EXAMPLES
from .test_clearance import east_west_mission, ridge_scenario


@pytest.fixture(scope="module")
def flank():
    """The mountain example with 10 m of trees on the ground: floor 60 + 10 = 70 m."""
    return load_scenario(EXAMPLES / "mountains.toml").replace(terrain={"obstacle_height_m": 10.0})


def _look(sc, alt_m, *, include_takeoff=True, start_xy=(0.0, 0.0), start_alt=None):
    orb = OrbitLook((600.0, 350.0), 70.0, 120.0, 5.0, "ring", alt_m=alt_m)
    return look_mission(sc.frame, [[600.0, 280.0], [300.0, 500.0]], (1, 2), [orb, None], alt_m=sc.fleet.altitude_m,
                        speed_m_s=sc.fleet.speed_m_s, autopilot="ardupilot", home_latlon_deg=sc.launch_latlon_deg,
                        start_xy_m=start_xy, include_takeoff=include_takeoff, look_alts_m=[None, None if alt_m is None else alt_m + 5.0],
                        floor_m=heights.look_floor_m(sc), start_alt_m=start_alt)


def _route(plan, sc):
    """(east, north, height above the DEM) of the route items, in order."""
    its = [it for it in plan.items if it.command in ROUTE_COMMANDS and it.has_position]
    xy = sc.frame.to_local_xy(np.array([[it.lat_deg, it.lon_deg] for it in its]))
    return np.column_stack([xy, [it.alt_m for it in its] - sc.dem.height_xy(xy)])


def test_a_low_look_keeps_the_clearance_over_ground_and_trees_on_every_leg(flank):
    assert heights.look_floor_m(flank) == 70.0
    safe = terrain_safe(_look(flank, 70.0).plan, flank, name="uav1")
    c = clearance_along(safe, flank, step_m=flank.dem.resolution_m / 4)
    assert c.min() >= 70.0 - 0.5, c.min()  # min_clearance 60 m above 10 m of obstacles, the descents included
    r = _route(safe, flank)
    ring = np.abs(np.hypot(r[:, 0] - 600.0, r[:, 1] - 350.0) - 70.0) < 1.0
    assert ring.sum() >= 12
    # the ring flies its 70 m above the ground under it, lifted only where the climb rate asks
    assert np.all(r[ring, 2] >= 70.0 - 0.5) and np.median(r[ring, 2]) < 70.0 + TRACK_TOLERANCE_M
    # the descent and the climb are straight down and up at the entry: two items at one place
    same = np.flatnonzero(np.all(np.abs(np.diff(r[:, :2], axis=0)) < 0.05, axis=1))
    drops = [r[k, 2] - r[k + 1, 2] for k in same]
    assert max(drops) > 20.0 and min(drops) < -20.0, drops  # down to the ring, up from it (and the fly-by)


def test_a_look_below_the_floor_over_the_dem_is_refused_in_one_sentence(flank):
    with pytest.raises(InfeasibleError, match=r"^look 1: a look at 65 m is below the look floor of 70 m; not flown$"):
        _look(flank, 65.0)
    with pytest.raises(InfeasibleError, match=r"at least terrain.min_clearance_m = 60 m over the DEM\); not flown"):
        heights.check_look_alt(flank, 65.0, "the look at P01")


def test_obstacles_raise_the_clearance_every_scan_leg_keeps(tmp_path):
    bare = ridge_scenario(tmp_path)
    trees = ridge_scenario(tmp_path, "obstacle_height_m = 37.0\nmin_clearance_m = 60.0\n")
    a, b = terrain_safe(east_west_mission(bare), bare), terrain_safe(east_west_mission(trees), trees)
    c0 = clearance_along(a, bare, step_m=5.0)
    c1 = clearance_along(b, trees, step_m=5.0)
    # over the ridge the straight legs of the bare plan pass 94 m above the rock, under the trees'
    # 97 m; with the trees stated a waypoint is added there
    assert c0.min() < 97.0 - 0.5 <= c1.min() and len(b.items) > len(a.items), (c0.min(), c1.min())


def test_too_many_obstacles_for_the_scan_height_are_refused_naming_the_key(tmp_path):
    from uavloc_gcs.errors import ConfigError

    with pytest.raises(ConfigError, match=r"terrain.obstacle_height_m.*80 m of obstacles plus terrain.min_clearance_m"
                                          r" = 30 m is more than the scan height fleet.altitude_m = 100 m"):
        ridge_scenario(tmp_path, "obstacle_height_m = 80.0\n")


def test_a_vehicle_low_in_the_air_goes_straight_up_where_it_is_first(flank):
    here = np.array([500.0, 200.0])
    g = flank.dem.height_at(*here) - flank.dem.height_at(0.0, 0.0)
    plain = terrain_safe(_look(flank, 80.0, include_takeoff=False, start_xy=here).plan, flank, name="uav1",
                         start_xy_m=here)
    low = terrain_safe(_look(flank, 80.0, include_takeoff=False, start_xy=here).plan, flank, name="uav1",
                       start_xy_m=here, start_alt_m=g + 72.0)
    assert len(low.items) == len(plain.items) + 1
    r = _route(low, flank)
    assert np.allclose(r[0, :2], here, atol=0.05) and r[0, 2] >= flank.fleet.altitude_m - 0.5  # up where it is
    assert np.allclose(_route(plain, flank), r[1:], atol=1e-6)  # then as planned
    # a vehicle at about the profile's height is not sent up and down again
    level = terrain_safe(_look(flank, 80.0, include_takeoff=False, start_xy=here).plan, flank, name="uav1",
                         start_xy_m=here, start_alt_m=g + r[0, 2] - 3.0)
    assert len(level.items) == len(plain.items)


def test_the_looks_climbs_count_in_the_missions_climb_energy(flank):
    high = terrain_safe(_look(flank, None).plan, flank, name="uav1")
    low = terrain_safe(_look(flank, 70.0).plan, flank, name="uav1")
    extra = climb_energy_j(low, flank) - climb_energy_j(high, flank)
    # two looks climbing back 30 m (the ring at 70 m) and 25 m (the fly-by at 75 m) to the 100 m
    # transit; the ring following the slope 30 m lower climbs with it too (89.7 m in all here)
    w = flank.power_model.weight_n
    assert extra >= w * (30.0 + 25.0) - 1e-6, extra / w
    assert [it.command for it in low.items].count(NAV_WAYPOINT) > [it.command for it in high.items].count(NAV_WAYPOINT)
