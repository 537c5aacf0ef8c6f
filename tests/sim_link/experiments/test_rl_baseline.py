"""RL-NM baseline: grid, strips, annulus geometry, and a mission on static people."""

import math
from pathlib import Path

import numpy as np
import pytest

from sim_link.experiments import rl_annuli as an
from sim_link.experiments.rl_baseline import RLConfig, make_grid, scan_cells, simulate_rl, strips
from sim_link.world import World
from uavloc_gcs.scenario import load_scenario

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"


def test_paper_grid_is_22_by_12_cells_of_about_51_by_53_m():
    sc = load_scenario(EXAMPLES / "paper.toml")
    g = make_grid(sc, 2)
    assert (g.nx, g.ny) == (22, 12)
    assert g.cell_x_m == pytest.approx(1120 / 22) and g.cell_y_m == pytest.approx(640 / 12)
    assert g.valid.all()
    parts = strips(g, 4)
    assert parts[0][0] == 0 and parts[-1][1] == 22 and len(parts) == 4
    assert all(a[1] == b[0] for a, b in zip(parts, parts[1:]))
    cells = scan_cells(g, parts[0], 2)
    assert cells and all(parts[0][0] <= i < parts[0][1] for i, _ in cells)


def _annulus(centre, truth, half=2.0, t=0.0):
    r = float(np.hypot(*(np.asarray(truth) - centre)))
    return an.Annulus(tuple(centre), max(r - half, 0.0), r + half, t)


def test_three_annuli_localize_and_bound_contains_the_truth():
    truth = np.array([40.0, 30.0])
    rings = [_annulus(np.array(c, float), truth, t=k) for k, c in enumerate([(0, 0), (100, 0), (50, 90)])]
    x, bound, used = an.localize(rings)
    assert np.hypot(*(x - truth)) < 3.0
    assert np.hypot(*(x - truth)) <= bound < 15.0
    assert len(used) == 3


def test_two_annuli_leave_the_mirror_in_the_bound():
    truth = np.array([40.0, 30.0])
    rings = [_annulus(np.array(c, float), truth) for c in [(0, 0), (100, 0)]]
    x, bound, _ = an.localize(rings)
    assert bound > 50.0  # the mirror (40, -30) is still possible
    # a silent hover point near the mirror rules it out
    x2, bound2, _ = an.localize(rings, silent_xy_m=[(40.0, -60.0)], range_m=60.0)
    assert np.hypot(*(x2 - truth)) < 5.0 and bound2 < 10.0


def test_inconsistent_annulus_is_dropped():
    truth = np.array([40.0, 30.0])
    rings = [_annulus(np.array(c, float), truth, t=k) for k, c in enumerate([(0, 0), (100, 0), (50, 90)])]
    rings.append(an.Annulus((50.0, 90.0), 150.0, 155.0, 9.0))  # impossible with the others
    x, bound, used = an.localize(rings)
    assert len(used) == 3 and np.hypot(*(x - truth)) < 3.0


def test_rl_mission_on_static_people_is_valid_and_deterministic():
    sc = load_scenario(EXAMPLES / "small.toml")
    cfg = RLConfig(train_episodes=3, episode_steps=8)
    runs = [simulate_rl(sc, World(sc, seed=11, people=3, motion="static"), seed=1, config=cfg) for _ in range(2)]
    a, b = runs
    assert a.completion_time_s == b.completion_time_s
    assert [p.error_m for p in a.persons] == [p.error_m for p in b.persons]
    assert a.method == "RL-NM" and a.planner_runtime_s > 0
    assert all(e <= sc.usable_energy_j * 1.01 for e in a.energy_j)
    assert a.located_fraction == 1.0
    assert all(p.error_m < sc.people.required_accuracy_m for p in a.persons)
    assert math.isfinite(a.completion_time_s) and a.completion_time_s > 0
