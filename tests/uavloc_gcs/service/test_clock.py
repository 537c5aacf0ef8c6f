"""Which clock a time is in (issue 42 item 7): under a simulator's speed-up the vehicles' clock runs
ahead of UTC, and "positions at 17:55 to 18:17 UTC" came out of a demo drawn at 17:47 UTC."""

import numpy as np

from uavloc_gcs.service.clock import MissionClock, utc_text
from uavloc_gcs.service.results import PersonResult, results_table

EPOCH = 1_795_000_000.0  # 2026-11-18 11:06:40 UTC


def test_real_time_vehicles_keep_their_own_gps_clock():
    anchors = [(t, EPOCH + 3.0 + t) for t in np.arange(0.0, 60.0, 2.0)]  # this computer 3 s late
    c = MissionClock.of(EPOCH, anchors)
    assert not c.simulated and c.label == "UTC"
    assert c.unix_s(30.0) == EPOCH + 30.0  # the vehicles' GPS time, not this computer's
    assert utc_text(EPOCH, 30.0) == utc_text(c, 30.0) == "2026-11-18T11:07:10.0Z"


def test_a_simulated_clock_at_20x_is_mapped_to_when_it_really_happened():
    wall0 = EPOCH  # the fleet starts its simulated clock at the wall time
    anchors = [(20.0 * k, wall0 + k) for k in range(0, 61)]  # 60 s of wall, 1,200 s of mission
    c = MissionClock.of(EPOCH, anchors)
    assert c.simulated and abs(c.rate - 20.0) < 1e-6
    assert "this computer's clock" in c.label and "20.0x" in c.label
    last = c.unix_s(1200.0)
    assert last == wall0 + 60.0  # the moment the vehicles were there, not 20 min later
    assert EPOCH + 1200.0 - last == 1140.0  # what the old mapping (epoch + t) put it ahead by
    assert c.unix_s(600.0) == wall0 + 30.0
    assert c.unix_s(1240.0) == wall0 + 62.0  # beyond the anchors: at their rate


def test_the_table_says_which_clock_its_times_are_in():
    anchors = [(20.0 * k, EPOCH + k) for k in range(0, 61)]
    p = PersonResult(1, 42.6, 13.3, 0.0, 0.0, 0.0, 0.0, 5.0, 9.0, 10.0, True, True, "", 1200.0, label="P01")
    sim = results_table([p], 15.0, epoch_unix_s=MissionClock.of(EPOCH, anchors))
    assert "11:07:40.0" in sim and "Times: UTC by this computer's clock" in sim
    real = results_table([p], 15.0, epoch_unix_s=EPOCH)
    assert "11:26:40.0" in real and "Times:" not in real
