"""The air-to-ground channel model (uavloc_gcs/a2g.py): its sources, its calibration and its
integrals, each against an independent computation (quadrature, sampling, the ITU-R geometry).
The Monte Carlo of the simulator itself is tests/sim_link/world/test_airground.py."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy import integrate
from scipy.special import comb
from scipy.stats import norm

from uavloc_gcs import a2g
from uavloc_gcs.a2g import ENVIRONMENTS, LOS, NLOS, A2GChannel
from uavloc_gcs.examples import scenario_path
from uavloc_gcs.scenario import load_scenario


def _sf(state, u_db):
    """P(F > u) of the fading in dB, from scipy (independent of uavloc_gcs.a2g_fading's tables)."""
    from scipy.stats import ncx2

    p = 10.0 ** (np.asarray(u_db, float) / 10.0)
    if state == NLOS:
        return np.exp(-p)
    k = 10 ** 0.9
    return ncx2.sf(p, df=2, nc=2 * k, scale=1 / (2 * (k + 1)))


def _pdf(state, u_db):
    """Density [1/dB] of the fading in dB, from scipy."""
    from scipy.stats import ncx2

    p = 10.0 ** (np.asarray(u_db, float) / 10.0)
    jac = p * math.log(10) / 10
    if state == NLOS:
        return np.exp(-p) * jac
    k = 10 ** 0.9
    return ncx2.pdf(p, df=2, nc=2 * k, scale=1 / (2 * (k + 1))) * jac


@pytest.fixture(scope="module")
def urban() -> A2GChannel:
    return A2GChannel(ENVIRONMENTS["urban"], a2g.wi2sar_reference_power_dbm(-90.0), 2.0, 1.0, -90.0)


def test_los_probability_is_al_hourani_in_degrees():
    for env in ENVIRONMENTS.values():
        # at theta = a degrees the curve is 1 / (1 + a) by its form
        assert a2g.los_probability(env, env.los_a) == pytest.approx(1.0 / (1.0 + env.los_a))
        p = a2g.los_probability(env, np.linspace(0.0, 90.0, 91))
        assert np.all(np.diff(p) > 0) and p[-1] > 0.7
    # degrees, not radians: urban at 45 deg is 0.97; fed 45 deg in radians (0.785) it would be 0.19
    assert a2g.los_probability(ENVIRONMENTS["urban"], 45.0) == pytest.approx(0.968, abs=0.001)
    assert a2g.elevation_deg(100.0, 100.0) == pytest.approx(45.0)


@pytest.mark.parametrize("name, tol", [("suburban", 0.1), ("urban", 0.05)])
def test_al_hourani_curve_follows_the_itu_p1410_geometry_it_was_fitted_to(name, tol):
    """Al-Hourani's (a, b) were fitted to ITU-R P.1410's building geometry at platform heights of
    kilometres: there the curve and the geometry agree (the tuples of ENVIRONMENTS belong together)."""
    env = ENVIRONMENTS[name]
    for theta in (10.0, 20.0, 30.0, 45.0, 60.0, 80.0):
        geo = a2g.p1410_los_probability(env, 2000.0 / math.tan(math.radians(theta)), 2000.0)
        assert float(a2g.los_probability(env, theta)) == pytest.approx(geo, abs=tol)


def test_fading_law_is_the_sampled_rician_and_rayleigh():
    from uavloc_gcs.a2g_fading import fading_law

    rng = np.random.default_rng(4)
    n = 400_000
    k = 10 ** 0.9
    h = math.sqrt(k / (k + 1)) + math.sqrt(1 / (2 * (k + 1))) * (rng.standard_normal(n) + 1j * rng.standard_normal(n))
    for k_db, db in ((9.0, 10 * np.log10(np.abs(h) ** 2)), (None, 10 * np.log10(rng.exponential(size=n)))):
        law = fading_law(k_db)
        m, sd = a2g.fading_db_moments(k_db)
        assert m == pytest.approx(db.mean(), abs=0.03) and sd == pytest.approx(db.std(), abs=0.03)
        for u in (-10.0, -3.0, 0.0, 2.0, 5.0):
            assert float(law.survival(u)) == pytest.approx(np.mean(db > u), abs=0.003)
        # the law of the mean of 2 frames (a slot) against the sampled means
        pairs = db[: n // 2 * 2].reshape(-1, 2).mean(axis=1)
        hist, edges = np.histogram(pairs, bins=40, range=(-8.0, 4.0), density=False)
        mids = 0.5 * (edges[1:] + edges[:-1])
        want = np.exp(law.log_density(mids, 2)) * (edges[1] - edges[0]) * len(pairs)
        assert np.all(np.abs(hist - want) < 5 * np.sqrt(want) + 20)
        # and the sampler draws it
        got = law.sample(rng.standard_normal((n, 2)))
        assert np.mean(got > 0.0) == pytest.approx(float(law.survival(0.0)), abs=0.003)
    assert a2g.fading_db_moments(None)[0] == pytest.approx(-10 / math.log(10) * 0.5772156649, abs=1e-3)


def test_calibration_puts_a_los_frame_at_wi2sar_range_and_towns_block_more_than_the_wild():
    sc = load_scenario(scenario_path("field"))
    ch = A2GChannel.from_scenario(sc)
    assert sc.channel.environment == "urban" and ch is not None
    open_terrain = dataclasses.replace(ch, environment=dataclasses.replace(ch.environment, excess_los_db=0.0))
    assert open_terrain.state_range_m(LOS) == pytest.approx(a2g.WI2SAR_LOS_RANGE_M, rel=0.001)
    # ... and it is a probability 1/2 of hearing, shadowing and fading integrated
    always_los = dataclasses.replace(open_terrain, environment=dataclasses.replace(open_terrain.environment,
                                                                                     los_a=1e-12))
    h = math.sqrt(a2g.WI2SAR_LOS_RANGE_M ** 2 - 100.0 ** 2)
    assert float(always_los.frame_heard_probability(h, 100.0)) == pytest.approx(0.5, abs=0.002)
    wild = a2g.wi2sar_blocked_excess_db(ch.reference_power_dbm, ch.sensitivity_dbm)
    assert 3.0 < wild < 6.0  # Wi2SAR's occluded phones (foliage, bags) lose about 4.7 dB
    for env in ENVIRONMENTS.values():  # a town never blocks less than Wi2SAR's wilderness did
        assert env.excess_nlos_db - env.excess_los_db > wild + 10.0


def test_frame_heard_probability_is_the_integral_over_state_shadowing_and_fading(urban):
    for h, z in ((180.0, 60.0), (40.0, 30.0), (350.0, 100.0)):
        d = math.hypot(h, z)
        p_los = float(urban.los_probability(h, z))
        want = 0.0
        for s, w in ((LOS, p_los), (NLOS, 1 - p_los)):
            mp = float(urban.mean_power_dbm(d, s))
            inner = integrate.quad(lambda x: norm.pdf(x, 0, urban.shadow_db[s]) * _sf(s, urban.sensitivity_dbm - mp - x),
                                   -80, 80, limit=200)[0]
            want += w * inner
        assert float(urban.frame_heard_probability(h, z)) == pytest.approx(want, abs=2e-4)


def _quad_burst(ch, h, z, k, c=1.0, tx=0.0, n=None):
    """Brute force: P(n heard of k) (n None: P(at least one)) by quadrature over the shadowing."""
    d = math.hypot(h, z)
    p_los = float(ch.los_probability(h, z))
    out = 0.0
    for s, w in ((LOS, p_los), (NLOS, 1 - p_los)):
        mp = float(ch.mean_power_dbm(d, s, tx))

        def f(x):
            q = c * _sf(s, ch.sensitivity_dbm - mp - x)
            val = 1 - (1 - q) ** k if n is None else comb(k, n) * q ** n * (1 - q) ** (k - n)
            return norm.pdf(x, 0, ch.shadow_db[s]) * val

        out += w * integrate.quad(f, -90, 90, limit=200)[0]
    return out


@pytest.mark.parametrize("h, z, k", [(50.0, 30.0, 1), (150.0, 100.0, 8), (260.0, 60.0, 27), (30.0, 100.0, 80)])
def test_burst_and_count_probabilities_agree_with_quadrature(urban, h, z, k):
    assert float(urban.burst_heard_probability(h, z, k, channel_share=0.7)) == pytest.approx(
        _quad_burst(urban, h, z, k, 0.7), abs=5e-4)
    pmf = urban.heard_count_pmf(h, z, k, channel_share=0.7)
    assert pmf.sum() == pytest.approx(1.0, abs=1e-9)
    for n in {0, 1, k // 2, k}:
        assert pmf[n] == pytest.approx(_quad_burst(urban, h, z, k, 0.7, n=n), abs=5e-4)


def _quad_likelihood(ch, rssi, counts, missed, h, z, c=1.0, tx=0.0):
    """Brute force: the likelihood of burst_log_likelihood by the trapezoid rule over the shadowing
    on a fine grid, with scipy's fading densities (a slot of two frames: their numerical convolution)."""
    d = math.hypot(h, z)
    p_los = float(ch.los_probability(h, z))
    x = np.linspace(-60.0, 60.0, 60_001)
    u = np.arange(-80.0, 20.0, 0.005)
    out = 0.0
    for s, w in ((LOS, p_los), (NLOS, 1 - p_los)):
        mp = float(ch.mean_power_dbm(d, s, tx))
        f1 = _pdf(s, u)
        f2 = np.convolve(f1, f1) * 0.005  # the sum of two frames' F on 2 u[0] + 0.005 k
        dens = np.ones_like(x)
        for r, n in zip(rssi, counts):
            if n == 1:
                dens = dens * _pdf(s, r - mp - x)
            else:  # the mean of two: density 2 f2(2 v)
                dens = dens * 2 * np.interp(2 * (r - mp - x), 2 * u[0] + 0.005 * np.arange(len(f2)), f2, left=0, right=0)
        miss = (1 - c * _sf(s, ch.sensitivity_dbm - mp - x)) ** missed
        out += w * integrate.trapezoid(norm.pdf(x, 0, ch.shadow_db[s]) * dens * miss, x)
    return out


@pytest.mark.parametrize("rssi, counts, missed, h, z", [
    ([-80.0], [1], 0, 120.0, 60.0),
    ([-84.0, -82.5, -86.0], [1, 2, 1], 5, 200.0, 100.0),
    ([], [], 12, 90.0, 30.0),
    ([-88.0, -89.5], [1, 1], 40, 250.0, 40.0),
    ([-60.0] * 6, [1] * 6, 1, 20.0, 30.0),
])
def test_burst_likelihood_agrees_with_quadrature(urban, rssi, counts, missed, h, z):
    got = float(urban.burst_log_likelihood(rssi, missed, h, z, counts=counts if counts else None))
    want = _quad_likelihood(urban, np.array(rssi), np.array(counts, float), missed, h, z)
    assert got == pytest.approx(math.log(want), abs=5e-3)


def test_burst_likelihood_integrates_to_the_count_probability(urban):
    """Over all values above the sensitivity, the likelihood of one heard frame of three is
    P(exactly one heard) / C(3, 1): the likelihood is a proper density of what the sensor sees."""
    h, z = 170.0, 80.0
    grid = np.linspace(-90.0, -30.0, 2401)
    dens = np.exp([float(urban.burst_log_likelihood([r], 2, h, z)) for r in grid])
    mass = integrate.trapezoid(dens, grid)
    assert 3 * mass == pytest.approx(float(urban.heard_count_pmf(h, z, 3)[1]), rel=5e-3)


def test_unknown_count_sums_the_known_counts(urban):
    pmf = np.array([0.0, 0.1, 0.2, 0.3, 0.25, 0.15])
    rssi, h, z = [-83.0, -85.0], np.array([60.0, 150.0, 240.0]), 50.0
    got = urban.burst_log_likelihood_unknown_sent(rssi, pmf, h, z, channel_share=0.8)
    want = np.zeros(3)
    for k in range(2, 6):
        want += pmf[k] * comb(k, 2) * np.exp(urban.burst_log_likelihood(rssi, k - 2, h, z, channel_share=0.8))
    assert np.allclose(got, np.log(want), atol=1e-9)
    assert np.all(np.isneginf(urban.burst_log_likelihood_unknown_sent([-80.0] * 7, pmf, h, z)))


def test_likelihood_is_vectorised_over_positions_and_fast(urban):
    import time

    rng = np.random.default_rng(1)
    h = rng.uniform(0, 400, (50, 100))
    z = np.full_like(h, 60.0)
    tx = rng.normal(0, 3, h.shape)
    ll = urban.burst_log_likelihood([-82.0, -84.0, -83.0], 4, h, z, tx_offset_db=tx)
    assert ll.shape == (50, 100) and np.all(np.isfinite(ll))
    one = urban.burst_log_likelihood([-82.0, -84.0, -83.0], 4, h[7, 9], z[7, 9], tx_offset_db=tx[7, 9])
    assert float(one) == pytest.approx(float(ll[7, 9]))
    t0 = time.perf_counter()
    for _ in range(5):
        urban.burst_log_likelihood([-82.0, -84.0, -83.0], 4, h, z, tx_offset_db=tx)
    assert (time.perf_counter() - t0) / 5 < 0.5  # 5,000 positions: about 10 ms on the 2-core machine


def test_hearing_costs_altitude_and_a_burst_reaches_further_than_a_frame(urban):
    frame = [urban.hearing_distance_m(z) for z in (100.0, 60.0, 40.0, 30.0)]
    burst = [urban.hearing_distance_m(z, frames=10) for z in (100.0, 60.0, 40.0, 30.0)]
    assert frame == sorted(frame, reverse=True) and frame[-1] < 0.5 * frame[0]
    assert all(b > f for b, f in zip(burst, frame))
    # the crossing is where the probability is 1/2
    assert float(urban.frame_heard_probability(frame[0], 100.0)) == pytest.approx(0.5, abs=0.002)
