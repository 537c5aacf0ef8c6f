"""The shadowing process: the closed-form AR(1) recursion equals the plain loop, across blocks."""

import numpy as np
import pytest

from sim_link.world.channel import ChannelParams, ShadowingState, _ar1, draw_shadowing_db


def test_closed_form_ar1_equals_the_loop_over_many_blocks():
    rng = np.random.default_rng(0)
    m, s = 5000, 3
    log_rho = -rng.uniform(0.0, 0.5, size=(m, s))  # spans ~600 in log many times over: several blocks
    innov = rng.standard_normal((m, s))
    x0 = rng.standard_normal(s)
    fast = _ar1(x0, log_rho, innov)
    slow = np.empty_like(innov)
    x = x0
    for i in range(m):
        x = np.exp(log_rho[i]) * x + innov[i]
        slow[i] = x
    assert np.allclose(fast, slow, atol=1e-9)


def test_correlated_samples_are_stationary_even_for_short_decorrelation():
    p = ChannelParams(correlated=True, decorrelation_m=0.5, samples_per_slot=10, shadowing_sigma_db=4.0)
    st = ShadowingState(np.random.default_rng(1))
    moved = np.full((20000, 2), 0.625)  # 25 m/s x 25 ms per slot, two phones
    psi = draw_shadowing_db(p, st, moved)
    assert np.all(np.isfinite(psi))
    assert psi.std() == pytest.approx(4.0, rel=0.03)
    flat = psi.reshape(-1, 2)[:, 0]
    rho = np.corrcoef(flat[:-1], flat[1:])[0, 1]
    assert rho == pytest.approx(np.exp(-0.0625 / 0.5), abs=0.02)  # one sample step = 6.25 cm
