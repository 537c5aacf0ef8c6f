"""Shared set-up of the end-to-end tests: a small scenario, the fake fleet in a child process."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from uavloc_gcs.scenario import loads_scenario

# Two vehicles over 400 m x 250 m at 60 m, three people: a whole search in ~150 s of mission time.
SMALL = """
name = "e2e"
[area]
origin_lat_deg = 42.62500
origin_lon_deg = 13.28300
width_m = 400.0
height_m = 250.0
[fleet]
vehicles = 2
autopilot = "{autopilot}"
speed_m_s = 15.0
altitude_m = 60.0
energy_budget_j = 200000.0
[people]
required_accuracy_m = 15.0
[planner]
time_limit_s = 0.2
[simulation]
people = 3
seed = {seed}
motion = "static"
speedup = {speedup}
{extra}
"""


def small_scenario(autopilot: str = "ardupilot", *, seed: int = 3, speedup: float = 25.0, extra: str = ""):
    return loads_scenario(SMALL.format(autopilot=autopilot, seed=seed, speedup=speedup, extra=extra),
                          source="e2e.toml")


def truth_errors_m(scenario, people, epoch_shift_s: float = 0.0) -> dict[int, float]:
    """True error [m] of every estimated person at the time its estimate refers to."""
    from sim_link.world import World

    world = World(scenario, seed=scenario.simulation.seed)
    ids = [int(e) for e in world.emitter_ids]
    out = {}
    for p in people:
        if p.emitter_id not in ids or not math.isfinite(p.east_m):
            continue
        xy = np.asarray(world.positions(p.t_ref_s + epoch_shift_s))[ids.index(p.emitter_id)][:2]
        out[p.emitter_id] = float(math.hypot(p.east_m - xy[0], p.north_m - xy[1]))
    return out


def world_ids(scenario) -> set[int]:
    from sim_link.world import World

    return {int(e) for e in World(scenario, seed=scenario.simulation.seed).emitter_ids}


def write_config(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


# The field world's channel and phones (examples/field.toml) as a small_scenario(extra=...) override.
FIELD = """
[channel]
path_loss_exponent = 2.3
reference_power_dbm = -40.0
receiver_sensitivity_dbm = -90.0
[emission]
model = "probe-bursts"
"""
