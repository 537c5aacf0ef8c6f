"""Hearing as evidence: slots heard bound the person within range, silences outside it."""

from pathlib import Path

import numpy as np
import pytest

from sim_link.world import World
from uavloc_gcs.estimation import ChannelModel, Silence, estimate_emitter, silence_from_track
from uavloc_gcs.observations import SlotBatch
from uavloc_gcs.scenario import load_scenario

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"


@pytest.fixture(scope="module")
def sc():
    return load_scenario(EXAMPLES / "paper.toml")


def lane(y, t0, reverse, sc):
    xs = np.arange(300.0, 820.0, sc.fleet.speed_m_s * sc.channel.slot_s)
    xs = xs[::-1] if reverse else xs
    t = t0 + np.arange(len(xs)) * sc.channel.slot_s
    return t, np.column_stack([xs, np.full(len(xs), y), np.full(len(xs), sc.fleet.altitude_m)])


def test_silence_is_the_track_where_the_phone_was_not_heard():
    t = np.arange(10) * 0.025
    xyz = np.column_stack([t, t, t])
    s = silence_from_track(t, xyz, t[3:6], slot_s=0.025)
    assert isinstance(s, Silence) and list(np.round(s.t_s / 0.025).astype(int)) == [0, 1, 2, 6, 7, 8, 9]
    assert len(silence_from_track(t, xyz, [], slot_s=0.025)) == 10


def test_a_silent_lane_rules_out_the_mirror(sc):
    """Heard from one lane only (20 m off it); the second lane, 100 m away, passes within range of
    the mirror image and hears nothing. Without the silence the mirror holds half the posterior
    (ambiguous, the radius spans both); with it, in every seed the estimate is the right side."""
    channel = ChannelModel.from_scenario(sc)
    without = with_ = 0
    for seed in range(4):
        world = World.with_people(sc, [[560.0, 280.0]], [[0.0, 0.0]], seed=seed)
        legs = [lane(300.0, 0.0, False, sc), lane(400.0, 25.0, True, sc)]
        slots = SlotBatch.concat([world.hear_track(1, t, x) for t, x in legs])
        assert np.all(slots.xyz_m[:, 1] == 300.0)  # heard from the first lane only
        quiet = silence_from_track(np.concatenate([t for t, _ in legs]), np.vstack([x for _, x in legs]),
                                   slots.t_s, slot_s=sc.channel.slot_s)
        plain = estimate_emitter(slots, channel, max_speed_m_s=0.0)
        est = estimate_emitter(slots, channel, max_speed_m_s=0.0, silence=quiet)
        truth = world.positions(est.t_ref_s)[0]
        without += plain.ambiguous
        assert not est.ambiguous and np.linalg.norm(est.position_xy_m - truth) <= est.radius95_m
        assert est.position_xy_m[1] < 300.0  # the right side of the lane
        with_ += 1
    assert without >= 2 and with_ == 4
