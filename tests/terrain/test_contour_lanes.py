"""Over a slope the scan's lanes run along the contours when lanes up and down it would end too
high to hear the valley (the descent limit cannot follow the ground): examples/mountains.toml."""

from __future__ import annotations

import math

import numpy as np

import uavloc_gcs.scan as scan
from uavloc_gcs.scan import plan_scan
from uavloc_gcs.scenario import loads_scenario
from uavloc_gcs.search.coverage import scan_coverage
from uavloc_gcs.terrain_missions import contour_angle, hearing_share

from .dems import EXAMPLES, write_geotiff


def _routes(plan):
    return [np.vstack([np.zeros((1, 2)), v.waypoints_xy_m, np.zeros((1, 2))]) for v in plan.vehicles]


def _mountains():
    return loads_scenario((EXAMPLES / "mountains.toml").read_text(), source=str(EXAMPLES / "mountains.toml"),
                          base_dir=EXAMPLES)


def test_lanes_along_the_contours_keep_the_mountainside_heard_by_two_lanes(monkeypatch):
    sc = _mountains()
    plan = plan_scan(sc)
    share = hearing_share(sc, _routes(plan), need=2, speed_m_s=sc.fleet.speed_m_s)
    assert share >= 0.95, share
    # the shortest scan (east-west lanes, up and down the flank), chosen before: a third of the
    # area out of hearing of two lanes, where the 3 m/s descent leaves the vehicles too high
    monkeypatch.setattr(scan, "_best_over_terrain", lambda _sc, candidates, _need: candidates[0])
    shortest = plan_scan(sc)
    assert shortest.lane_heading_deg == 90.0 and plan.lane_heading_deg != 90.0
    assert hearing_share(sc, _routes(shortest), need=2, speed_m_s=sc.fleet.speed_m_s) < 0.8
    # the planned-coverage yardstick flies the same terrain-following profile
    assert scan_coverage(sc).overall(2) < 0.8


def test_the_planned_coverage_over_terrain_uses_the_profile_the_vehicles_can_fly():
    cov = scan_coverage(_mountains())
    assert cov.overall(1) >= 0.99 and cov.overall(2) >= 0.95


def test_contour_angle_of_a_tilted_plane_and_of_level_ground(tmp_path):
    from pyproj import CRS, Transformer

    lat, lon = 42.63, 13.29
    tr = Transformer.from_crs(CRS.from_epsg(4326), CRS.from_epsg(32633), always_xy=True)
    e0, n0 = tr.transform(lon, lat)
    cells = 100
    x = (np.arange(cells) + 0.5) * 30.0 - 1500.0
    for name, slope_e, slope_n in (("east", 0.3, 0.0), ("diag", 0.2, 0.2), ("flat", 0.0, 0.0)):
        heights = (500.0 + slope_e * x[None, :] + slope_n * (-x)[:, None]).astype(np.float32)
        write_geotiff(tmp_path / f"{name}.tif", heights, west=e0 - 1500.0, north=n0 + 1500.0, cell_x=30.0, cell_y=30.0,
                      crs="EPSG:32633")
        sc = loads_scenario(f"""
[area]
origin_lat_deg = {lat}
origin_lon_deg = {lon}
width_m = 600
height_m = 400
[fleet]
vehicles = 1
altitude_m = 100
speed_m_s = 10
[terrain]
dem = "{name}.tif"
""", source=str(tmp_path / "s.toml"), base_dir=tmp_path)
        angle = contour_angle(sc, sc.area_xy_m())
        if name == "flat":
            assert angle is None
        else:  # across the gradient: north for a slope rising east, north-west for one rising north-east
            want = math.pi / 2 if name == "east" else 3 * math.pi / 4
            assert abs(angle - want) < math.radians(2), math.degrees(angle)
