"""The grid estimator of the field world (estimation/burst_grid.py) under the air-to-ground channel.

The world draws bursts from ``a2g.A2GChannel``; the estimator must use the same channel (issue 41
item 1) and place a trapped person orbited low inside its 95 % circle, the circle shrinking as
bursts come in. One seeded world each: statistics over many belong to ``uavloc bench field``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sim_link.world import World
from uavloc_gcs.estimation.burst_grid import Burst, BurstGridEstimator, GridSpec, bursts_from_slots
from uavloc_gcs.estimation.burst_models import A2GBursts, LogDistanceBursts
from uavloc_gcs.observations import SlotBatch
from uavloc_gcs.scenario import load_scenario
from uavloc_gcs.search.phones import channel_share, frames_prior
from uavloc_gcs.search.policy import SearchPolicy

ROOT = Path(__file__).resolve().parents[3]


def _field(static: bool = True):
    sc = load_scenario(ROOT / "examples" / "field.toml")
    return sc.replace(people={"max_speed_m_s": 0.0}) if static else sc


def _pmf(sc) -> np.ndarray:
    fp = np.asarray(frames_prior(sc).p, float)
    return np.concatenate([[0.0], fp / fp.sum()])


def _estimator(sc) -> BurstGridEstimator:
    """The field world's grid estimator over the area (as bench low_orbit builds it)."""
    pmf = _pmf(sc)
    return BurstGridEstimator(A2GBursts.from_scenario(sc, pmf, channel_share(sc)), pmf,
                              area_xy_m=sc.area_xy_m(), area_margin_m=100.0)


def test_the_field_world_estimates_with_its_own_air_to_ground_channel():
    sc = _field(static=False)
    assert sc.channel.environment is not None  # field.toml names its environment
    spec = SearchPolicy(sc)._grid_spec()
    assert isinstance(spec.model, A2GBursts)
    assert spec.model.channel_share == pytest.approx(channel_share(sc))
    paper = load_scenario(ROOT / "examples" / "paper.toml")
    assert A2GBursts.from_scenario(paper, _pmf(sc)) is None  # no environment: not this channel


def test_a_burst_table_is_the_channels_own_likelihood_over_distance_and_offset():
    sc = _field()
    pmf = _pmf(sc)
    m = A2GBursts.from_scenario(sc, pmf, channel_share(sc))
    h = np.array([0.0, 20.0, 60.0, 150.0])
    tx = np.array([-3.0, 0.0, 3.0])[:, None]
    got = m.heard_loglik(np.array([-72.0, -75.0]), np.array([2.0, 1.0]), pmf, h[None, :], 30.0, tx)
    assert got.shape == (3, 4)
    for i, t in enumerate(tx[:, 0]):
        want = m.channel.burst_log_likelihood_unknown_sent(np.array([-72.0, -75.0]), pmf, h, 30.0,
                                                          counts=np.array([2.0, 1.0]), tx_offset_db=t,
                                                          channel_share=m.channel_share)
        np.testing.assert_allclose(got[i], want, rtol=1e-4, atol=1e-3)  # interpolated over the mean power
    silent = m.silent_loglik(pmf, h[None, :], 30.0, tx)
    assert np.all(np.diff(silent[1]) > 0)  # hearing nothing is likelier the farther the phone
    assert m.reach_m(30.0) > 200.0  # the urban tail: a louder phone in line of sight is heard far


def test_a_trapped_person_orbited_low_is_inside_a_circle_that_shrinks():
    sc = _field()
    est = _estimator(sc)
    person = np.array([520.0, 300.0])
    world = World.with_people(sc, [person], seed=7)
    centre, alt, speed = person + np.array([40.0, -35.0]), 30.0, 8.0  # the scan put them ~50 m off
    parts, radii, t0, ang0 = [], [], 0.0, 0.0
    while t0 < 900.0 and (not radii or radii[-1] > 15.0):
        t = np.arange(t0, t0 + 10.0, sc.channel.slot_s)
        ang = ang0 + speed * (t - t0) / alt
        xyz = np.column_stack([centre[0] + alt * np.cos(ang), centre[1] + alt * np.sin(ang), np.full(len(t), alt)])
        parts.append(world.hear_track(1, t, xyz))
        t0, ang0 = t0 + 10.0, float(ang[-1] + speed * sc.channel.slot_s / alt)
        if len(parts[-1]):
            post = est.posterior(bursts_from_slots(SlotBatch.concat(parts)), float(t[-1]))
            centre = post.mean_xy_m  # the look follows the posterior (search/orbit.py ADAPTIVE_ORBITS)
            radii.append(post.radius_about(post.mean_xy_m))
            error = float(np.hypot(*(post.mean_xy_m - person)))
    assert len(radii) >= 3, "too few bursts heard in 15 min from 30 m for this check"
    assert radii[-1] < 0.5 * radii[0], radii
    assert error <= radii[-1], (error, radii[-1])


def test_the_log_distance_world_keeps_its_model():
    sc = _field().replace(channel={"environment": None})
    spec = SearchPolicy(sc)._grid_spec()
    assert isinstance(spec.model, LogDistanceBursts) and isinstance(spec, GridSpec)


# -- units that share their shadowing (issue 39: BLE beacons 2 s apart, elicited frames) ------------

def test_units_heard_close_together_weigh_what_they_add():
    from uavloc_gcs.estimation.burst_grid import Burst, unit_weights

    b = [Burst(0.0, 1, (0.0, 0.0, 30.0), (-80.0,), (1,)), Burst(2.0, 1, (16.0, 0.0, 30.0), (-80.0,), (1,)),
         Burst(4.0, 2, (16.0, 0.0, 30.0), (-80.0,), (1,)), Burst(60.0, 1, (600.0, 0.0, 30.0), (-80.0,), (1,))]
    w = unit_weights(b, 50.0)
    rho = np.exp(-16.0 / 50.0)
    assert w[0] == 1.0 and w[1] == pytest.approx((1 - rho) / (1 + rho))
    assert w[2] == 1.0  # another vehicle's first unit
    assert w[3] == pytest.approx(1.0, abs=1e-4)  # far from the one before: independent
    assert np.all(unit_weights(b, None) == 1.0)  # the log-distance channel: i.i.d. frames


def test_units_on_an_orbit_weigh_what_they_say_about_where_the_person_is():
    """On an orbit the bearing from the person turns between two beacons, where the shadowing's
    AR(1) has less power than at frequency zero: each unit weighs the chain's share at that turn
    (Whittle), more than the zero-frequency share, never more than 1; a straight pass far from the
    reference turns the bearing little and weighs about as before; without a reference, as before."""
    from uavloc_gcs.estimation import burst_grid
    from uavloc_gcs.estimation.burst_grid import Burst, unit_weight, unit_weights

    s2, f2 = 16.0, 6.0
    rho = np.exp(-16.0 / 50.0)
    assert unit_weight(rho, s2, f2) == pytest.approx((s2 + f2) / (s2 * (1 + rho) / (1 - rho) + f2))
    assert unit_weight(rho, s2, f2, omega=0.53) > 2.5 * unit_weight(rho, s2, f2)
    assert unit_weight(0.2, s2, f2, omega=np.pi) == 1.0  # capped: no unit counts for more than one
    assert unit_weight(1.0, s2, f2) == pytest.approx(0.0, abs=1e-9)  # the same place again adds nothing
    ring = [Burst(2.0 * k, 1, (30.0 * np.cos(k * 16 / 30), 30.0 * np.sin(k * 16 / 30), 30.0), (-80.0,), (1,))
            for k in range(12)]
    flat = unit_weights(ring, 50.0, (s2, f2))
    about = unit_weights(ring, 50.0, (s2, f2), about_xy_m=(0.0, 0.0))
    assert flat[0] == about[0] == 1.0
    assert np.allclose(about[1:], unit_weight(rho, s2, f2, omega=16 / 30), rtol=0.01)
    assert np.all(about[1:] > 2.5 * flat[1:])
    far = [Burst(2.0 * k, 1, (16.0 * k, 0.0, 30.0), (-80.0,), (1,)) for k in range(12)]
    w_far = unit_weights(far, 50.0, (s2, f2), about_xy_m=(90.0, 2000.0))
    assert np.allclose(w_far[1:], unit_weights(far, 50.0, (s2, f2))[1:], rtol=0.02)
    burst_grid.BEARING_WEIGHTS = False
    try:
        assert np.allclose(unit_weights(ring, 50.0, (s2, f2), about_xy_m=(0.0, 0.0)), flat)
    finally:
        burst_grid.BEARING_WEIGHTS = True


def test_beacons_heard_from_one_place_say_what_one_beacon_says():
    """A vehicle hovering hears the same shadowing again and again: fifty beacons from one place
    must not make a circle that one beacon does not (they did, summed as independent)."""
    from uavloc_gcs.estimation.burst_grid import Burst
    from uavloc_gcs.radios import ble_view

    sc = _field().replace(emission={"findmy_share": 1.0})
    spec = SearchPolicy(sc)._grid_spec("ble")
    assert spec.model.channel.reference_power_dbm == pytest.approx(
        sc.channel.reference_power_dbm + sc.emission.ble_power_offset_db)
    assert spec.model.channel.sensitivity_dbm == sc.channel.ble_receiver_sensitivity_dbm
    assert spec.model.channel == A2GBursts.from_scenario(ble_view(sc), np.array([0.0, 1.0])).channel
    est = spec.estimator()
    one = [Burst(0.0, 1, (500.0, 300.0, 30.0), (-88.0,), (1,))]
    many = [Burst(2.0 * k, 1, (500.0, 300.0, 30.0), (-88.0 + 0.1 * (k % 3),), (1,)) for k in range(50)]
    r1 = est.posterior(one, 0.0)
    r50 = est.posterior(many, 100.0)
    assert r50.radius_about(r50.mean_xy_m) >= 0.95 * r1.radius_about(r1.mean_xy_m)


def test_a_table_where_a_burst_is_impossible_stays_finite():
    """The models floor log 0 at -1e300, which float32 makes -inf; two -inf neighbours interpolated
    to NaN and the person had "no place on the grid" (an elicited look, bench low_orbit run 7)."""
    from uavloc_gcs.estimation.burst_grid import Burst, burst_table

    class Impossible:  # heard nowhere nearer than 20 m
        def heard_loglik(self, rssi, counts, pmf, h, z, tx):
            return np.where(h < 20.0, -1e300, -1.0 - 0.01 * h) + 0.0 * tx

    b = Burst(0.0, 1, (0.0, 0.0, 30.0), (-60.0,), (1,))
    t = burst_table(Impossible(), b, np.array([0.0, 1.0]), 100.0, np.array([-1.0, 0.0, 1.0]))
    v = t.at(np.array([0.0, 3.3, 19.0, 50.0]))
    assert np.all(np.isfinite(v)) and np.all(v[:, :2] < -1e29) and np.allclose(v[:, 3], -1.5, atol=0.05)


def test_a_unit_no_place_explains_does_not_erase_the_others():
    """A phone joining a mimicked network does so at a burst, and the burst and the first answers
    were heard as one run of 84 frames, more than any burst sends: its table was at the floor
    everywhere, which in float32 swamped every other unit, and the posterior became the whole
    area (radius 685 m after 240 units; `uavloc bench low_orbit --elicitation 2`, run 7)."""
    sc = _field()
    pmf, est = _pmf(sc), _estimator(sc)
    person = np.array([520.0, 300.0])
    world = World.with_people(sc, [person], seed=7)
    t = np.arange(0.0, 900.0, sc.channel.slot_s)
    ang = 8.0 * t / 30.0
    xyz = np.column_stack([person[0] + 10 + 30 * np.cos(ang), person[1] + 30 * np.sin(ang), np.full(len(t), 30.0)])
    bursts = bursts_from_slots(world.hear_track(1, t, xyz))
    assert len(bursts) >= 3, "too few bursts heard for this check"
    good = est.posterior(bursts, 900.0)
    too_many = Burst(450.0, 1, (float(person[0]), float(person[1]) + 30.0, 30.0), (-70.0,) * 42, (2,) * 42)
    assert sum(too_many.counts) > len(pmf) - 1  # more frames than a burst sends
    with_it = est.posterior(bursts + [too_many], 900.0)
    assert with_it.radius_about(with_it.mean_xy_m) == pytest.approx(good.radius_about(good.mean_xy_m), rel=1e-3)
    assert np.allclose(with_it.mean_xy_m, good.mean_xy_m, atol=0.1)


def test_a_burst_and_the_answers_heard_during_it_are_two_units():
    """A phone joins a mimicked network at a burst: its probe frames (one address) and its first
    answers (its network address, kept) overlap in time. Grouped by time alone they made one run
    of more frames than a burst sends; grouped by the address they keep they are two units. A phone
    with one address for everything, or bursts only, is grouped as before."""
    def slots(t, address):
        n = len(t)
        return SlotBatch.from_columns(np.asarray(t, float), np.ones(n, int), np.tile([0.0, 0.0, 30.0], (n, 1)),
                                      np.asarray(address), np.full(n, -70.0), np.ones(n, int),
                                      address=np.asarray(address))

    net = 7
    probe = slots(10.0 + 0.025 * np.arange(40), [101] * 40)  # a burst of 40 frames under one address
    answers = slots([10.3, 10.6, 10.9, 30.0, 30.4, 61.0], [net] * 6)  # the network address, kept
    units = bursts_from_slots(SlotBatch.concat([probe, answers]))
    sizes = sorted(len(b.counts) for b in units)
    assert sizes == [1, 2, 3, 40]  # the burst; the answers during it; two runs of answers later
    # bursts only (addresses of their own): as grouped by time
    only = SlotBatch.concat([probe, slots(40.0 + 0.025 * np.arange(5), [102] * 5)])
    assert [len(b.counts) for b in bursts_from_slots(only)] == [40, 5]
    # one address for everything (a phone with a global address): as grouped by time
    same = SlotBatch.concat([slots(probe.t_s, [net] * 40), answers])
    assert sorted(len(b.counts) for b in bursts_from_slots(same)) == [1, 2, 43]
