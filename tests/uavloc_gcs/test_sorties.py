"""Sorties (uavloc_gcs/sorties.py, issue 38): a vehicle's path cut into one sortie per pack."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mission_io import plan as plan_file
from mission_io import waypoints as wpl_file
from uavloc_gcs.energy import ZENG_2019, route_cost
from uavloc_gcs.errors import InfeasibleError
from uavloc_gcs.mission import NAV_RETURN_TO_LAUNCH
from uavloc_gcs.scan import plan_scan
from uavloc_gcs.scenario import loads_scenario
from uavloc_gcs.sorties import scan_sorties, sortie_missions, sortie_tracks, split_path

E10 = float(ZENG_2019.energy_per_m_j(10.0))  # J per metre at 10 m/s
LANES = np.array([[100, 0], [1100, 0], [1100, 100], [100, 100], [100, 200], [1100, 200]], float)


def test_a_path_longer_than_a_pack_is_cut_where_the_pack_just_gets_home():
    """Known answer: 2,500 m of flight per pack. Sortie 1: 100 m to the path, 2,187.5 m along it to
    (100, 187.5), 212.5 m home. Sortie 2 flies home -> (100, 187.5) and the rest."""
    sp = split_path(LANES, speed_m_s=10.0, pack_j=2500 * E10, swap_s=120.0)
    assert sp.packs == 2 and sp.complete
    s1, s2 = sp.sorties
    assert s1.path_to_m == pytest.approx(2187.5, abs=1e-6) and s1.length_m == pytest.approx(2500.0, abs=1e-6)
    assert s1.energy_j == pytest.approx(2500 * E10, rel=1e-9)
    np.testing.assert_allclose(s1.waypoints_xy_m[-1], [100.0, 187.5], atol=1e-6)
    np.testing.assert_allclose(s2.waypoints_xy_m[0], [100.0, 187.5], atol=1e-6)
    np.testing.assert_allclose(s2.waypoints_xy_m[1:], LANES[4:], atol=1e-9)
    assert s2.length_m == pytest.approx(212.5 + 1012.5 + np.hypot(1100, 200), abs=1e-6)
    assert sp.duration_s == pytest.approx((s1.length_m + s2.length_m) / 10.0 + 120.0)
    np.testing.assert_allclose(sp.start_times_s(), [0.0, 250.0 + 120.0])


def test_one_pack_that_holds_the_route_is_one_sortie_of_the_routes_cost():
    sp = split_path(LANES, speed_m_s=10.0, pack_j=1e9, swap_s=120.0)
    rc = route_cost(np.vstack([[0, 0], LANES, [0, 0]]), 10.0)
    assert sp.packs == 1 and sp.swaps == 0 and sp.duration_s == pytest.approx(rc.duration_s)
    assert sp.sorties[0].energy_j == pytest.approx(rc.energy_j)
    np.testing.assert_array_equal(sp.sorties[0].waypoints_xy_m, LANES)


def test_a_drained_first_pack_cuts_sooner_and_max_sorties_stops_the_split():
    fresh = split_path(LANES, speed_m_s=10.0, pack_j=2500 * E10)
    used = split_path(LANES, speed_m_s=10.0, pack_j=2500 * E10, first_pack_j=1200 * E10)
    assert used.sorties[0].path_to_m < fresh.sorties[0].path_to_m
    assert used.sorties[0].energy_j == pytest.approx(1200 * E10, rel=1e-9)
    short = split_path(LANES, speed_m_s=10.0, pack_j=2300 * E10, max_sorties=2)
    assert short.packs == 2 and not short.complete and short.flown_m < short.path_m


def test_a_path_no_pack_can_make_progress_on_is_refused_in_one_sentence():
    far = np.array([[3000.0, 0.0], [3100.0, 0.0]])
    with pytest.raises(InfeasibleError, match="uav3 cannot fly its path beyond 0 of 100 m"):
        split_path(far, speed_m_s=10.0, pack_j=5000 * E10, name="uav3")


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(-800, 800), st.floats(-800, 800)), min_size=1, max_size=12),
       st.floats(2000.0, 8000.0))
def test_sorties_cover_the_path_in_order_each_within_its_pack(points, pack_m):
    path = np.array(points, float)
    try:
        sp = split_path(path, speed_m_s=12.0, pack_j=pack_m * float(ZENG_2019.energy_per_m_j(12.0)))
    except InfeasibleError:
        assert 2 * np.linalg.norm(path, axis=1).max() > pack_m - 2.0  # only when some point is out of reach
        return
    pack_j = pack_m * float(ZENG_2019.energy_per_m_j(12.0))
    assert sp.complete and sp.sorties[0].path_from_m == 0.0
    assert sp.sorties[-1].path_to_m == pytest.approx(sp.path_m)
    for a, b in zip(sp.sorties, sp.sorties[1:]):
        assert b.path_from_m == a.path_to_m
        # greedy: every sortie but the last empties its pack (less the centimetres of dropped duplicate points)
        assert a.energy_j == pytest.approx(pack_j, rel=1e-6, abs=0.1 * float(ZENG_2019.energy_per_m_j(12.0)))
    for s in sp.sorties:
        assert s.energy_j <= pack_j * (1 + 1e-9)
        route = np.vstack([[0, 0], s.waypoints_xy_m, [0, 0]])
        assert route_cost(route, 12.0).length_m == pytest.approx(s.length_m, rel=1e-9, abs=1e-6)


def _scenario(batteries: int, energy_j: float = 15_000.0) -> object:
    return loads_scenario(f"""
[area]
origin_lat_deg = 47.3977
origin_lon_deg = 8.5456
width_m = 500
height_m = 300
[fleet]
vehicles = 2
speed_m_s = 20
energy_budget_j = {energy_j}
batteries = {batteries}
battery_swap_s = 90
""")


def test_a_scan_beyond_one_pack_flies_in_sorties_and_too_few_packs_is_refused():
    sc = _scenario(3)
    plan = plan_scan(sc)  # one pack would refuse it (scan._check_energy)
    with pytest.raises(InfeasibleError, match="needs .* kJ for its"):
        plan_scan(_scenario(1))
    sorties = scan_sorties(sc, plan)
    assert [sp.packs for sp in sorties] == [2, 2]
    with pytest.raises(InfeasibleError, match=r"needs 2 packs .* has 1 \(fleet.batteries\)"):
        scan_sorties(sc.replace(fleet={"batteries": 1}), plan)
    tracks = sortie_tracks(sorties, 20.0, 100.0)
    assert len(tracks) == 4
    (t1, _), (t2, _) = tracks[:2]
    assert t2[0] - t1[-1] == pytest.approx(90.0)  # the swap on the ground hears nothing


def test_sortie_missions_are_valid_files_each_ending_with_rtl(tmp_path):
    for autopilot in ("ardupilot", "px4"):
        sc = _scenario(3).replace(fleet={"autopilot": autopilot})
        plan = plan_scan(sc)
        sorties = scan_sorties(sc, plan)
        missions = sortie_missions(sc, plan, sorties)
        assert [len(m) for m in missions] == [sp.packs for sp in sorties]
        for per, sp in zip(missions, sorties):
            for m, s in zip(per, sp.sorties):
                assert m.items[0].command == 22 and m.items[-1].command == NAV_RETURN_TO_LAUNCH
                ll = sc.frame.to_wgs84_latlon(s.waypoints_xy_m)
                np.testing.assert_allclose([(w.lat_deg, w.lon_deg) for w in m.waypoints()], ll, atol=1e-9)
                back = plan_file.read(plan_file.write(tmp_path / "s.plan", m))
                assert [i.command for i in back.items] == [i.command for i in m.items]
                again = wpl_file.read(wpl_file.write(tmp_path / "s.waypoints", m), autopilot=autopilot)
                assert len(again.waypoints()) == len(m.waypoints())
