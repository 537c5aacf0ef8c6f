"""Terrain in the pictures: hillshade and contours in the scan preview and result.png."""

from __future__ import annotations

import numpy as np

from uavloc_gcs.render.estimates import result_figure
from uavloc_gcs.render.maps import save_figure
from uavloc_gcs.render.scan_plot import scan_figure
from uavloc_gcs.render.terrain import contour_interval_m
from uavloc_gcs.scan import plan_scan
from uavloc_gcs.scenario import load_scenario

from .dems import EXAMPLES


def _legend_texts(fig):
    return [t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()]


def test_contour_intervals_are_round_and_few():
    assert contour_interval_m(480.0) == 50.0
    assert contour_interval_m(9.0) == 1.0
    assert contour_interval_m(2500.0) == 250.0


def test_the_preview_and_the_result_show_the_ground_only_with_a_dem(tmp_path):
    sc = load_scenario(EXAMPLES / "mountains.toml")
    fig = scan_figure(sc, plan_scan(sc))
    assert any("50 m contours" in t for t in _legend_texts(fig))
    ax = fig.axes[0]
    assert len(ax.images) == 1  # the hillshade
    shade = ax.images[0].get_array()
    assert np.ptp(shade) > 0.2  # a real relief, not a flat grey
    save_figure(fig, tmp_path / "preview.png")
    assert (tmp_path / "preview.png").stat().st_size > 20_000

    area = sc.area_xy_m()
    track = {1: np.array([[0.0, 0.0], [500.0, 300.0]])}
    res = result_figure([], area_xy_m=area, tracks_xy_m=track, terrain=sc.dem)
    assert any("contours" in t for t in _legend_texts(res))
    flat = load_scenario(EXAMPLES / "small.toml")
    assert not any("contours" in t for t in _legend_texts(scan_figure(flat, plan_scan(flat))))
    assert not any("contours" in t for t in _legend_texts(result_figure([], area_xy_m=area, tracks_xy_m=track)))


def test_the_live_map_gets_contour_lines_only_with_a_dem(tmp_path):
    from uavloc_gcs.service.store import Store
    from uavloc_gcs.service.web import MapFeed

    sc = load_scenario(EXAMPLES / "mountains.toml")
    s = Store(tmp_path / "search.sqlite", commit_interval_s=0.01)
    s.flush()
    try:
        terrain = MapFeed(sc, s.path).static()["terrain"]
        flat = MapFeed(load_scenario(EXAMPLES / "small.toml"), s.path).static()["terrain"]
    finally:
        s.close()
    assert flat is None
    assert terrain["interval_m"] in (50.0, 100.0) and len(terrain["lines"]) >= 5
    levels = {c["level_m"] for c in terrain["lines"]}
    assert {1100.0, 1200.0, 1300.0, 1400.0, 1500.0} <= levels
    assert sum(len(c["xy_m"]) for c in terrain["lines"]) <= 4000 + len(terrain["lines"])
    # a contour's vertices lie on its level: the DEM there reads the level to a metre or two
    c = next(c for c in terrain["lines"] if c["level_m"] == 1300.0)
    z = sc.dem.height_xy(np.array(c["xy_m"]))
    assert np.nanmax(np.abs(z - 1300.0)) < 5.0
