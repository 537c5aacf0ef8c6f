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
