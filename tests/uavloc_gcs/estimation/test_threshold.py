"""The field world's receiver: frames heard above a sensitivity (truncated likelihood) and silences
within heard bursts (censored observations)."""

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from uavloc_gcs.errors import EstimationError
from uavloc_gcs.estimation import ChannelModel, estimate_emitter
from uavloc_gcs.estimation.crb import censored_information, data_information, frames_information
from uavloc_gcs.estimation.evidence import Censored, FramesPrior, burst_windows, censored_silence
from uavloc_gcs.estimation.fit import Problem
from uavloc_gcs.estimation.prepared import censored_rows, prepare
from uavloc_gcs.estimation.maneuver import find_passes
from uavloc_gcs.estimation.model import (
    log_probability_residual,
    tobit_information_factor,
    truncated_information_factor,
)
from uavloc_gcs.observations import SlotBatch

FIELD = ChannelModel(-30.0, 2.85, 6.0, 1.0, sensitivity_dbm=-92.0)
ALT_M = 80.0


def frames_heard(channel, truth_xy, t_s, xyz_m, rng, vehicle=1, tx_db=0.0) -> SlotBatch:
    """One slot per frame sent at t_s from a receiver at xyz_m, kept when heard (RSSI above S)."""
    d = np.sqrt(np.sum((xyz_m[:, :2] - truth_xy) ** 2, axis=1) + xyz_m[:, 2] ** 2)
    rssi = channel.rssi_dbm(d) + tx_db + rng.normal(0.0, channel.shadowing_sigma_db, len(d))
    keep = rssi > channel.sensitivity_dbm
    n = int(keep.sum())
    return SlotBatch(t_s[keep], np.full(n, vehicle), xyz_m[keep], np.zeros(n, np.int64), rssi[keep],
                     np.ones(n, int))


def leg(y_m, t0_s, x0=-300.0, x1=300.0, speed=25.0, rate_hz=10.0):
    t = np.arange(0.0, (x1 - x0) / speed, 1.0 / rate_hz)
    return t0_s + t, np.column_stack([x0 + speed * t, np.full(len(t), y_m), np.full(len(t), ALT_M)])


def test_channel_reads_the_sensitivity_and_drops_the_exact_gate():
    sc = SimpleNamespace(channel=SimpleNamespace(reference_power_dbm=-30.0, path_loss_exponent=2.85,
                                                 shadowing_sigma_db=6.0, reference_distance_m=1.0,
                                                 receiver_sensitivity_dbm=-92.0),
                         fleet=SimpleNamespace(comm_range_m=150.0))
    ch = ChannelModel.from_scenario(sc)
    assert ch.sensitivity_dbm == -92.0 and ch.gate_m == np.inf
    assert ChannelModel(comm_range_m=150.0).gate_m == 150.0
    # 50 % of the frames heard at the median range where mu = S (~150 m for this channel)
    d50 = float(np.exp(ch.threshold_log_range))
    assert abs(float(ch.rssi_dbm(d50)) - (-92.0)) < 1e-9 and 140.0 < d50 < 160.0


def test_information_factors_are_the_known_limits():
    # far inside the range: a heard frame is a plain Gaussian one; at the edge it holds little
    assert truncated_information_factor(-8.0) == pytest.approx(1.0, abs=1e-9)
    assert truncated_information_factor(3.0) < 0.1
    # the Tobit information at z -> -inf is the Gaussian's, and it is positive everywhere
    z = np.linspace(-6, 6, 25)
    assert tobit_information_factor(-8.0) == pytest.approx(1.0, abs=1e-6)
    assert np.all(tobit_information_factor(z) > 0)
    r, dr = log_probability_residual(np.array([40.0, 0.0]), np.array([3.0, 3.0]))
    assert r[0] == 0.0 and dr[0] == 0.0 and r[1] == pytest.approx(np.sqrt(6 * np.log(2)))


def _problem(tx: bool, rng, counts: bool = False) -> tuple[Problem, np.ndarray]:
    truth = np.array([20.0, 90.0])
    t1, x1 = leg(0.0, 0.0)
    t2, x2 = leg(180.0, 60.0)
    slots = SlotBatch.concat([frames_heard(FIELD, truth, t1, x1, rng), frames_heard(FIELD, truth, t2, x2, rng, 2)])
    data = prepare(slots, FIELD)
    passes = find_passes(data.t_s, float(data.t_s.max()), 0.01)
    assert passes is not None
    cens = Censored(np.array([5.0, 70.0]), np.array([[0.0, -120.0, ALT_M], [10.0, 300.0, ALT_M]]), np.array([4.0, 6.0]))
    if counts:  # burst 0 heard 3 times by one vehicle, not by another; burst 1 heard once
        cens = Censored(np.array([5.0, 5.0, 70.0]), np.array([[0.0, -120.0, ALT_M], [30.0, 10.0, ALT_M],
                                                             [10.0, 300.0, ALT_M]]),
                        np.zeros(3), np.array([0.0, 3.0, 1.0]), np.array([4, 4, 9]), FramesPrior(np.ones(12)))
    if counts == "exposure":  # and the bursts nobody heard, along both legs
        from uavloc_gcs.estimation.evidence import burst_exposure, burst_rate_prior

        ex = burst_exposure([(1, t1, x1), (2, t2, x2)], slots, frames_prior=cens.prior,
                            rates=burst_rate_prior((20.0, 135.0), 0.54))
        cens = replace(cens, exposure=ex)
    p = Problem(data, True, tx, 1.5, 0.3, passes, threshold_y=FIELD.threshold_log_range,
                log_range_sigma=FIELD.log_range_sigma, censored=censored_rows(cens, data, passes),
                turn_at_s=30.0)
    theta = np.zeros(p.size)
    theta[:4] = [25.0, 80.0, 0.3, -0.2]
    if tx:
        theta[p.beta_index] = 0.1
    theta[p.base_size:p.offsets_end] = rng.normal(0.0, 3.0, p.offsets_end - p.base_size)
    theta[p.offsets_end:] = [0.2, -0.1]
    return p, theta


@pytest.mark.parametrize("tx,counts", [(False, False), (True, False), (True, True), (True, "exposure")])
def test_truncated_and_censored_jacobian_matches_finite_differences(tx, counts):
    p, theta = _problem(tx, np.random.default_rng(4), counts)
    jac = p.jacobian(theta)
    num = np.empty_like(jac)
    for k in range(len(theta)):
        h = 1e-6 * max(1.0, abs(theta[k]))
        e = np.zeros_like(theta)
        e[k] = h
        num[:, k] = (p.residuals(theta + e) - p.residuals(theta - e)) / (2 * h)
    rows = slice(0, p.data_rows)  # the truncated slots and the censoring rows
    assert p.data_rows == len(p.data.t_s) + 2 + (counts == "exposure")  # two silences, or two bursts (+ exposure)
    np.testing.assert_allclose(jac[rows], num[rows], rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(jac, num, rtol=1e-5, atol=1e-7)
    # the cost is the data's -2 ln likelihood: Gaussian + 2 n (-ln Phi(-z)) + 2 k (-ln Phi(z))
    r = p.data_residuals(theta)
    assert np.all(r[len(p.data.t_s):] >= 0)  # the censored rows (the slots' are signed roots)


def test_crb_information_is_the_estimators():
    rng = np.random.default_rng(2)
    truth, vel = np.array([20.0, 90.0]), np.array([0.3, -0.2])
    t1, x1 = leg(0.0, 0.0)
    slots = frames_heard(FIELD, truth, t1, x1, rng)
    data = prepare(slots, FIELD, merge_s=0.0)
    t_ref = float(data.t_c)
    cens = Censored(np.array([5.0]), np.array([[0.0, 200.0, ALT_M]]), np.array([4.0]))
    p = Problem(data, True, False, 1.5, 0.3, threshold_y=FIELD.threshold_log_range,
                log_range_sigma=FIELD.log_range_sigma, censored=censored_rows(cens, data, None))
    theta = np.concatenate([truth, vel])
    want = p.data_information(theta)
    got = data_information(slots, FIELD, truth, vel, t_ref) + censored_information(cens, FIELD, truth, vel, t_ref)
    np.testing.assert_allclose(got, want, rtol=1e-9)
    # a frame sent holds more than it does once heard (the edge's information is in hearing it)
    full = frames_information(t1, x1, FIELD, truth, vel, t_ref)
    assert np.trace(full) > np.trace(data_information(slots, FIELD, truth, vel, t_ref))


def test_the_untruncated_fit_is_biased_near_the_threshold_and_the_truncated_one_is_not():
    """A static phone 160 m off two crossing legs (slant ~180 m, below half of its frames heard):
    the heard frames' RSSI is biased up, so the Gaussian fit puts the phone nearer the tracks; the
    truncated likelihood does not. 200 draws."""
    rng = np.random.default_rng(11)
    truth = np.array([160.0, 160.0])
    t1, x1 = leg(0.0, 0.0)
    t2 = 40.0 + np.arange(0.0, 24.0, 0.1)
    x2 = np.column_stack([np.zeros(len(t2)), -300.0 + 25.0 * (t2 - 40.0), np.full(len(t2), ALT_M)])
    gauss = ChannelModel(-30.0, 2.85, 6.0, 1.0)
    err = {"old": [], "new": []}
    for _ in range(200):
        slots = SlotBatch.concat([frames_heard(FIELD, truth, t1, x1, rng), frames_heard(FIELD, truth, t2, x2, rng, 2)])
        for key, ch in (("old", gauss), ("new", FIELD)):
            data = prepare(slots, ch)
            p = Problem(data, False, False, 0.0, 0.3, threshold_y=ch.threshold_log_range,
                        log_range_sigma=ch.log_range_sigma)
            theta, _ = p.fit(truth.copy())
            err[key].append(theta - truth)
    old, new = np.mean(err["old"], axis=0), np.mean(err["new"], axis=0)
    sd = np.std(err["new"], axis=0) / np.sqrt(200)
    # both coordinates pulled towards the legs (the origin) by tens of metres without the truncation
    assert np.all(old < -20.0)
    assert np.all(np.abs(new) < np.maximum(3.0 * sd, 4.0))
    assert np.sqrt(np.mean(np.sum(np.square(err["new"]), axis=1))) < np.sqrt(
        np.mean(np.sum(np.square(err["old"]), axis=1)))


def test_censored_silence_only_within_heard_bursts():
    heard = SlotBatch(np.array([10.0, 10.3, 10.6, 100.0]), np.array([1, 1, 3, 1]), np.zeros((4, 3)),
                      np.zeros(4, np.int64), np.full(4, -80.0), np.array([2, 3, 1, 1]))
    assert [len(g) for _, _, g in burst_windows(heard.t_s)] == [3, 1]
    t = np.arange(0.0, 200.0, 0.5)
    track = np.column_stack([t, np.zeros(len(t)), np.full(len(t), ALT_M)])
    tracks = [(1, t, track), (2, t, track + [0.0, 50.0, 0.0]), (3, t[:100], track[:100])]
    c = censored_silence(tracks, heard)
    # burst 1 (10.0-10.6 s): heard by 1 (5 frames) and 3; vehicle 2 listened: one row, 5 frames;
    # burst 2 (100 s): heard by 1 (1 frame); 2 listened, 3 had landed (its track ends at 49.5 s)
    assert list(c.t_s) == [10.3, 100.0] and list(c.frames) == [5.0, 1.0]
    np.testing.assert_allclose(c.xyz_m[0], [10.3, 50.0, ALT_M])
    assert len(censored_silence(tracks, heard, frames=1.0)) == 2
    assert len(censored_silence(tracks, SlotBatch.empty())) == 0


def _one_leg_bursts(rng):
    """A static phone 60 m north of vehicle 1's leg, heard in three bursts of 10 frames (those
    above the threshold kept); vehicle 2 flies a parallel leg 150 m south at the same time and
    hears none of them."""
    truth = np.array([0.0, 60.0])
    t1, x1 = leg(0.0, 0.0)
    t2, x2 = leg(-150.0, 0.0)
    m = np.zeros(len(t1), bool)
    for tb in (8.0, 12.0, 16.0):
        m |= (t1 >= tb) & (t1 < tb + 0.95)
    return truth, frames_heard(FIELD, truth, t1[m], x1[m], rng), [(1, t1, x1), (2, t2, x2)]


def test_censored_silence_rules_out_the_mirror_the_heard_bursts_cannot():
    """Without the silences the two sides of the leg fit the bursts equally (the mirror holds half
    the mass); vehicle 2's silence during the bursts rules out the south side in every seed."""
    for seed in (0, 1, 2):
        truth, slots, tracks = _one_leg_bursts(np.random.default_rng(seed))
        alone = estimate_emitter(slots, FIELD, max_speed_m_s=1.5, model_motion=False)
        assert alone.mirror is not None and alone.mirror.holds_mass and alone.ambiguous
        cens = censored_silence(tracks, slots)
        assert len(cens) == 3 and np.all(cens.frames >= 5)
        for moving in (False, True):
            est = estimate_emitter(slots, FIELD, max_speed_m_s=1.5, model_motion=moving, censored=cens)
            assert est.position_xy_m[1] > 0 and not est.ambiguous  # the north side, the truth's
            assert est.mirror is None or est.mirror.relative_likelihood < 0.01
            assert np.linalg.norm(est.position_xy_m - truth) <= est.radius95_m < alone.radius95_m


def test_censored_needs_a_threshold():
    truth, slots, tracks = _one_leg_bursts(np.random.default_rng(0))
    with pytest.raises(EstimationError, match="threshold"):
        estimate_emitter(slots, ChannelModel(-30.0, 2.85, 6.0), max_speed_m_s=1.5,
                         censored=censored_silence(tracks, slots))


def test_transmit_power_is_estimated_under_the_threshold():
    """A phone 6 dB louder than nominal, heard from two crossing legs near the edge: estimated
    jointly, the offset comes out within a few dB and the position stays close."""
    rng = np.random.default_rng(5)
    truth = np.array([60.0, 70.0])
    t1, x1 = leg(0.0, 0.0)
    t2 = 40.0 + np.arange(0.0, 24.0, 0.1)
    x2 = np.column_stack([np.zeros(len(t2)), -300.0 + 25.0 * (t2 - 40.0), np.full(len(t2), ALT_M)])
    slots = SlotBatch.concat([frames_heard(FIELD, truth, t1, x1, rng, tx_db=6.0),
                              frames_heard(FIELD, truth, t2, x2, rng, 2, tx_db=6.0)])
    est = estimate_emitter(slots, FIELD, max_speed_m_s=0.0, model_motion=False, estimate_tx_power=True)
    assert abs(est.tx_offset_db - 6.0) < 3.0
    assert np.linalg.norm(est.position_xy_m - truth) < 30.0


def test_estimate_all_takes_each_emitters_censored_rows():
    truth, slots, tracks = _one_leg_bursts(np.random.default_rng(0))
    from uavloc_gcs.estimation import estimate_all

    cens = censored_silence(tracks, slots)
    out = estimate_all(slots, FIELD, max_speed_m_s=1.5, model_motion=False, censored={0: cens})
    one = estimate_emitter(slots, FIELD, max_speed_m_s=1.5, model_motion=False, censored=cens)
    np.testing.assert_array_equal(out[0].position_xy_m, one.position_xy_m)
    assert out[0].position_xy_m[1] > 0


def test_hearing_counts_with_a_frames_prior_rule_out_the_far_side_too():
    """The same bursts with every listening vehicle's count (a frames prior of 1-12 frames): the
    estimate stays on the true side and its radius is no larger than with the silences alone."""
    truth, slots, tracks = _one_leg_bursts(np.random.default_rng(1))
    plain = estimate_emitter(slots, FIELD, max_speed_m_s=1.5, model_motion=False,
                             censored=censored_silence(tracks, slots))
    cens = censored_silence(tracks, slots, frames_prior=FramesPrior(np.ones(12)))
    assert len(cens) == 6 and set(cens.heard[cens.heard > 0]) and cens.prior is not None
    est = estimate_emitter(slots, FIELD, max_speed_m_s=1.5, model_motion=False, censored=cens)
    assert est.position_xy_m[1] > 0 and not est.ambiguous
    assert np.linalg.norm(est.position_xy_m - truth) <= est.radius95_m <= plain.radius95_m


# -- the bursts nobody heard (evidence.Exposure) ------------------------------------------------


def test_exposure_loglik_gradient_matches_finite_differences_and_the_table_matches_the_sum():
    from uavloc_gcs.estimation.evidence import burst_rate_prior, exposure_loglik

    rng = np.random.default_rng(3)
    rates, log_w = burst_rate_prior((20.0, 135.0), (0.86, 0.54), log_uniform=True)
    log_p = FramesPrior(np.ones(27)).log_p
    cell = np.repeat(np.arange(20), 2)  # two vehicles listening in each of 20 cells
    z = rng.normal(0.5, 1.5, (1, 40))
    args = (cell, 2.0, rates, log_w, log_p, 3)
    logf, dz, logf0 = exposure_loglik(z, *args)
    assert logf[0] < logf0  # F(A) is largest where nothing could have been heard
    num = [(exposure_loglik(z + e, *args)[0] - exposure_loglik(z - e, *args)[0])[0] / 2e-6 for e in 1e-6 * np.eye(40)]
    np.testing.assert_allclose(dz[0], num, rtol=1e-5, atol=1e-9)
    assert np.all(dz[0] > 0)  # farther from every vehicle (z up): fewer bursts missed, more likely
    many = z + rng.normal(0.0, 0.3, (200, 40))  # the samplers' path (interpolated table)
    exact = [exposure_loglik(many[i:i + 1], *args)[0][0] for i in range(200)]
    np.testing.assert_allclose(exposure_loglik(many, *args)[0], exact, atol=1e-6)


def test_burst_rate_prior_refuses_gaps_that_are_not_positive_and_ordered():
    from uavloc_gcs.estimation.evidence import burst_rate_prior

    rates, log_w = burst_rate_prior((20.0, 135.0), 0.54)
    assert np.isclose(np.exp(log_w).sum(), 1.0) and rates.max() < 1 / 20.0 and rates.min() > 1 / 160.0
    assert np.exp(log_w[-1]) > np.exp(log_w[0])  # uniform in the gap: long gaps weigh more on a log grid
    for bad in ((0.0, 10.0), (30.0, 20.0), (-5.0, 10.0)):
        with pytest.raises(ValueError, match="median gap"):
            burst_rate_prior(bad)


def _orbit_one_burst(rng):
    """A vehicle circles (110 m, 12 m/s, 80 m up) for 600 s and hears one burst 260 m from the
    orbit's centre, with another vehicle's lane far away."""
    t = np.arange(0.0, 600.0, 0.1)
    ang = t * 12.0 / 110.0
    orbit = np.column_stack([110.0 * np.cos(ang), 110.0 * np.sin(ang), np.full(len(t), ALT_M)])
    truth = np.array([260.0, 0.0])
    at = int(np.argmin(np.abs(t - 300.0) + 1e6 * (np.cos(ang) < 0.999)))  # near 300 s, over the truth's side
    tf = t[at] + np.sort(rng.uniform(0.0, 1.0, 12))
    xyz = np.column_stack([np.interp(tf, t, orbit[:, c]) for c in range(3)])
    slots = frames_heard(FIELD, truth, tf, xyz, rng)
    return truth, slots, [(1, t, orbit)]


def test_the_bursts_nobody_heard_push_the_person_away_from_where_the_vehicle_listened_longest():
    """Ten minutes of orbiting heard one burst: a person that close to the orbit would have been
    heard more often, so with the exposure the estimate moves away from the orbit's centre, and
    the fit's Jacobian holds the exposure's row."""
    from uavloc_gcs.estimation.evidence import burst_rate_prior

    rng = np.random.default_rng(11)
    truth, slots, tracks = _orbit_one_burst(rng)
    assert len(slots) >= 2
    prior = FramesPrior(np.ones(12))
    rates = burst_rate_prior((20.0, 135.0), 0.54)
    plain = estimate_emitter(slots, FIELD, max_speed_m_s=1.5, model_motion=False,
                             censored=censored_silence(tracks, slots, frames_prior=prior))
    cens = censored_silence(tracks, slots, frames_prior=prior, exposure_rates=rates)
    ex = cens.exposure
    assert ex is not None and ex.bursts == 1
    # the rows: one per 2 s, from 150 s before the burst to 150 s after it
    assert len(ex) == pytest.approx(151, abs=2) and ex.t_s.min() >= slots.t_s.min() - 151.0
    est = estimate_emitter(slots, FIELD, max_speed_m_s=1.5, model_motion=False, censored=cens)
    assert np.linalg.norm(est.position_xy_m) > np.linalg.norm(plain.position_xy_m) + 20.0
    assert np.linalg.norm(est.position_xy_m - truth) < np.linalg.norm(plain.position_xy_m - truth)

    data = prepare(slots, FIELD)
    p = Problem(data, False, True, 1.5, 0.5, threshold_y=FIELD.threshold_log_range,
                log_range_sigma=FIELD.log_range_sigma, censored=censored_rows(cens, data, None))
    theta = np.array([150.0, 40.0, 0.1])
    assert p.data_rows == len(data.t_s) + 1 + 1  # one burst's counts, one exposure
    jac = p.jacobian(theta)
    num = np.column_stack([(p.residuals(theta + e) - p.residuals(theta - e)) / 2e-6 for e in 1e-6 * np.eye(3)])
    np.testing.assert_allclose(jac, num, rtol=1e-5, atol=1e-7)
