"""`python -m benchmarks.altitude`: what altitude costs and buys (the full table runs in the
benchmark; here a small world checks that the columns mean what they say)."""

import math

import pytest

from benchmarks import altitude
from uavloc_gcs.examples import scenario_path
from uavloc_gcs.scenario import load_scenario


@pytest.fixture(scope="module")
def field():
    return load_scenario(scenario_path("field"))


def test_hearing_distances_shrink_with_altitude_under_the_urban_channel_only(field):
    urban = altitude.scenario_for(field, "urban")
    before = altitude.scenario_for(field, altitude.BEFORE)
    assert urban.channel.environment == "urban" and before.channel.environment is None
    hi, lo = altitude.hearing_distances_m(urban, 100.0), altitude.hearing_distances_m(urban, 30.0)
    assert lo[0] < 0.5 * hi[0] and lo[1] < hi[1] and hi[1] > hi[0]
    # before issue 41 altitude cost nothing: the frame's 149 m slant range reached further from 30 m up
    b_hi, b_lo = altitude.hearing_distances_m(before, 100.0), altitude.hearing_distances_m(before, 30.0)
    assert b_lo[0] > b_hi[0] and b_hi[0] == pytest.approx(math.sqrt(149.0 ** 2 - 100.0 ** 2), abs=2.0)


def test_one_small_world_row(field):
    r = altitude.measure("urban", 60.0, people=15, seeds=1, base=field)
    assert 0.0 <= r["heard"] <= 1.0 and r["bursts"] >= 1
    assert 0.0 <= r["rel_error"] < 3.0 and r["error_m"] >= 0.0
    assert altitude.main(["--people", "5", "--seeds", "1", "--environments", "high-rise", "--altitudes", "30"]) == 0
