"""Coverage over terrain: what a vehicle hears is judged from its height above each cell's own
ground, not above the launch point. The mountains demo flew lanes 100 m above the slope (300-400 m
above the launch point) and reported 0.604 of 0.731 km² "unsearched", the lanes' own cells
included; from its stored telemetry the fixed accumulator says 0.190 km²."""

from __future__ import annotations

import numpy as np
import pytest

from uavloc_gcs.scenario import load_scenario
from uavloc_gcs.search.coverage import Coverage

from .dems import EXAMPLES


@pytest.fixture(scope="module")
def mountains():
    return load_scenario(EXAMPLES / "mountains.toml")


def _lane(sc, y_m, height_above_ground_m):
    """A lane due east across the area at ``y_m``, ``height_above_ground_m`` above the ground under
    the vehicle (times, positions with z above the launch point, as telemetry gives them)."""
    dem, home = sc.dem, sc.dem.height_at(0.0, 0.0)
    x = np.arange(0.0, 1120.0, 15.0)
    xy = np.column_stack([x, np.full(len(x), y_m)])
    z = dem.height_xy(xy, clamp=True) - home + height_above_ground_m
    return np.arange(len(x)) * 1.0, np.column_stack([xy, z])


def _pod_along(cov, y_m, x_lo, x_hi):
    g = cov.grid.xy_m
    near = (np.abs(g[:, 1] - y_m) < 30.0) & (g[:, 0] > x_lo) & (g[:, 0] < x_hi)
    return cov.pod(1)[near]


def test_a_lane_100_m_above_a_rising_slope_covers_its_cells_all_along(mountains):
    sc = mountains
    cov = Coverage(sc)
    t, xyz = _lane(sc, 300.0, 100.0)
    assert xyz[-1, 2] - xyz[0, 2] > 150.0  # the ground rises under the lane: z above launch grows
    cov.add_track(1, t, xyz)
    pod = _pod_along(cov, 300.0, 100.0, 1000.0)
    assert len(pod) > 10 and pod.min() > 0.3, pod.round(2)  # heard the whole way, high end included


def test_a_lane_too_high_above_the_ground_covers_nothing_there(mountains):
    sc = mountains
    cov = Coverage(sc)
    t, xyz = _lane(sc, 300.0, 100.0)
    xyz[:, 2] = xyz[:, 2].max()  # flown level at the highest point's altitude: far above the low end
    cov.add_track(1, t, xyz)
    g = sc.dem.height_xy(np.column_stack([np.arange(100.0, 1000.0, 15.0), np.full(60, 300.0)]), clamp=True)
    low = np.arange(100.0, 1000.0, 15.0)[g - g.min() < 20.0]  # where the ground is lowest
    pod = _pod_along(cov, 300.0, low.min() - 10.0, low.max() + 10.0)
    assert len(pod) and pod.max() < 0.05, pod.round(2)  # 150 m range, more than 150 m above it


def test_the_final_claims_judge_each_cell_from_its_own_ground_too(mountains):
    """The final report's POD (search.pod.pod_from_tracks, the stricter model) took the heights as
    above every cell: the mountains demo, flown 100 m above the whole slope, ended with "POD 0.33;
    0.487 km² unsearched (no vehicle within hearing), east 164 to 1124 m"; from its stored telemetry
    it is now 1.00 (0.96 for two)."""
    from uavloc_gcs.search.coverage import final_summary

    sc = mountains
    cov = Coverage(sc)
    t, xyz = _lane(sc, 300.0, 100.0)
    cov.add_track(1, t, xyz)
    final = final_summary(cov)
    g = final.grid.xy_m
    near = (np.abs(g[:, 1] - 300.0) < 30.0) & (g[:, 0] > 100.0) & (g[:, 0] < 1000.0)
    assert near.sum() > 10 and final.pod1[near].min() > 0.3, final.pod1[near].round(2)
