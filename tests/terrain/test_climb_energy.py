"""The energy of climbing (issue 28 item 4): W v_c on top of Zeng's level-flight power."""

from __future__ import annotations

import pytest

from uavloc_gcs.energy import ZENG_2019, RotorcraftPower
from uavloc_gcs.errors import InfeasibleError
from uavloc_gcs.scan import plan_scan, scan_missions
from uavloc_gcs.scenario import load_scenario
from uavloc_gcs.terrain_missions import check_climb_energy, climb_energy_j, mission_heights_m, terrain_safe

from .dems import EXAMPLES


def test_climb_power_is_the_weight_times_the_climb_rate_and_descents_are_free():
    assert ZENG_2019.weight_n == 20.0
    # Zeng's induced power Pi = (1 + k) W^1.5 / sqrt(2 rho A) with k = 0.1 is the same W
    w, rho, a = ZENG_2019.weight_n, ZENG_2019.air_density_kg_m3, ZENG_2019.rotor_disc_area_m2
    assert 1.1 * w**1.5 / (2 * rho * a) ** 0.5 == pytest.approx(ZENG_2019.induced_w, rel=1e-3)
    assert ZENG_2019.climb_power_w(2.5) == pytest.approx(50.0)
    assert ZENG_2019.climb_power_w(-1.5) == 0.0
    assert ZENG_2019.climb_energy_j([0.0, 100.0, 50.0, 150.0]) == pytest.approx(20.0 * 200.0)
    assert RotorcraftPower(weight_n=30.0).climb_energy_j([0.0, 10.0]) == pytest.approx(300.0)


def test_a_mountain_scan_s_climbs_are_counted_and_a_budget_they_break_is_refused():
    sc = load_scenario(EXAMPLES / "mountains.toml")
    plan = plan_scan(sc)
    missions = [terrain_safe(m, sc) for m in scan_missions(sc, plan)]
    h = mission_heights_m(missions[0], sc)
    assert h[0] == pytest.approx(sc.dem.height_at(0, 0))
    climbs = check_climb_energy(sc, plan.vehicles, missions)
    # each vehicle climbs at least from the launch ground to its highest point
    for m, c in zip(missions, climbs):
        hh = mission_heights_m(m, sc)
        assert c == pytest.approx(climb_energy_j(m, sc))
        assert c >= 20.0 * (hh.max() - hh[0]) - 1e-6 and c > 5_000.0
    tight = sc.replace(fleet={"energy_budget_j": (plan.vehicles[0].energy_j + 1000.0) / 0.85})
    with pytest.raises(InfeasibleError, match=r"uav\d needs .* kJ to climb over the terrain"):
        check_climb_energy(tight, plan.vehicles, missions)
