"""Fast mission simulation: flight model, energy, and whole missions on a small scenario."""

import math
from pathlib import Path

import numpy as np
import pytest

from sim_link.experiments.missionsim import METHODS, Flight, Vehicle, simulate_mission, slot_times
from sim_link.world import World
from uavloc_gcs.scenario import load_scenario

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"


@pytest.fixture(scope="module")
def small():
    return load_scenario(EXAMPLES / "small.toml")


def test_flight_is_a_constant_speed_polyline():
    f = Flight(np.array([[0, 0], [30, 0], [30, 40]]), 10.0, 10.0)
    assert f.length_m == pytest.approx(70.0)
    assert f.end_t_s == pytest.approx(17.0)
    assert np.allclose(f.position(10.0), [0, 0])
    assert np.allclose(f.position(12.0), [20, 0])
    assert np.allclose(f.position(14.0), [30, 10])
    assert np.allclose(f.position(100.0), [30, 40])  # hovers at the end
    assert np.allclose(f.position(np.array([5.0, 13.0])), [[0, 0], [30, 0]])


def test_slot_times_tile_time_without_gaps_or_overlap():
    a, b = slot_times(0.0, 1.0, 0.025), slot_times(1.0, 2.5, 0.025)
    both = np.concatenate([a, b])
    assert len(a) == 40 and len(both) == 100
    assert np.allclose(np.diff(both), 0.025)


def test_energy_counts_flight_and_hover(small):
    v = Vehicle(1, small)
    v.fly(np.array([[0, 0], [200, 0]]), 0.0)  # 10 s at 20 m/s, then hover
    v.account(15.0)
    pw = small.power_model
    expect = pw.leg_energy_j(200.0, 20.0) + pw.hover_energy_j(5.0)
    assert v.energy_j == pytest.approx(expect)
    st = v.state(15.0)
    assert st.energy_j == pytest.approx(small.usable_energy_j - expect)
    assert st.start_xy_m == pytest.approx((200.0, 0.0))


@pytest.mark.parametrize("method", list(METHODS))
def test_every_method_finishes_home_and_locates_static_people(small, method):
    world = World(small, seed=11, people=3, motion="static")
    res = simulate_mission(small, world, method, seed=1, time_limit_s=20.0, max_iter=15)
    assert res.method == method and res.people == 3
    assert res.completion_time_s >= res.scan_time_s > 0
    assert all(e <= small.usable_energy_j * 1.01 for e in res.energy_j)
    assert res.located_fraction == 1.0
    req = small.people.required_accuracy_m
    for p in res.persons:
        assert p.heard and p.located and p.claimed_radius_m <= req
        assert p.error_m < 2 * req  # a 95 % radius: 2x is far outside it
    assert np.all(np.diff(res.error_times_s) >= 0)
    assert math.isfinite(res.max_error_m[-1])


def test_mission_is_deterministic_and_moving_people_are_tracked(small):
    runs = [simulate_mission(small, World(small, seed=4, people=3, motion="random_waypoint"), "MLE-EPSO (M)",
                             seed=2, time_limit_s=20.0, max_iter=15) for _ in range(2)]
    a, b = runs
    assert a.completion_time_s == b.completion_time_s
    assert [p.error_m for p in a.persons] == [p.error_m for p in b.persons]
    assert a.located_fraction == 1.0
    assert a.max_final_error_m < 2 * small.people.required_accuracy_m


def test_clairvoyant_yardstick_and_recorded_silences(small):
    """The oracle plans the same follow-up looks at the true tracks: it ends after the scan and
    no later than the real mission (which may need more looks). The policy records where the
    vehicles listened; with the hearing evidence on, estimates after the scan weigh silences."""
    import uavloc_gcs.search.policy as policy_module

    seen = []
    original = policy_module.SearchPolicy._silence

    def spy(self, p):
        out = original(self, p)
        seen.append(0 if out is None else len(out))
        return out

    policy_module.SearchPolicy._silence = spy
    try:
        world = World(small, seed=3, people=3, motion="random_waypoint")
        res = simulate_mission(small, world, "MLE-EPSO (M)", seed=3, time_limit_s=20.0, max_iter=15, oracle=True,
                               hearing_evidence=True)
    finally:
        policy_module.SearchPolicy._silence = original
    assert res.scan_time_s < res.oracle_completion_time_s <= res.completion_time_s + 1e-6
    assert seen and max(seen) > 0
    plain = simulate_mission(small, World(small, seed=3, people=3, motion="random_waypoint"), "MLE-EPSO (M)",
                             seed=3, time_limit_s=20.0, max_iter=15)
    assert math.isnan(plain.oracle_completion_time_s)


def test_an_orbit_is_flown_at_its_speed_and_charged_at_its_power(small):
    """A task with an orbit look (search/orbit.py): the circle's whole turns at the orbit speed,
    its energy at that speed's power, the legs at cruise speed."""
    from types import SimpleNamespace

    from sim_link.experiments.missionsim import _orbit_path
    from uavloc_gcs.search.orbit import OrbitLook

    cruise = small.fleet.speed_m_s
    orb = OrbitLook((0.0, 300.0), 100.0, 120.0, 8.0)
    task = SimpleNamespace(waypoints_xy_m=np.array([[0.0, 200.0], [0.0, 0.0]]), orbits=(orb,))
    path, speeds, heights = _orbit_path(task, np.zeros(2), cruise, small.fleet.altitude_m)
    assert heights is None  # at the survey altitude: no vertical legs
    v = Vehicle(1, small)
    v.fly(path, 0.0, speeds)
    t_end = 200.0 / cruise + orb.flown_s + 200.0 / cruise
    assert v.flight.end_t_s == pytest.approx(t_end, rel=0.01)  # 36-gon: the circle within 1 %
    v.account(t_end)
    pw = small.power_model
    expect = 2 * pw.leg_energy_j(200.0, cruise) + float(pw.power_w(8.0)) * orb.flown_s
    assert v.energy_j == pytest.approx(expect, rel=0.01)
    mid = v.flight.position(200.0 / cruise + 0.5 * orb.flown_s)
    assert math.hypot(mid[0], mid[1] - 300.0) == pytest.approx(100.0, rel=0.01)


def test_a_look_at_its_own_height_is_flown_there_with_its_descent_and_climb_charged(small):
    """An orbit with alt_m (issue 41 item 2): the vehicle goes down at the entry, flies the circle at
    that height (the slots it hears are placed there), climbs back; the vertical legs take their
    time at the terrain's rates and the climb costs W dh on top of hovering."""
    from types import SimpleNamespace

    from sim_link.experiments.missionsim import _orbit_path
    from uavloc_gcs.search.orbit import OrbitLook

    cruise, survey = small.fleet.speed_m_s, small.fleet.altitude_m
    low = 30.0
    orb = OrbitLook((0.0, 300.0), 100.0, 120.0, 8.0, alt_m=low)
    flat = OrbitLook((0.0, 300.0), 100.0, 120.0, 8.0)
    task = SimpleNamespace(waypoints_xy_m=np.array([[0.0, 200.0], [0.0, 0.0]]), orbits=(orb,))
    path, speeds, heights = _orbit_path(task, np.zeros(2), cruise, survey)
    assert heights[0] == survey and heights[-1] == survey and np.min(heights) == low
    v, w = Vehicle(1, small), Vehicle(2, small)
    v.fly(path, 0.0, speeds, heights)
    p2, s2, _ = _orbit_path(SimpleNamespace(waypoints_xy_m=task.waypoints_xy_m, orbits=(flat,)), np.zeros(2), cruise, survey)
    w.fly(p2, 0.0, s2)
    dh = survey - low
    vert = dh / small.terrain.max_descent_m_s + dh / small.terrain.max_climb_m_s
    assert v.flight.end_t_s == pytest.approx(w.flight.end_t_s + vert, rel=1e-9)
    mid = 200.0 / cruise + dh / small.terrain.max_descent_m_s + 0.5 * orb.flown_s
    assert float(v.flight.height(mid, survey)) == pytest.approx(low)
    assert float(v.flight.height(1.0, survey)) == pytest.approx(survey)
    t_end = v.flight.end_t_s
    v.account(t_end)
    w.account(w.flight.end_t_s)
    pw = small.power_model
    assert v.energy_j == pytest.approx(w.energy_j + pw.hover_power_w() * vert + pw.weight_n * dh, rel=1e-6)
    # replanned in the middle of the low circle onto a path of its own: it climbs back first
    v2 = Vehicle(3, small)
    v2.fly(path, 0.0, speeds, heights)
    v2.fly(np.vstack([v2.flight.position(mid).reshape(1, 2), np.zeros((1, 2))]), mid)
    assert float(v2.flight.height(mid + 1.0, survey)) < survey
    assert float(v2.flight.height(mid + dh / small.terrain.max_climb_m_s + 1.0, survey)) == pytest.approx(survey)


def test_a_scan_alone_flies_home_after_it_and_plans_no_look(small):
    """adaptive=False (the conventional search of `uavloc bench field`): no replans, every vehicle
    home after its scan, the people what the scan's data gives; the adaptive mission on the same
    world locates at least as many."""
    world = World(small, seed=11, people=3, motion="static")
    alone = simulate_mission(small, world, seed=1, time_limit_s=5.0, max_iter=15, adaptive=False)
    full = simulate_mission(small, World(small, seed=11, people=3, motion="static"), seed=1, time_limit_s=5.0,
                            max_iter=15)
    assert alone.replans == 0
    assert alone.scan_time_s < alone.completion_time_s
    # home straight from the scan's end: at most the longest way home at cruise speed after it
    far = math.hypot(small.area.width_m, small.area.height_m)
    assert alone.completion_time_s <= alone.scan_time_s + far / small.fleet.speed_m_s + 2.0
    assert sum(p.located for p in full.persons) >= sum(p.located for p in alone.persons)


def test_a_vehicle_with_a_spare_pack_is_swapped_on_the_ground_and_planned_again(small):
    """Sorties (issue 38): a vehicle that lands with less than half its pack left and a spare pack is
    on the ground for fleet.battery_swap_s (no energy to plan with, its spare pack stated, deaf),
    then flies on a fresh pack; the energy of the packs before is kept."""
    sc = small.replace(fleet={"batteries": 2, "battery_swap_s": 60.0})
    v = Vehicle(1, sc)
    assert v.spare_packs == 1
    far = 0.3 * sc.usable_energy_j / sc.power_model.energy_per_m_j(sc.fleet.speed_m_s)  # 60 % of a pack there and back
    v.fly(np.array([[0.0, 0.0], [far, 0.0], [0.0, 0.0]]), 0.0)
    t_land = v.flight.end_t_s
    v.land_if_home(t_land + 1.0)
    assert not v.swap_if_due(t_land + 1.0) and v.in_swap
    st = v.state(t_land + 30.0)
    assert st.energy_j == 0.0 and st.spare_packs == 1 and st.pack_energy_j == pytest.approx(sc.usable_energy_j)
    v.fly(np.array([[0.0, 0.0], [100.0, 0.0]]), t_land + 30.0)  # a plan made during the swap is not flown
    assert v.home_t_s is not None
    used = v.energy_j
    assert v.swap_if_due(t_land + 60.0) and not v.in_swap
    assert v.energy_j == 0.0 and v.total_energy_j == pytest.approx(used) and v.spare_packs == 0
    st = v.state(t_land + 60.0)
    assert st.energy_j == pytest.approx(sc.usable_energy_j) and st.spare_packs == 0


def test_a_scan_longer_than_a_pack_is_flown_in_sorties_within_the_packs(small):
    """With packs too small for a vehicle's scan, the scan is cut into sorties (uavloc_gcs.sorties)
    and flown one after another with a swap between; no vehicle uses more than its packs hold, and
    at least one needed more than one."""
    sc = small.replace(fleet={"batteries": 3, "battery_swap_s": 60.0, "energy_budget_j": 15000.0})
    world = World(sc, seed=11, people=3, motion="static")
    res = simulate_mission(sc, world, seed=1, time_limit_s=5.0, max_iter=15)
    usable = sc.usable_energy_j
    assert max(res.energy_j) > 1.02 * usable  # a second pack was flown
    assert all(e <= 3 * usable * 1.02 for e in res.energy_j)
    assert res.completion_time_s >= res.scan_time_s


def test_the_battery_failsafe_takes_a_vehicle_home_at_its_reserve_and_holds_it_there(small):
    """A vehicle that hovers at the end of its plan (nothing else given) until its usable energy is
    spent turns home from where it is at the reserve; a plan given on the way is not flown, and it
    lands having flown home on its reserve, within its pack."""
    v = Vehicle(1, small)
    v.fly(np.array([[0.0, 0.0], [300.0, 0.0]]), 0.0)  # 15 s out, then hovers there
    hover_w = small.power_model.hover_energy_j(1.0)
    t_reserve = small.usable_energy_j / hover_w  # (about: the leg out costs less than its hover)
    assert not v.failsafe(0.5 * t_reserve)  # half a pack: nothing happens
    t = 0.5 * t_reserve
    while not v.failsafe(t):
        t += 1.0
        assert t < 2 * t_reserve, "the failsafe never triggered"
    assert v.energy_j == pytest.approx(small.usable_energy_j, abs=hover_w)  # at the reserve (1 s steps)
    assert v.flight.path[0] == pytest.approx([300.0, 0.0]) and v.flight.path[-1] == pytest.approx([0.0, 0.0])
    v.fly(np.array([[300.0, 0.0], [300.0, 200.0]]), t + 1.0)  # a plan on the way home is not taken
    assert v.flight.path[-1] == pytest.approx([0.0, 0.0])
    v.land_if_home(math.inf)
    assert v.home_t_s is not None and not v.failsafe_home and v.failsafe_returns == 1
    assert small.usable_energy_j < v.energy_j < small.fleet.energy_budget_j  # the way home came from the reserve
    # on its way home already when the reserve is reached: it flies on, nothing is counted
    w = Vehicle(1, small)
    w.fly(np.array([[0.0, 0.0], [300.0, 0.0], [0.0, 0.0]]), 0.0)
    w.energy_j = small.usable_energy_j
    assert not w.failsafe(20.0) and w.failsafe_returns == 0 and w.flight.path.shape == (3, 2)


def test_at_the_searchs_time_limit_every_vehicle_flies_home_from_where_it_is(small):
    """[search] time_limit_s ends the search as the daemon does: every vehicle in the air flies
    straight home from where it is and nothing more is heard. Before, the simulator stopped listening
    at its cap and let the vehicles fly their plans on, charging them: a three-pack field search
    "took" 91 minutes and 405 kJ on one 250 kJ pack."""
    v = Vehicle(1, small)
    v.fly(np.array([[0.0, 0.0], [400.0, 0.0], [400.0, 400.0], [0.0, 400.0], [0.0, 0.0]]), 0.0)
    planned_end = v.flight.end_t_s
    t = 200.0 / small.fleet.speed_m_s  # half-way out on the first leg
    v.recall(t)
    assert v.flight.path[0] == pytest.approx([200.0, 0.0]) and v.flight.path[-1] == pytest.approx([0.0, 0.0])
    assert v.flight.end_t_s == pytest.approx(2 * t) and 2 * t < planned_end
    v.land_if_home(math.inf)
    assert v.home_t_s == pytest.approx(2 * t) and v.failsafe_returns == 0
    v.recall(3 * t)  # on the ground: stays there
    assert v.home_t_s == pytest.approx(2 * t)

    world = lambda: World(small, seed=11, people=3, motion="static")  # noqa: E731
    free = simulate_mission(small, world(), seed=1, time_limit_s=5.0, max_iter=15)
    assert not free.time_limited
    limit = 0.5 * free.scan_time_s
    cut = simulate_mission(small.replace(search={"time_limit_s": limit}), world(), seed=1, time_limit_s=5.0,
                           max_iter=15)
    assert cut.time_limited and cut.replans == 0  # no look planned after the limit
    assert cut.scan_time_s == pytest.approx(limit)  # the scan too was cut at the limit
    far = math.hypot(small.area.width_m, small.area.height_m)  # the longest way home
    assert cut.completion_time_s <= limit + far / small.fleet.speed_m_s + 2.0
    assert all(e < f for e, f in zip(cut.energy_j, free.energy_j))
    # a scan alone (no looks) whose vehicles are only flying home at the limit is not cut short
    alone = simulate_mission(small, world(), seed=1, time_limit_s=5.0, max_iter=15, adaptive=False)
    home = simulate_mission(small.replace(search={"time_limit_s": alone.scan_time_s + 1.0}), world(), seed=1,
                            time_limit_s=5.0, max_iter=15, adaptive=False)
    assert not home.time_limited and home.completion_time_s == pytest.approx(alone.completion_time_s)
    mid = simulate_mission(small.replace(search={"time_limit_s": 0.5 * alone.scan_time_s}), world(), seed=1,
                           time_limit_s=5.0, max_iter=15, adaptive=False)  # a lawnmower cut in its scan
    assert mid.time_limited and mid.completion_time_s < alone.completion_time_s


def test_a_reported_person_is_the_phone_that_sent_most_of_their_bursts():
    """A person linked from two phones' bursts is judged as the phone that sent most of them, and
    the share the other phone sent is reported (issue 41 item 4): a fix among B's bursts credited
    to A (the first address heard) would be scored as A's error."""
    from sim_link.experiments.truth import person_results
    from uavloc_gcs.observations import SlotBatch
    from uavloc_gcs.search.policy import PersonStatus

    sc = load_scenario(EXAMPLES / "field.toml").replace(simulation={"people": 2, "seed": 3, "motion": "static"},
                                                        people={"max_speed_m_s": 0.0})
    world = World(sc, seed=3)
    frames = world.emission.frames(0.0, 900.0)
    bursts = {}  # person -> first frame of each of their bursts
    for k in range(len(frames)):
        bursts.setdefault(int(frames.person[k]), {}).setdefault(int(frames.burst[k]), k)
    a = list(bursts[0].values())[:1]  # one burst of phone 0 (heard first)
    b = list(bursts[1].values())[:3]  # three of phone 1
    rows = a + b
    slots = SlotBatch.from_columns(frames.t_s[rows], np.zeros(4), np.zeros((4, 3)),
                                   np.full(4, frames.address[a[0]]), np.full(4, -70.0), np.ones(4),
                                   address=frames.address[rows])
    truth = world.positions(0.0)
    status = PersonStatus(emitter_id=int(frames.address[a[0]]), estimate=None, located=True, reason="",
                          xy_m=(float(truth[1, 0]) + 3.0, float(truth[1, 1])), t_ref_s=0.0, fix_t_s=100.0,
                          radius95_m=10.0)
    by_first = person_results(world, [status], 0.0)
    assert by_first[0].located and by_first[0].error_m > 20.0 and math.isnan(by_first[0].foreign_share)
    judged = person_results(world, [status], 0.0, lambda eid: slots)
    assert not judged[0].heard and math.isnan(judged[0].foreign_share)
    assert judged[1].located and judged[1].error_m == pytest.approx(3.0)
    assert judged[1].foreign_share == pytest.approx(0.25)
    # every circle reported is judged against its own phone, duplicates of one phone included
    from dataclasses import replace

    from sim_link.experiments.truth import circle_claims

    twice = [status, replace(status, xy_m=(float(truth[1, 0]) + 30.0, float(truth[1, 1])), located=False,
                             radius95_m=25.0)]
    assert circle_claims(world, twice, 0.0, lambda eid: slots) == ((True, 10.0, True), (False, 25.0, False))
    assert circle_claims(world, [replace(status, xy_m=None)], 0.0, lambda eid: slots) == ()
