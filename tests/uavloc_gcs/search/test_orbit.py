"""Orbit looks (search/orbit.py): radius, dwell, mission items per autopilot, the path simulators fly,
and the policy giving orbit looks in the burst world only."""

from __future__ import annotations

import math

import numpy as np
import pytest

from uavloc_gcs.examples import scenario_path
from uavloc_gcs.mission import DO_CHANGE_SPEED, NAV_RETURN_TO_LAUNCH, NAV_WAYPOINT, to_wire
from uavloc_gcs.scenario import load_scenario
from uavloc_gcs.search import orbit
from uavloc_gcs.search.burst_timing import BurstTiming


@pytest.fixture(scope="module")
def field():
    return load_scenario(scenario_path("field"))


def test_radius_is_near_the_altitude_and_dwell_catches_the_bursts(field):
    # range information about the horizontal position peaks at rho = altitude (100 m)
    r = orbit.orbit_radius_m(field, 0.0)
    assert 80.0 <= r <= 120.0
    o = orbit.plan_orbit(field, (0.0, 0.0), 60.0)
    w = BurstTiming.from_scenario(field).window_for(orbit.ORBIT_BURSTS, orbit.ORBIT_P)
    ph = orbit.mean_p_heard(field, o.radius_m, 60.0)
    assert 0.5 < ph < 1.0
    assert o.dwell_s == pytest.approx(min(w / ph, orbit.MAX_DWELL_S))
    assert o.flown_s >= o.dwell_s and o.flown_s - o.dwell_s < 2 * math.pi * o.radius_m / o.speed_m_s
    # a wider estimate hears less of the bursts: a longer dwell
    assert orbit.plan_orbit(field, (0.0, 0.0), 150.0).dwell_s > o.dwell_s


def test_speed_models_follow_the_sitl_measurements():
    assert orbit.orbit_speed_m_s("loiter-turns", 60.0, 25.0) == pytest.approx(7.9, abs=0.05)
    assert orbit.orbit_speed_m_s("loiter-turns", 500.0, 10.0) == 10.0  # never above the cruise speed
    assert 3.0 < orbit.orbit_speed_m_s("ring", 60.0, 25.0) < 6.5


@pytest.mark.parametrize("autopilot, form", [("ardupilot", "ring"), ("px4", "ring"), ("ardupilot", "loiter-turns")])
def test_look_mission_items(field, autopilot, form):
    o = orbit.OrbitLook((300.0, 200.0), 100.0, 200.0, orbit.orbit_speed_m_s(form, 100.0, 25.0), form)
    lm = orbit.look_mission(field.frame, [[100.0, 0.0], [300.0, 100.0]], (5, 6), [None, o], alt_m=100.0,
                            speed_m_s=25.0, autopilot=autopilot, home_latlon_deg=field.launch_latlon_deg,
                            start_xy_m=(0.0, 0.0))
    wire = to_wire(lm.plan, autopilot)
    seqs = lm.look_seqs(autopilot == "ardupilot")
    assert wire[-1].command == NAV_RETURN_TO_LAUNCH
    assert wire[seqs[0]].command == NAV_WAYPOINT  # the fly-by
    entry = lm.look_xy_m[1]
    assert np.hypot(*(entry - np.array(o.centre_xy_m))) == pytest.approx(100.0)
    # the entry is the circle's point nearest the previous look point
    assert np.hypot(*(entry - np.array([100.0, 0.0]))) == pytest.approx(np.hypot(200.0, 200.0) - 100.0, abs=1e-6)
    if form == "loiter-turns":
        loiter = wire[seqs[1]]
        assert loiter.command == orbit.NAV_LOITER_TURNS
        assert loiter.param1 == o.turns and loiter.param3 == pytest.approx(100.0)
    else:
        ring = [w for w in wire if w.command == NAV_WAYPOINT and w.seq >= seqs[1]]
        assert len(ring) == o.turns * orbit.RING_POINTS_PER_TURN + 1
        lat_lon = np.array([[w.x / 1e7, w.y / 1e7] for w in ring])
        d = np.hypot(*(field.frame.to_local_xy(lat_lon) - np.array(o.centre_xy_m)).T)
        assert np.allclose(d, 100.0, atol=0.05)
        speeds = [w.param2 for w in wire if w.command == DO_CHANGE_SPEED]
        assert speeds == [25.0, pytest.approx(o.speed_m_s), 25.0]  # slow on the ring, cruise after


def test_expand_path_inserts_whole_turns(field):
    o = orbit.OrbitLook((0.0, 500.0), 100.0, 100.0, 8.0)
    path, seg = orbit.expand_path([[0.0, 0.0], [0.0, 400.0]], [None, o], (0.0, -100.0))
    on = np.r_[False, seg == 1]  # path points that end a circle segment
    ring = path[on]
    d = np.hypot(ring[:, 0], ring[:, 1] - 500.0)
    assert np.allclose(d, 100.0)
    length = np.linalg.norm(np.diff(path, axis=0), axis=1)[seg == 1].sum()
    assert length == pytest.approx(o.turns * 2 * math.pi * 100.0, rel=0.01)
    assert np.allclose(path[np.flatnonzero(on)[-1]], path[np.flatnonzero(seg == 1)[0]])  # back at the entry


def test_no_orbits_in_the_paper_world():
    from uavloc_gcs.search import SearchPolicy

    paper = load_scenario(scenario_path("paper"))
    assert orbit.orbit_targets(SearchPolicy(paper), 0.0, ["unchanged"]) == ["unchanged"]


def test_points_after_the_looks_are_flown_through(field):
    """A task whose looks are followed by a coverage pass's lane points (search/coverage.py)."""
    o = orbit.OrbitLook((300.0, 200.0), 100.0, 100.0, 6.0)
    lm = orbit.look_mission(field.frame, [[300.0, 100.0], [600.0, 0.0], [600.0, 300.0]], (6,), [o], alt_m=100.0,
                            speed_m_s=25.0, autopilot="px4", home_latlon_deg=field.launch_latlon_deg,
                            start_xy_m=(0.0, 0.0))
    assert len(lm.look_xy_m) == 3 and np.allclose(lm.look_xy_m[1:], [[600.0, 0.0], [600.0, 300.0]])
    wire = to_wire(lm.plan, "px4")
    assert [wire[k].command for k in lm.look_seqs(False)] == [NAV_WAYPOINT] * 3
    assert lm.look_seqs(False)[2] == len(wire) - 2  # the last lane point, then the return


def test_elicited_phones_get_orbits_as_long_as_the_frames_the_accuracy_needs(field):
    """With an on-board access point a look is an orbit long enough for the elicited frames to place
    the person within the required accuracy: the dwell falls with the square of the accuracy asked
    (a fly-by at 25 m/s hears about 20 frames at 2 Hz). Frames a few metres apart share their
    shadowing (estimation.burst_grid.unit_weights): asking four times as often barely shortens it
    (before issue 39 it made the look four times shorter, and its estimate overconfident)."""
    from uavloc_gcs.search import SearchPolicy

    ap = field.replace(emission={"elicitation_rate_hz": 2.0, "elicitation_join": "in-reach"},
                       search={"look_height_m": 30.0}, people={"required_accuracy_m": 30.0})
    assert orbit.elicited(ap) and not orbit.elicited(field)
    # a mimicked network is joined at the phone's next burst: the look waits for one as well
    scan = orbit.plan_orbit(ap.replace(emission={"elicitation_join": "scan"}), (0.0, 0.0), 5.0)
    wait = orbit.join_wait_s(ap)
    assert 30.0 < wait < orbit.MAX_DWELL_S
    assert scan.dwell_s == pytest.approx(min(orbit.plan_orbit(ap, (0.0, 0.0), 5.0).dwell_s + wait, orbit.MAX_DWELL_S))
    o2 = orbit.plan_orbit(ap, (0.0, 0.0), 5.0)
    # at least a whole turn, about a hundred frames (a fly-by at 25 m/s hears about 20)
    assert o2.dwell_s * o2.speed_m_s >= 2 * np.pi * o2.radius_m and o2.dwell_s * 2.0 > 80
    assert o2.dwell_s < orbit.MAX_DWELL_S
    o8 = orbit.plan_orbit(ap.replace(emission={"elicitation_rate_hz": 8.0}), (0.0, 0.0), 5.0)
    assert 0.9 * o2.dwell_s <= o8.dwell_s <= o2.dwell_s
    loose = orbit.plan_orbit(ap.replace(people={"required_accuracy_m": 60.0}), (0.0, 0.0), 5.0)
    assert loose.dwell_s == pytest.approx(o2.dwell_s / 4, rel=0.02)
    assert orbit._uses_orbits(SearchPolicy(ap)) and not orbit._uses_orbits(SearchPolicy(
        load_scenario(scenario_path("paper")).replace(emission={"elicitation_rate_hz": 2.0})))
