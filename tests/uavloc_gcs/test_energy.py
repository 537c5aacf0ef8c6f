"""Zeng's rotary-wing power model against the check values in SPEC §1 / science.md §1."""

import numpy as np
import pytest

from uavloc_gcs.energy import ZENG_2019, RotorcraftPower, path_length_m, route_cost


@pytest.mark.parametrize(
    "speed, power",
    [(0, 168.48), (5, 143.61), (10, 126.03), (15, 138.54), (20, 178.30), (25, 248.95), (30, 356.28)],
)
def test_power_table(speed, power):
    assert ZENG_2019.power_w(speed) == pytest.approx(power, abs=0.02)


def test_optimal_speeds():
    v_me = ZENG_2019.max_endurance_speed_m_s()
    assert v_me == pytest.approx(10.21, abs=0.01)
    assert ZENG_2019.power_w(v_me) == pytest.approx(126.0, abs=0.01)
    v_mr = ZENG_2019.max_range_speed_m_s()
    assert v_mr == pytest.approx(18.30, abs=0.01)
    assert ZENG_2019.energy_per_m_j(v_mr) == pytest.approx(8.83, abs=0.01)


def test_inner_root_never_negative_at_high_speed():
    # The seed paper's V^2 typo makes the induced term NaN above ~5.7 m/s; the correct form is finite.
    v = np.linspace(0, 40, 401)
    p = ZENG_2019.power_w(v)
    assert np.all(np.isfinite(p)) and np.all(p > 0)


def test_route_cost():
    xy = np.array([[0, 0], [300, 400], [300, 0]])
    assert path_length_m(xy) == pytest.approx(900.0)
    c = route_cost(xy, 25.0)
    assert c.duration_s == pytest.approx(36.0)
    assert c.energy_j == pytest.approx(ZENG_2019.power_w(25.0) * 36.0)
    with pytest.raises(ValueError):
        route_cost(xy, 0.0)


def test_custom_parameters_change_power():
    heavier = RotorcraftPower(induced_w=120.0)
    assert heavier.hover_power_w() > ZENG_2019.hover_power_w()
