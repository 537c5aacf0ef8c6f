"""Shared map helpers: every helper draws, output is deterministic, PNG/SVG by suffix."""

import numpy as np
import pytest
from matplotlib.image import imread

from uavloc_gcs.render import maps


def _figure():
    fig, ax = maps.new_map("Test map", subtitle=maps.origin_caption(-33.9, -70.1))
    maps.draw_area(ax, np.array([[0, 0], [500, 0], [500, 300], [0, 300]]))
    maps.draw_polygons(ax, [np.array([[0, 0], [250, 0], [250, 300], [0, 300]])], labels=["part 1"])
    maps.draw_polylines(ax, [np.array([[0, 10], [490, 10], [490, 120], [0, 120]]),
                             np.array([[0, 200], [490, 200]])], labels=["uav1", "uav2"])
    maps.draw_points(ax, np.array([[100, 100], [300, 250]]), label="people", annotations=["p1", "p2"])
    maps.draw_circles(ax, np.array([[100, 100], [300, 250]]), [20.0, 35.0], label="95 % radius")
    maps.draw_circles(ax, np.array([[50, 50]]), 15.0, label="95 % radius")  # duplicate label
    maps.draw_launch(ax)
    length = maps.add_scale_bar(ax)
    maps.add_north_arrow(ax)
    maps.add_legend(ax)
    return fig, ax, length


def test_helpers_draw_everything_and_dedupe_the_legend():
    fig, ax, length = _figure()
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels.count("95 % radius") == 1
    assert {"search area", "uav1", "uav2", "people", "launch / home", "part 1"} <= set(labels)
    assert length in (100.0, 200.0)
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    assert x0 <= -20 and x1 >= 500 and y0 <= -5 and y1 >= 300  # circles, area and launch in view
    assert "33.90000° S, 70.10000° W" in maps.origin_caption(-33.9, -70.1)


@pytest.mark.parametrize("suffix", [".png", ".svg"])
def test_save_is_deterministic(tmp_path, suffix):
    a, b = tmp_path / f"a{suffix}", tmp_path / f"b{suffix}"
    maps.save_figure(_figure()[0], a)
    maps.save_figure(_figure()[0], b)
    assert a.read_bytes() == b.read_bytes()
    assert a.stat().st_size > 10_000
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([a.name, b.name])  # no temp files left


def test_png_is_a_real_picture(tmp_path):
    p = maps.save_figure(_figure()[0], tmp_path / "m.png")
    img = imread(p)
    assert img.shape[0] > 500 and img.shape[1] > 800
    assert img[..., :3].std() > 0.05  # not blank


def test_bad_suffix_writes_nothing(tmp_path):
    with pytest.raises(ValueError, match=".png or .svg"):
        maps.save_figure(_figure()[0], tmp_path / "m.jpg")
    assert list(tmp_path.iterdir()) == []


def test_many_vehicles_get_distinct_colors():
    cols = maps.vehicle_colors(20)
    assert len(cols) == 20 and len({str(c) for c in cols}) == 20


def test_a_95_circle_wider_than_the_area_is_an_outline_and_leaves_the_pod_raster_visible():
    """The field demo's result.png: two people heard once had 95 % radii of 7 and 20 km; tinted,
    they covered the whole map in pink and the POD raster (green: 0.80 achieved) read as 0."""
    from types import SimpleNamespace as P

    from matplotlib.patches import Circle

    from uavloc_gcs.render.estimates import WIDE_CIRCLE_FRACTION, result_figure

    area = np.array([[0, 0], [1120, 0], [1120, 640], [0, 640]], float)
    people = [P(emitter_id=1, label="P01", state="given up", east_m=600, north_m=300, radius95_m=19600.0),
              P(emitter_id=2, label="P02", state="given up", east_m=300, north_m=200, radius95_m=120.0)]
    ax = result_figure(people, area_xy_m=area, tracks_xy_m={}).axes[0]
    circles = [c for c in ax.patches if isinstance(c, Circle)]
    tinted = [c.get_radius() for c in circles if c.get_facecolor()[3] > 0]
    assert 120.0 in tinted and all(r <= WIDE_CIRCLE_FRACTION * 1120 for r in tinted)
    assert any(c.get_radius() == 19600.0 and c.get_edgecolor()[3] > 0 for c in circles)  # still drawn


def test_a_person_without_a_position_is_labelled_at_the_truth_with_its_state():
    """The field demo's result.png showed two never-heard phones as unlabelled crosses beside a table
    that names them (issue 40 item 3): every row's name is on the map when the truth is known."""
    import math
    from types import SimpleNamespace as P

    from uavloc_gcs.render.estimates import result_figure

    area = np.array([[0, 0], [1120, 0], [1120, 640], [0, 640]], float)
    people = [P(emitter_id=1, label="P01", state="given up", east_m=600, north_m=300, radius95_m=90.0),
              P(emitter_id=2, label="P02", state="never heard", east_m=math.nan, north_m=math.nan, radius95_m=math.nan)]
    truth = {1: np.array([620.0, 310.0]), 2: np.array([200.0, 500.0])}
    ax = result_figure(people, area_xy_m=area, tracks_xy_m={}, truth_xy_m=truth).axes[0]
    texts = [t.get_text() for t in ax.texts]
    assert "P01" in texts and "P02 (never heard)" in texts
    # without the truth (a real search) a person without a position has no place on the map
    ax = result_figure(people, area_xy_m=area, tracks_xy_m={}).axes[0]
    assert not any(t.get_text().startswith("P02") for t in ax.texts)


def test_a_person_placed_far_outside_the_area_is_an_arrow_at_the_edge_not_a_squashed_map():
    """The field demo's result.png: one person placed 3.7 km away shrank the 1.1 km area to a corner
    (issue 40 item 3). The map's extent is the area's; that person is an arrow at its edge with the
    name and the distance."""
    from types import SimpleNamespace as P

    from uavloc_gcs.render.estimates import result_figure

    area = np.array([[0, 0], [1120, 0], [1120, 640], [0, 640]], float)
    people = [P(emitter_id=1, label="P01", state="given up", east_m=600, north_m=300, radius95_m=90.0),
              P(emitter_id=3, label="P03", state="given up", east_m=3700.0, north_m=-200.0, radius95_m=900.0)]
    ax = result_figure(people, area_xy_m=area, tracks_xy_m={}).axes[0]
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    assert x1 - x0 < 1.5 * 1120 and x1 < 1500 and y0 > -300  # the area fills the map
    arrows = [t for t in ax.texts if t.get_text().startswith("P03:")]
    assert [t.get_text() for t in arrows] == ["P03: 3.7 km from launch"]
    tip = arrows[0].xy
    assert x0 < tip[0] < x1 and y0 < tip[1] < y1 and tip[0] > 0.8 * x1  # inside, at the east edge
    assert "P01" in [t.get_text() for t in ax.texts]  # the people near the area as before
