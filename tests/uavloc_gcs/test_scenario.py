"""Scenario files: the examples load, and every kind of bad value names its key."""

from pathlib import Path

import numpy as np
import pytest

from uavloc_gcs.errors import ConfigError
from uavloc_gcs.scenario import load_scenario, loads_scenario

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

RECT = """
[area]
origin_lat_deg = 42.625
origin_lon_deg = 13.283
width_m = 1120
height_m = 640
"""


def test_paper_scenario_matches_the_paper():
    sc = load_scenario(EXAMPLES / "paper.toml")
    assert sc.fleet.vehicles == 4
    assert sc.fleet.altitude_m == 100 and sc.fleet.speed_m_s == 25 and sc.fleet.comm_range_m == 150
    assert sc.people.max_speed_m_s == 1.5
    assert sc.channel.path_loss_exponent == 2 and sc.channel.shadowing_sigma_db == 4
    assert sc.channel.log_range_sigma == pytest.approx(0.4605, abs=1e-4)
    assert sc.horizontal_range_m == pytest.approx(111.80, abs=0.01)
    xy = sc.area_xy_m()
    assert np.ptp(xy[:, 0]) == pytest.approx(1120, abs=0.05)
    assert np.ptp(xy[:, 1]) == pytest.approx(640, abs=0.05)


@pytest.mark.parametrize("name", sorted(p.name for p in EXAMPLES.glob("*.toml")))
def test_every_example_loads(name):
    sc = load_scenario(EXAMPLES / name)
    assert len(sc.area_xy_m()) >= 3


def test_heading_rotates_the_rectangle():
    sc = loads_scenario(RECT + "heading_deg = 0\n")
    xy = sc.area_xy_m()
    # Width side due north, height side due west.
    assert np.ptp(xy[:, 1]) == pytest.approx(1120, abs=0.1)
    assert np.ptp(xy[:, 0]) == pytest.approx(640, abs=0.1)
    assert xy[:, 0].max() < 1e-6


@pytest.mark.parametrize(
    "extra, key, fragment",
    [
        ("[fleet]\nvehicles = 0\n", "fleet.vehicles", "at least 1"),
        ("[fleet]\nvehicles = 2.5\n", "fleet.vehicles", "whole number"),
        ("[fleet]\naltitude_m = 'high'\n", "fleet.altitude_m", "number"),
        ("[fleet]\ncomm_range_m = 90\n", "fleet.comm_range_m", "must exceed the altitude"),
        ("[fleet]\nautopilot = 'inav'\n", "fleet.autopilot", "expected one of"),
        ("[fleet]\nspeeed_m_s = 3\n", "fleet.speeed_m_s", "unknown key"),
        ("[fleet]\nenergy_reserve_fraction = 1.5\n", "fleet.energy_reserve_fraction", "[0, 1)"),
        ("[people]\nmax_speed_m_s = 30\n", "people.max_speed_m_s", "slower than the vehicles"),
        ("[channel]\nshadowing_sigma_db = -1\n", "channel.shadowing_sigma_db", "positive"),
        ("[wind]\nspeed = 3\n", "wind", "unknown section"),
        ("[fleet]\nbatteries = 0\n", "fleet.batteries", "1-50 packs"),
        ("[fleet]\nbatteries = 2.5\n", "fleet.batteries", "whole number"),
        ("[fleet]\nbatteries = 500\n", "fleet.batteries", "1-50 packs"),
        ("[fleet]\nbattery_swap_s = -10\n", "fleet.battery_swap_s", "0-3600 s"),
        ("[fleet]\nbattery_swap_s = 'two minutes'\n", "fleet.battery_swap_s", "number"),
        ("[search]\ntime_limit_s = 0\n", "search.time_limit_s", "positive"),
        ("[search]\ntime_limit_s = 1e9\n", "search.time_limit_s", "more than a week"),
    ],
)
def test_bad_values_name_the_key(extra, key, fragment):
    with pytest.raises(ConfigError) as ei:
        loads_scenario(RECT + extra, source="mission.toml")
    msg = str(ei.value)
    assert msg.startswith("mission.toml")
    assert f"'{key}'" in msg
    assert fragment in msg


def test_sortie_keys_default_to_one_pack_and_are_read():
    """issue 38: one pack is the behaviour before sorties; the keys are read as given."""
    sc = loads_scenario(RECT)
    assert sc.fleet.batteries == 1 and sc.search.time_limit_s is None
    sc = loads_scenario(RECT + "[fleet]\nbatteries = 3\nbattery_swap_s = 90\n[search]\ntime_limit_s = 3600\n")
    assert (sc.fleet.batteries, sc.fleet.battery_swap_s, sc.search.time_limit_s) == (3, 90.0, 3600.0)
    assert sc.usable_energy_j == pytest.approx(sc.fleet.energy_budget_j * 0.85)  # per pack


def test_area_errors():
    with pytest.raises(ConfigError, match="missing \\[area\\]"):
        loads_scenario("[fleet]\nvehicles = 2\n")
    with pytest.raises(ConfigError, match="exactly one of"):
        loads_scenario(RECT + "polygon_deg = [[1,1],[1,2],[2,2]]\n")
    with pytest.raises(ConfigError, match="area.width_m"):
        loads_scenario(RECT.replace("width_m = 1120", "width_m = -5"))
    with pytest.raises(ConfigError, match="crosses itself"):
        loads_scenario("[area]\npolygon_deg = [[0,0],[0.01,0.01],[0,0.01],[0.01,0]]\n")
    with pytest.raises(ConfigError, match="at least 3"):
        loads_scenario("[area]\npolygon_deg = [[0,0],[0.01,0.01]]\n")
    with pytest.raises(ConfigError, match="latitude"):
        loads_scenario("[area]\npolygon_deg = [[95,0],[0.01,0.01],[0,0.01]]\n")


def test_not_toml_and_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="not valid TOML"):
        loads_scenario("[area\n")
    with pytest.raises(ConfigError, match="file not found"):
        load_scenario(tmp_path / "nope.toml")


def test_replace_revalidates():
    sc = loads_scenario(RECT)
    assert sc.replace(fleet={"vehicles": 2}).fleet.vehicles == 2
    with pytest.raises(ConfigError):
        sc.replace(fleet={"vehicles": 0})


def test_polygon_is_counter_clockwise_and_launch_defaults_to_first_corner():
    sc = loads_scenario("[area]\npolygon_deg = [[0,0],[0.01,0],[0.01,0.01],[0,0.01]]\n")  # clockwise
    xy = sc.area_xy_m()
    area2 = np.sum(xy[:, 0] * np.roll(xy[:, 1], -1) - np.roll(xy[:, 0], -1) * xy[:, 1])
    assert area2 > 0
    assert sc.launch_latlon_deg == (0.0, 0.0)


@pytest.mark.parametrize(
    "extra, key, fragment",
    [
        ("[emission]\nmodel = 'beacons'\n", "emission.model", "expected one of"),
        ("[emission]\nelicitation_rate_hz = -1\n", "emission.elicitation_rate_hz", "must not be negative"),
        ("[emission]\nmimicry_share = 1.5\n", "emission.mimicry_share", "between 0 and 1"),
        ("[emission]\nelicitation_join = \"always\"\n", "emission.elicitation_join", "in-reach"),
        ("[emission]\nburst_gap_median_min_s = 0\n", "emission.burst_gap_median_min_s", "must be positive"),
        ("[emission]\nburst_gap_median_max_s = -5\n", "emission.burst_gap_median_max_s", "must be positive"),
        ("[emission]\nburst_gap_median_max_s = 10\n", "emission.burst_gap_median_max_s", "is below"),
        ("[emission]\nburst_gap_p90_min_s = 15\n", "emission.burst_gap_p90_min_s", "must exceed the median"),
        ("[emission]\nburst_gap_p90_max_s = 100\n", "emission.burst_gap_p90_max_s", "must exceed the median"),
        ("[emission]\nframes_per_burst_median_min = 0\n", "emission.frames_per_burst_median_min", "at least 1"),
        ("[emission]\nframes_per_burst_max = 10\n", "emission.frames_per_burst_max", "is below"),
        ("[emission]\nframes_per_burst_max = 2.5\n", "emission.frames_per_burst_max", "whole number"),
        ("[emission]\nlong_silence_per_gap = 1.0\n", "emission.long_silence_per_gap", "[0, 1)"),
        ("[emission]\nlong_silence_min_s = 0\n", "emission.long_silence_min_s", "must be positive"),
        ("[emission]\nframe_spacing_s = 0.5\n", "emission.frame_spacing_s", "overlap"),
        ("[emission]\nframe_spacing_s = 0\n", "emission.frame_spacing_s", "must be positive"),
        ("[emission]\ngap_s = 3\n", "emission.gap_s", "unknown key"),
        ("[channel]\nreceiver_sensitivity_dbm = -30\n", "channel.receiver_sensitivity_dbm", "not below the reference"),
        ("[channel]\nlisten_channels = [1, 6, 36]\n", "channel.listen_channels", "1..14"),
        ("[channel]\nlisten_channels = []\n", "channel.listen_channels", "at least one"),
        ("[channel]\nlisten_channels = [6, 6]\n", "channel.listen_channels", "twice"),
        ("[channel]\nenvironment = 'rural'\n", "channel.environment",
         "choose one of suburban, urban, dense-urban, high-rise"),
        ("[channel]\nenvironment = 3\n", "channel.environment", "must be a string"),
        ("[channel]\nenvironment = 'urban'\n", "channel.environment", "set channel.receiver_sensitivity_dbm"),
        ("[channel]\nenvironment = 'urban'\nreceiver_sensitivity_dbm = -90\n", "channel.environment",
         'model = "probe-bursts"'),
        ("[channel]\nenvironment = 'urban'\nreceiver_sensitivity_dbm = -90\n[emission]\nmodel = 'probe-bursts'\n"
         "[simulation]\ncorrelated_shadowing = true\n", "simulation.correlated_shadowing", "draws its own shadowing"),
    ],
)
def test_bad_emission_and_receiver_values_name_the_key(extra, key, fragment):
    with pytest.raises(ConfigError) as ei:
        loads_scenario(RECT + extra, source="mission.toml")
    msg = str(ei.value)
    assert f"'{key}'" in msg and fragment in msg
    assert msg.count(". ") == 0  # one sentence


def test_field_scenario_is_the_paper_geometry_in_the_field_world():
    paper, field = load_scenario(EXAMPLES / "paper.toml"), load_scenario(EXAMPLES / "field.toml")
    assert field.area == paper.area and field.fleet == paper.fleet and field.scan == paper.scan
    assert field.emission.model == "probe-bursts" and paper.emission.model == "continuous"
    assert paper.channel.receiver_sensitivity_dbm is None
    ch = field.channel
    assert -95 <= ch.receiver_sensitivity_dbm <= -90 and ch.listen_channel_list == (1, 6, 11)
    # the channel is the urban air-to-ground one (issue 41); the paper's 150 m planning range lies
    # between a blocked frame's and a line-of-sight frame's 50 % hearing distance
    from uavloc_gcs.a2g import LOS, NLOS, A2GChannel

    a2g = A2GChannel.from_scenario(field)
    assert ch.environment == "urban" and paper.channel.environment is None
    assert a2g.state_range_m(NLOS) < field.fleet.comm_range_m < a2g.state_range_m(LOS)
    # free space (eta = 2) from the same P0 and sensitivity gives Wi2SAR's ~300 m line-of-sight range
    los = 10 ** ((ch.reference_power_dbm - ch.receiver_sensitivity_dbm) / 20)
    assert 280 < los < 340
    assert field.simulation.tx_power_spread_db > 0
    # a search in the field world flies a scan planned for detection; the paper's flies the paper's
    assert paper.search.pod_target is None and 0.5 <= field.search.pod_target < 0.95
