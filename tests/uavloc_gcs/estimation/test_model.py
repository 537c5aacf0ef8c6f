"""Building blocks with closed-form answers: 95 % circles, the channel inversion, the annulus and
reach bounds, the Fisher information, and the access radius."""

import math

import numpy as np
import pytest

from uavloc_gcs.estimation import ChannelModel, access_radius_m, data_information, position_rmse_bound_m
from uavloc_gcs.estimation.annulus import annulus_bound_m, reach_bound_m
from uavloc_gcs.estimation.model import circle_probability, mixture_radius, radius_of_probability
from uavloc_gcs.observations import SlotBatch

CH = ChannelModel(comm_range_m=150.0)


def test_radius_of_probability_known_values():
    assert radius_of_probability(np.eye(2)) == pytest.approx(math.sqrt(-2 * math.log(0.05)), rel=1e-4)
    assert radius_of_probability(np.diag([4.0, 1e-12])) == pytest.approx(1.959964 * 2.0, rel=1e-4)
    cov = np.array([[3.0, 1.0], [1.0, 2.0]])
    r = radius_of_probability(cov)
    x = np.random.default_rng(0).multivariate_normal([0, 0], cov, 200_000)
    assert np.mean(np.hypot(*x.T) <= r) == pytest.approx(0.95, abs=0.003)
    assert circle_probability(cov, r) == pytest.approx(0.95, abs=1e-4)
    assert radius_of_probability(np.full((2, 2), np.inf)) == math.inf


def test_mixture_radius_against_sampling():
    """The circle about a point holding 95 % of a Gaussian mixture (a near twin of the estimate):
    the centred single Gaussian agrees with radius_of_probability, and off-centre and two-part
    mixtures with a large sample, to 1 % of the radius."""
    cov = np.array([[3.0, 1.0], [1.0, 2.0]])
    assert mixture_radius([0, 0], [(1.0, [0, 0], cov)]) == pytest.approx(radius_of_probability(cov), rel=0.01)
    assert mixture_radius([0, 0], [(1.0, [0, 0], np.diag([9.0, 1e-10]))]) == pytest.approx(1.96 * 3, rel=0.01)
    rng = np.random.default_rng(1)
    main = rng.multivariate_normal([1.0, 0.5], cov, 300_000)
    twin = rng.multivariate_normal([6.0, 0.0], np.diag([4.0, 4.0]), 100_000)  # a quarter of the mass
    for parts, x in [([(1.0, [1.0, 0.5], cov)], main),
                     ([(0.75, [1.0, 0.5], cov), (0.25, [6.0, 0.0], np.diag([4.0, 4.0]))], np.vstack([main, twin]))]:
        r = mixture_radius([0, 0], parts)
        assert r == pytest.approx(float(np.quantile(np.hypot(*x.T), 0.95)), rel=0.01)
    # a twin holding a quarter of the mass needs far less than a circle over its whole 95 % circle
    assert mixture_radius([0, 0], parts) < 6.0 + radius_of_probability(np.diag([4.0, 4.0]))
    assert mixture_radius([0, 0], [(1.0, [0, 0], np.full((2, 2), np.nan))]) == math.inf


def test_channel_inversion_matches_the_paper_numbers():
    assert CH.log_range_sigma == pytest.approx(0.4605, abs=1e-4)
    assert CH.log_range(CH.rssi_dbm(123.0)) == pytest.approx(math.log(123.0))


def _pass(y_m, n=400, t0=0.0, noise=None):
    t = t0 + np.arange(n) * 0.025
    x = -200 + 25 * (t - t0)
    xyz = np.column_stack([x, np.full(n, y_m), np.full(n, 100.0)])
    d = np.hypot(np.hypot(x, y_m), 100.0)
    rssi = CH.rssi_dbm(d) + (0 if noise is None else noise)
    keep = d <= 150
    return SlotBatch.from_columns(t[keep], np.ones(keep.sum()), xyz[keep], np.zeros(keep.sum()), rssi[keep],
                                  np.full(keep.sum(), 10))


def test_noise_free_rings_contain_the_truth_and_bound_is_finite():
    s = SlotBatch.concat([_pass(-50.0), _pass(40.0, t0=20.0)])
    y = CH.log_range(s.rssi_dbm)
    b = annulus_bound_m(np.zeros(2), s.t_s.max(), s.t_s, s.xyz_m[:, :2], s.xyz_m[:, 2], y, s.n_samples,
                        CH.log_range_sigma, 0.0)
    assert 0 < b < 250  # Bonferroni over ~900 rings: z = 3.9, each ring spans x0.57..x1.76 in range
    # a point 10 m off is still inside the set, so the bound from there is at least 10 m
    b2 = annulus_bound_m(np.array([10.0, 0.0]), s.t_s.max(), s.t_s, s.xyz_m[:, :2], s.xyz_m[:, 2], y,
                         s.n_samples, CH.log_range_sigma, 0.0)
    assert b2 >= 10.0
    # rings that cannot all hold (a far-off ghost) give NaN, not a number
    far = annulus_bound_m(np.zeros(2), 0.0, np.zeros(2), np.array([[0.0, 0.0], [5000.0, 0.0]]),
                          np.full(2, 100.0), np.log([101.0, 101.0]), np.array([10, 10]), CH.log_range_sigma, 0.0)
    assert math.isnan(far)


def test_reach_bound_of_one_pass_is_the_lens_of_the_first_and_last_slot():
    s = _pass(0.0, n=1000)
    r = reach_bound_m(np.zeros(2), s.t_s.max(), s.t_s, s.xyz_m[:, :2], s.xyz_m[:, 2], 150.0, 0.0)
    half = np.abs(s.xyz_m[:, 0]).max()
    reach = math.sqrt(150.0**2 - 100.0**2)
    assert r == pytest.approx(math.sqrt(reach**2 - half**2), rel=0.05)
    assert reach_bound_m(np.zeros(2), 0.0, s.t_s, s.xyz_m[:, :2], s.xyz_m[:, 2], math.inf, 0.0) == math.inf


def test_fisher_information_static_known_answer():
    # one sample right above at 100 m carries no horizontal information; one at 100 m east carries
    # (x / d^2)^2 / s^2 along east only
    s = SlotBatch.from_columns([0.0, 0.0], [1, 1], [[0, 0, 100.0], [-100.0, 0, 100.0]], [0, 0], [-80.0, -80.0], [1, 1])
    j = data_information(s, CH, [0.0, 0.0], [0.0, 0.0], 0.0, model_motion=False)
    assert j[0, 0] == pytest.approx((100.0 / 20000.0) ** 2 / CH.log_range_sigma**2)
    assert j[1, 1] == pytest.approx(0.0) and j[0, 1] == pytest.approx(0.0)
    assert position_rmse_bound_m(j) == math.inf


def test_access_radius_is_monotone_in_the_required_accuracy():
    from uavloc_gcs.estimation import estimate_emitter

    rng = np.random.default_rng(3)
    s = _pass(-60.0, n=900, noise=rng.normal(0, 4 / math.sqrt(10), 900))
    est = estimate_emitter(s, CH, max_speed_m_s=1.5)
    kw = dict(t_pass_s=est.t_ref_s + 20, altitude_m=100.0, speed_m_s=25.0, channel=CH, comm_range_m=150.0)
    radii = [access_radius_m(est, required_accuracy_m=a, **kw) for a in (0.5, 10.0, 20.0, 60.0)]
    assert radii[0] == 0.0  # no single pass gets a moving person to half a metre
    assert all(b >= a for a, b in zip(radii, radii[1:]))
    assert 0 < radii[-1] <= math.sqrt(150**2 - 100**2)


@pytest.mark.parametrize("y_m, static_10, cv_pos_10, cv_vel_10", [
    (100.0, 5.5, 9.7, 0.31), (130.0, 3.2, 6.1, 0.13), (160.0, 3.2, 9.8, 0.16)])
def test_fisher_information_reproduces_the_reference_crb_table(y_m, static_10, cv_pos_10, cv_vel_10):
    """science.md §2: legs at y = 80 and 240 m joined by a turn at x = 1120 m, 25 m/s, h = 100 m,
    D = 150 m, person at x = 600 m (static, or moving at (1, 0.5) m/s; bound at t = 0), 10 samples/slot."""
    pts = [(0, 80), (1120, 80), (1120, 240), (0, 240)]
    t, xy, t0 = [], [], 0.0
    for a, b in zip(pts[:-1], pts[1:]):
        a, b = np.asarray(a, float), np.asarray(b, float)
        n = int(np.linalg.norm(b - a) / 25 / 0.025)
        f = np.arange(n) / n
        t.append(t0 + f * n * 0.025)
        xy.append(a + np.outer(f, b - a))
        t0 += n * 0.025
    t, xy = np.concatenate(t), np.vstack(xy)
    for v, expected in ((np.zeros(2), static_10), (np.array([1.0, 0.5]), cv_pos_10)):
        pos = np.array([600.0, y_m]) + np.outer(t, v)
        d = np.sqrt(np.sum((pos - xy) ** 2, axis=1) + 100.0**2)
        m = d <= 150.0
        s = SlotBatch.from_columns(t[m], np.ones(m.sum()), np.column_stack([xy[m], np.full(m.sum(), 100.0)]),
                                   np.zeros(m.sum()), CH.rssi_dbm(d[m]), np.full(m.sum(), 10))
        moving = bool(np.any(v))
        j = data_information(s, CH, [600.0, y_m], v, 0.0, model_motion=moving)
        assert position_rmse_bound_m(j) == pytest.approx(expected, abs=0.06)
        if moving:
            cov = np.linalg.inv(j)
            assert math.sqrt(cov[2, 2] + cov[3, 3]) == pytest.approx(cv_vel_10, abs=0.01)
