"""The RSSI alone's attainable floor (benchmarks.posterior): the importance-sampled posterior mean
against a brute-force grid, and where the Cramer-Rao bound is and is not reachable."""

import math
import subprocess
import sys

import numpy as np
import pytest

from benchmarks import localize as bench
from benchmarks.posterior import estimate_candidates, log_posterior, rssi_posterior_mean
from sim_link.world import World
from uavloc_gcs.estimation import ChannelModel, data_information, estimate_emitter, position_rmse_bound_m
from uavloc_gcs.estimation import prior_information
from uavloc_gcs.estimation.prepared import prepare
from uavloc_gcs.examples import scenario_path
from uavloc_gcs.observations import SlotBatch
from uavloc_gcs.scenario import load_scenario


@pytest.fixture(scope="module")
def paper():
    sc = load_scenario(scenario_path("paper"))
    return sc, ChannelModel.from_scenario(sc)


def _two_lanes(sc, start, vel, lane_y, seed):
    """Slots of a walker heard from two parallel lanes 100 m apart (bench localize's geometry)."""
    world = World.with_people(sc, [start], [vel], seed=seed)
    v, slot, alt, half = sc.fleet.speed_m_s, sc.channel.slot_s, sc.fleet.altitude_m, sc.horizontal_range_m + 60
    t1, x1 = bench._leg([start[0] - half, lane_y], [start[0] + half, lane_y], 0.0, v, slot, alt)
    t2, x2 = bench._leg([start[0] + half, lane_y + 100], [start[0] - half, lane_y + 100], t1[-1] + 5.0, v, slot, alt)
    return world, SlotBatch.concat([world.hear_track(1, t1, x1), world.hear_track(1, t2, x2)])


def _grid_mean(data, t_ref, center, vmax):
    """The posterior mean by brute force over a grid of positions (2 m) and velocities (0.15 m/s),
    with the grid (K, 4) and its normalised weights."""
    xs = np.arange(center[0] - 30, center[0] + 30.1, 2.0)
    ys = np.arange(center[1] - 70, center[1] + 70.1, 2.0)
    vs = np.arange(-1.5, 1.501, 0.15)
    px, py, vx, vy = (a.ravel() for a in np.meshgrid(xs, ys, vs, vs, indexing="ij"))
    x = np.column_stack([px, py, vx, vy])
    lp = log_posterior(x, data, t_ref, vmax)
    w = np.exp(lp - lp.max())
    w /= w.sum()
    return w @ x[:, :2], x, w


def test_posterior_mean_of_a_walker_ending_under_the_last_track_agrees_with_a_grid(paper):
    """A walker crossing towards the second lane and ending 20 m beyond it: the range from that lane
    fixes little more than the squared offset, so the posterior is tens of metres wide across the
    track although the information at the truth promises a few metres."""
    sc, ch = paper
    vmax = sc.people.max_speed_m_s
    world, slots = _two_lanes(sc, np.array([560.0, 320.0]), np.array([-0.3, 1.2]), 320.0 - 95.0, seed=11)
    data = prepare(slots, ch)
    est = estimate_emitter(slots, ch, max_speed_m_s=vmax)
    t_ref = est.t_ref_s
    truth, tvel = world.positions(t_ref)[0], world.velocities(t_ref)[0]
    pm, ess = rssi_posterior_mean(data, t_ref, estimate_candidates(est), vmax, np.random.default_rng(0))
    grid, x, w = _grid_mean(data, t_ref, truth, vmax)
    assert ess > 500
    assert np.linalg.norm(pm - grid) < 1.5, (pm, grid)
    # the posterior's spread across the track against the bound at the truth
    py = x[:, 1]
    spread = math.sqrt(float(w @ (py - w @ py) ** 2))
    prior = prior_information(ch, max_speed_m_s=vmax)
    bound = position_rmse_bound_m(data_information(slots, ch, truth, tvel, t_ref) + prior)
    assert spread > 2.0 * bound, (spread, bound)


def test_posterior_mean_is_the_fit_where_the_posterior_is_gaussian(paper):
    """Between two lanes, well off both tracks, a static phone: the posterior mean and the
    constant-velocity MAP fit are the same point to a fraction of the error."""
    sc, ch = paper
    vmax = sc.people.max_speed_m_s
    world, slots = _two_lanes(sc, np.array([560.0, 320.0]), np.zeros(2), 320.0 - 50.0, seed=5)
    est = estimate_emitter(slots, ch, max_speed_m_s=vmax, maneuver_time_s=math.inf)
    pm, ess = rssi_posterior_mean(prepare(slots, ch), est.t_ref_s, estimate_candidates(est), vmax,
                                  np.random.default_rng(1))
    sd = math.sqrt(np.trace(est.covariance[:2, :2]) / 2)
    assert ess > 1000
    assert np.linalg.norm(pm - est.position_xy_m) < 0.5 * sd, (pm, est.position_xy_m, sd)


def test_bench_localize_prints_the_floor_with_mmse():
    cmd = [sys.executable, "-m", "uavloc_gcs", "bench", "localize", "--runs", "3", "--family", "two parallel, moving",
           "--mmse"]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    head = next(k for k, line in enumerate(lines) if "MMSE m" in line and "ratio away" in line)
    row = lines[head + 2].split()
    assert " ".join(row[:3]) == "two parallel, moving"
    mmse, ess = float(row[-4]), float(row[-1])
    assert mmse > 0 and ess > 100
    # the correlated family gets no floor (its likelihood is not the i.i.d. one)
    assert not any(line.startswith("two parallel, moving, corr.") for line in lines[head:])
