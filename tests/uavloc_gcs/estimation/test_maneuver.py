"""People who turn and stop: the maneuver process noise (uavloc_gcs/estimation/maneuver.py).

Known answers: a person who walks east and then turns north (the constant-velocity model is
wrong), and a person who stood still and then walked away (old slots far from the current
position must not dominate). The pure CV model (``maneuver_time_s=inf``) is run alongside to show
that these cases do break it, i.e. that the assertions could fail.
"""

import math
from pathlib import Path

import numpy as np
import pytest

from sim_link.world.people import Tracks
from sim_link.world import World
from uavloc_gcs.estimation import ChannelModel, estimate_emitter
from uavloc_gcs.estimation.maneuver import (
    MAX_PASSES,
    find_passes,
    intensity_m2_s3,
    irw_covariance,
    state_noise,
)
from uavloc_gcs.observations import SlotBatch
from uavloc_gcs.scenario import load_scenario

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"
VMAX = 1.5


@pytest.fixture(scope="module")
def sc():
    return load_scenario(EXAMPLES / "paper.toml")


@pytest.fixture(scope="module")
def channel(sc):
    return ChannelModel.from_scenario(sc)


def leg(world, vehicle, a, b, t0_s):
    """One straight leg at 100 m and 25 m/s from a to b starting at t0_s."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    n = int(np.linalg.norm(b - a) / 25.0 / 0.025)
    f = np.arange(n) / n
    return world.hear_track(vehicle, t0_s + f * n * 0.025, np.column_stack([a + np.outer(f, b - a), np.full(n, 100.0)]))


def track(times_s, points_xy_m):
    return Tracks((np.asarray(times_s, float),), (np.asarray(points_xy_m, float),))


# east at 1.2 m/s for 60 s, then north at 1.2 m/s
TURN = track([0.0, 60.0, 1000.0], [[500.0, 300.0], [572.0, 300.0], [572.0, 300.0 + 1.2 * 940.0]])


def turn_mission(world):
    """Two scan lanes (100 m apart) while the person walks east; after the turn one look pass at
    ~150 s (north-south, 28 m east of the person), and a crossing second look at ~170 s."""
    lanes = SlotBatch.concat([leg(world, 1, (200, 250), (800, 250), 10.0), leg(world, 1, (800, 350), (200, 350), 43.0)])
    one = SlotBatch.concat([lanes, leg(world, 2, (600, 250), (600, 550), 146.0)])
    return lanes, one, SlotBatch.concat([one, leg(world, 2, (450, 440), (750, 440), 166.0)])


def error_m(est, world, dt_s=0.0):
    return float(np.linalg.norm(est.predict(est.t_ref_s + dt_s)[0] - world.positions(est.t_ref_s + dt_s)[0]))


@pytest.mark.parametrize("seed", range(6))
def test_a_person_who_turns_is_inside_the_radius(sc, channel, seed):
    """Two looks after the turn. With the turn models (TURN_JUMP, shipped) the radius is 12-19 m
    (measured; errors 1-11 m): two looks do not tell when the person turned, and the models of a
    turn at each gap leave modes 5-15 m apart along the walk. Without them it was 11.5-14.4 m, and
    the same models' figures in bench localize's random-waypoint families say such radii were
    1.7-2.6x too small for the worst 5 % of people who turned. In one seed of six a mode 14 m off
    is just outside the estimate's own circle and the estimate is ambiguous: a look settles it."""
    world = World(sc, seed=seed, tracks=TURN)
    slots = turn_mission(world)[2]
    est = estimate_emitter(slots, channel, max_speed_m_s=VMAX)
    assert est.ok
    assert error_m(est, world) <= est.radius95_m <= (30.0 if est.ambiguous else 20.0)  # honest and still useful
    # ... and 30 s later (the person keeps walking north)
    assert error_m(est, world, 30.0) <= est.predict(est.t_ref_s + 30.0)[1]


def test_two_looks_after_a_turn_mostly_settle_it(sc, channel):
    """At most one seed of six is left ambiguous after the two looks, and the radius is at most
    15 m (the paper scenario's requirement: located) in at least two; measured 1 and 2 of 6."""
    ests = [(estimate_emitter(turn_mission(w)[2], channel, max_speed_m_s=VMAX))
            for w in (World(sc, seed=seed, tracks=TURN) for seed in range(6))]
    assert sum(e.ambiguous for e in ests) <= 1
    assert sum(e.radius95_m <= 15.0 for e in ests) >= 2


def test_the_constant_velocity_model_misses_the_turn(sc, channel):
    """Why the above could fail: the pure CV fit of the same slots is outside its own radius in
    half of the seeds (measured: 3 of 6; errors 9-10 m against radii 6.5-8.6 m)."""
    misses = 0
    for seed in range(6):
        world = World(sc, seed=seed, tracks=TURN)
        cv = estimate_emitter(turn_mission(world)[2], channel, max_speed_m_s=VMAX, maneuver_time_s=math.inf)
        misses += error_m(cv, world) > cv.radius95_m
    assert misses >= 2


def test_one_look_after_a_turn_is_mostly_covered(sc, channel):
    """A single look pass after the turn: its mirror is resolved only by the old lanes, which
    point the wrong way after a sharp turn at full speed (a tail event for the Gaussian random
    walk). Measured with the turn models (shipped): covered in 6 of 6 seeds, all flagged ambiguous
    with the radius over both mirrors (errors 55-65 m, radii 60-81 m); with the main model alone
    3 of 6, in the other 3 the wrong mirror winning (~60 m off, radius ~9 m). The CV model is
    covered in none (errors ~50 m, radii 9-16 m). A second look fixes all 6 (above)."""
    new = cv = 0
    for seed in range(6):
        world = World(sc, seed=seed, tracks=TURN)
        slots = turn_mission(world)[1]
        est = estimate_emitter(slots, channel, max_speed_m_s=VMAX)
        old = estimate_emitter(slots, channel, max_speed_m_s=VMAX, maneuver_time_s=math.inf)
        new += error_m(est, world) <= est.radius95_m
        cv += error_m(old, world) <= old.radius95_m
    assert new >= 3 and cv <= 1


@pytest.mark.parametrize("switches", [{"TURN_MIXTURE": True}, {"MANEUVER_TAIL_DOF": 4.0}, {"TURN_JUMP": True},
                                      {"TURN_JUMP": True, "TWINS_ACROSS_MODELS_ONLY": False}], ids=str)
def test_a_model_of_turns_covers_one_look_after_a_turn(sc, channel, monkeypatch, switches):
    """Switches of ``estimate`` that keep the wrong mirror from taking all the mass after a turn
    (the first two off; bench localize --switch turn-mixture, tail-4; the turn models on since
    2026-11-25):

    - ``TURN_MIXTURE``, a second model in which the person turned since the lanes: one look
      covered in 5 of 6 seeds (3 of 6 without), radii after the second look 17-28 m instead of
      11-14 m;
    - ``MANEUVER_TAIL_DOF``, a multivariate t prior on the offsets, so that a turn costs a
      logarithm instead of a square: 6 of 6 seeds, radii after the second look 15-26 m;
    - ``TURN_JUMP``, models in which the person turned once, at one of the longest gaps: 5 of 6
      seeds, radii after the second look 17-25 m (the same with twins merged as well).

    The larger radii (and, for the first two, a worse fit under correlated shadowing) are why the
    first two are off; the turn models' radii after two looks are 12-19 m with the near-twin radius. The first two were measured with a near twin covered over its whole circle: with the
    two modes' mixture (MIXTURE_RADIUS) each leaves one seed 1.05-1.1x outside after two looks
    (its twins' masses are less reliable), so they are checked as measured."""
    from uavloc_gcs.estimation import estimate as estimate_module

    if "TURN_JUMP" not in switches:  # the estimator they were measured in
        for name, value in {"MIXTURE_RADIUS": False, "TURN_JUMP": False, "TWINS_ACROSS_MODELS_ONLY": True,
                            "TURN_TIME_S": None}.items():
            monkeypatch.setattr(estimate_module, name, value)
    for switch, value in switches.items():
        monkeypatch.setattr(estimate_module, switch, value)
    covered = 0
    for seed in range(6):
        world = World(sc, seed=seed, tracks=TURN)
        _, one, both = turn_mission(world)
        est = estimate_emitter(one, channel, max_speed_m_s=VMAX)
        covered += error_m(est, world) <= est.radius95_m
        two = estimate_emitter(both, channel, max_speed_m_s=VMAX)
        assert error_m(two, world) <= two.radius95_m <= 30.0
    assert covered >= 5



def test_turn_models_started_from_the_main_modes_find_what_the_start_grid_finds(sc, channel, monkeypatch):
    """TURN_JUMP's turn models start from the main model's modes (TURN_STARTS_FROM_MAIN), not from
    the whole grid with their own mirrors: the same estimates on the known-answer turn, after one
    look and after two, at about half the solve time (bench localize: 7.5 ms against 13 ms)."""
    from uavloc_gcs.estimation import estimate as estimate_module

    monkeypatch.setattr(estimate_module, "TURN_JUMP", True)
    for seed in range(3):
        world = World(sc, seed=seed, tracks=TURN)
        for slots in turn_mission(world)[1:]:
            got = {}
            for cheap in (True, False):
                monkeypatch.setattr(estimate_module, "TURN_STARTS_FROM_MAIN", cheap)
                monkeypatch.setattr(estimate_module, "TURN_MIRRORS", not cheap)
                got[cheap] = estimate_emitter(slots, channel, max_speed_m_s=VMAX)
            fast, grid = got[True], got[False]
            assert np.linalg.norm(fast.position_xy_m - grid.position_xy_m) < 1.0, (seed, fast, grid)
            assert fast.radius95_m == pytest.approx(grid.radius95_m, rel=0.1), (seed, fast, grid)


def test_a_near_twin_is_covered_by_the_mixture_not_by_its_whole_circle(sc, channel, monkeypatch):
    """With the turn models (TURN_JUMP, twins merged, a turn every 200 s) two looks after the
    known turn leave a second mode a few metres from the estimate, inside its own circle, holding
    10-35 % of the mass. Reaching over that mode's whole circle (MIXTURE_RADIUS = False) made the
    radius 17-25 m where 11-16 m covered the person; the 95 % circle of the two modes' mixture
    (measured: 12-19 m) is smaller and still covers them, now and 30 s later."""
    from uavloc_gcs.estimation import estimate as estimate_module

    for name, value in {"TURN_JUMP": True, "TWINS_ACROSS_MODELS_ONLY": False, "TURN_TIME_S": 200.0}.items():
        monkeypatch.setattr(estimate_module, name, value)
    twins = 0
    for seed in range(6):
        world = World(sc, seed=seed, tracks=TURN)
        both = turn_mission(world)[2]
        monkeypatch.setattr(estimate_module, "MIXTURE_RADIUS", False)
        whole = estimate_emitter(both, channel, max_speed_m_s=VMAX)
        whole_later = whole.predict(whole.t_ref_s + 30.0)[1]  # the rule applies to predictions too
        monkeypatch.setattr(estimate_module, "MIXTURE_RADIUS", True)
        est = estimate_emitter(both, channel, max_speed_m_s=VMAX)
        if est.ambiguous or est.mirror is None or not est.mirror.holds_mass:
            assert est.radius95_m == pytest.approx(whole.radius95_m), seed  # the rule is only for twins
            continue
        twins += 1
        assert error_m(est, world) <= est.radius95_m < whole.radius95_m - 2.0, (seed, est.radius95_m, whole.radius95_m)
        assert est.radius95_m >= 0.8 * est.mode_radius95_m, seed  # never much below the estimate's own
        assert error_m(est, world, 30.0) <= est.predict(est.t_ref_s + 30.0)[1] < whole_later - 2.0, seed
    assert twins >= 4


def _tail_problem(dof):
    from uavloc_gcs.estimation.fit import Problem
    from uavloc_gcs.estimation.prepared import Prepared

    rng = np.random.default_rng(0)
    t = np.concatenate([np.linspace(0.0, 20.0, 30), np.linspace(200.0, 215.0, 30)])
    a = np.column_stack([np.linspace(0.0, 500.0, 60), rng.normal(0.0, 5.0, 60)])
    data = Prepared(t, t - t.mean(), float(t.mean()), a, np.full(60, 40.0), np.zeros(60, int),
                    rng.normal(4.0, 0.2, 60), np.full(60, 20.0), np.ones(60), a.mean(axis=0))
    return Problem(data, True, True, VMAX, 0.2, find_passes(t, float(t.max()), VMAX**2 / 60.0), offset_tail=dof)


def test_the_heavy_tailed_offset_prior_is_a_least_squares_residual_with_its_jacobian():
    """The t prior enters the fit as f(s) e with f(s)^2 s = c ln(1 + s / c): its analytic
    Jacobian matches central differences, its cost is that logarithm (below the Gaussian's s far
    out, equal to it at the origin to first order), and the Gaussian is unchanged without it."""
    tail, gauss = _tail_problem(4.0), _tail_problem(None)
    assert tail.passes.count >= 2
    theta = np.random.default_rng(1).normal(0.0, 3.0, tail.size)
    jac = tail.jacobian(theta)
    num = np.column_stack([(tail.residuals(theta + h) - tail.residuals(theta - h)) / 2e-6
                           for h in np.eye(tail.size) * 1e-6])
    assert np.max(np.abs(jac - num)) < 1e-6 * np.max(np.abs(jac))
    e2 = float(np.sum(gauss.residuals(theta)[-2 * tail.passes.count:] ** 2))  # the offsets' rows come last
    assert gauss.offset_prior_cost(theta) == pytest.approx(e2)
    c = 4.0 + 2 * tail.passes.count
    assert tail.offset_prior_cost(theta) == pytest.approx(c * math.log1p(e2 / c))
    assert tail.offset_prior_cost(theta) < e2
    small = theta.copy()
    small[tail.base_size:] *= 1e-4
    assert tail.offset_prior_cost(small) == pytest.approx(gauss.offset_prior_cost(small), rel=1e-6)


@pytest.mark.parametrize("across_models_only", [True, False])
def test_two_modes_of_one_model_that_meet_at_the_reference_time(monkeypatch, across_models_only):
    """Told apart at the fit's reference time, two modes with different velocities can be at the
    same place at t_ref: by default they stay two candidates (the second a twin of the first);
    with TWINS_ACROSS_MODELS_ONLY off they are one, holding both masses, and the real
    alternative further away becomes the mirror."""
    from uavloc_gcs.estimation import estimate as estimate_module

    monkeypatch.setattr(estimate_module, "TWINS_ACROSS_MODELS_ONLY", across_models_only)
    thetas = [np.array([0.0, 0.0, 1.0, 0.0]), np.array([10.0, 0.5, 0.0, 0.0]), np.array([10.0, 60.0, 0.0, 0.0])]
    sol = estimate_module._Solution(None, [(t, 0.0) for t in thetas],
                                    [(np.eye(4), -1.0), (np.eye(4), -2.0), (np.eye(4), -3.0)], 1.0, 0.0)
    entries = estimate_module._candidates([(sol, 0.0)], True, 10.0)  # all at t_c + 10 s
    if across_models_only:
        assert len(entries) == 3 and np.linalg.norm(entries[1].pos - entries[0].pos) < 1.0
    else:
        assert len(entries) == 2
        assert entries[0].logmass == pytest.approx(float(np.logaddexp(-1.0, -2.0)))
        assert np.allclose(entries[1].pos, (10.0, 60.0))
        assert entries[0].cov[1, 1] > 1.0  # the twins' spread is in the merged covariance


def test_the_turn_is_a_velocity_change_before_its_time_with_its_jacobian():
    """With a turn at t_k, a slot before it sees the person shifted by (t_k - t) u, a slot after it
    not at all; the analytic Jacobian (the prior's rows and the hearing bounds' rows included, some
    of them binding) matches central differences."""
    from dataclasses import replace

    from uavloc_gcs.estimation.evidence import Bounds

    plain = _tail_problem(None)
    turned = replace(plain, turn_at_s=100.0, turn_sigma_m_s=1.5)
    assert turned.size == plain.size + 2 and turned.offsets_end == plain.size
    theta = np.random.default_rng(1).normal(0.0, 3.0, turned.size)
    g0, _ = plain._geometry(theta[:plain.size])
    g1, _ = turned._geometry(theta)
    lead = np.maximum(100.0 - turned.data.t_s, 0.0)
    assert np.allclose(g1 - g0, np.outer(lead, theta[-2:]))
    assert np.all(lead[turned.data.t_s > 100.0] == 0.0) and np.any(lead > 0)
    tau = np.array([-80.0, -60.0, 10.0, 60.0, 90.0])
    bounds = Bounds(tau, np.array([[0.0, 0.0], [100.0, 0.0], [200.0, 50.0], [400.0, 0.0], [500.0, 0.0]]),
                    np.full(5, 30.0), np.array([1.0, -1.0, 1.0, -1.0, 1.0]), np.full(5, 4.0),
                    np.array([0, -1, -1, -1, 1]))
    bounded = replace(turned, bounds=bounds)
    theta[:2] = (150.0, 20.0)
    r = bounded.residuals(theta)
    assert np.any(r[-5:] > 0)  # some bounds bind
    jac = bounded.jacobian(theta)
    num = np.column_stack([(bounded.residuals(theta + h) - bounded.residuals(theta - h)) / 2e-6
                           for h in np.eye(bounded.size) * 1e-6])
    assert np.max(np.abs(jac - num)) < 1e-6 * np.max(np.abs(jac))
    assert np.allclose(bounded.prior_information()[-2:, -2:], np.eye(2) / 1.5**2)


def test_mirroring_one_pass_keeps_the_others_where_they_were_with_a_turn():
    """A mirror start of one old pass moves only that pass's person: with a turn model the turn's
    shift is part of where the person was at the other passes, and stays there."""
    from dataclasses import replace

    from uavloc_gcs.estimation.modes import _mirror_one_pass

    problem = replace(_tail_problem(None), turn_at_s=100.0, turn_sigma_m_s=1.5)
    theta = np.random.default_rng(2).normal(0.0, 3.0, problem.size)
    theta[:2] = (250.0, 30.0)
    d = problem.data

    def person(th):
        g, _ = problem._geometry(th)
        return g + d.a_xy

    j = int(problem.passes.index[5])
    assert j >= 0
    mirrored = _mirror_one_pass(problem, theta, np.array([0.0, 0.0]), np.array([1.0, 0.0]), float(d.t_s[5]))
    other = problem.passes.index != j
    assert np.allclose(person(mirrored)[other], person(theta)[other])
    inside = problem.passes.index == j
    assert np.allclose(person(mirrored)[inside].mean(axis=0) * (1, -1), person(theta)[inside].mean(axis=0), atol=1e-6)


def test_the_heavy_tailed_offset_prior_is_normalised():
    """Two motion models' masses stay comparable with the t prior: for one pass (d = 2) the t's
    integral over the plane is 2 pi c / dof (c = dof + 2), so its normalisation is the Gaussian's
    plus ln(dof / c)."""
    from uavloc_gcs.estimation.estimate import _offset_prior_norm
    from uavloc_gcs.estimation.fit import Problem

    t = np.concatenate([np.arange(0.0, 10.0, 0.5), np.arange(150.0, 151.0, 0.5)])
    passes = find_passes(t, float(t.max()), intensity_m2_s3(VMAX))
    assert passes.count == 1
    for dof in (1.0, 4.0):
        tail = Problem(None, True, False, VMAX, 1.0, passes, offset_tail=dof)
        gauss = Problem(None, True, False, VMAX, 1.0, passes)
        assert _offset_prior_norm(tail) - _offset_prior_norm(gauss) == pytest.approx(math.log(dof / (dof + 2.0)))


def test_offset_prior_normalisation_matches_the_irw_covariance():
    """What makes the two motion models' masses comparable: -1/2 log det of the offsets' prior
    (both axes), from the whitening, equals the one of the IRW covariance itself."""
    from uavloc_gcs.estimation.estimate import _offset_prior_norm
    from uavloc_gcs.estimation.fit import Problem

    t = np.concatenate([np.arange(0.0, 10.0, 0.5), np.arange(60.0, 70.0, 0.5), np.arange(150.0, 151.0, 0.5)])
    q = intensity_m2_s3(VMAX)
    passes = find_passes(t, float(t.max()), q)
    problem = Problem(None, True, False, VMAX, 1.0, passes)
    sign, logdet = np.linalg.slogdet(irw_covariance(passes.lags_s, q))
    assert sign > 0 and passes.count == 2
    assert _offset_prior_norm(problem) == pytest.approx(-logdet, rel=1e-6)  # -1/2 * 2 axes * logdet
    assert _offset_prior_norm(Problem(None, True, False, VMAX, 1.0, None)) == 0.0


def test_before_the_turn_the_lanes_alone_are_as_good_as_before(sc, channel):
    world = World(sc, seed=1, tracks=TURN)
    lanes = turn_mission(world)[0]
    est = estimate_emitter(lanes, channel, max_speed_m_s=VMAX)
    cv = estimate_emitter(lanes, channel, max_speed_m_s=VMAX, maneuver_time_s=math.inf)
    assert error_m(est, world) <= est.radius95_m <= 1.2 * cv.radius95_m
    # the prediction grows at least by v_max dt (the person may stop or turn at any moment)
    _, r60 = est.predict(est.t_ref_s + 60.0)
    assert r60 >= est.radius95_m + VMAX * 60.0 - 1e-9
    assert error_m(est, world, 60.0) <= r60


def test_an_old_fix_far_from_the_person_does_not_dominate(sc, channel):
    """Stood at (450, 300) for 60 s (scan lanes), then walked north-east 150 m; two crossing look
    passes at ~200 s over the new position. The old lanes say 'static at (450, 300)'."""
    walk = track([0.0, 60.0, 60.0 + 150.0 / 1.2, 1000.0],
                 [[450.0, 300.0], [450.0, 300.0], [450.0 + 106.07, 300.0 + 106.07], [450.0 + 106.07, 300.0 + 106.07]])
    for seed in range(3):  # measured: errors 2-6 m, radii ~8 m; CV 10-12 m off with radii 5-7 m
        world = World(sc, seed=seed, tracks=walk)
        slots = SlotBatch.concat([
            leg(world, 1, (150, 250), (750, 250), 0.0), leg(world, 1, (750, 350), (150, 350), 33.0),
            leg(world, 2, (380, 440), (730, 440), 185.0), leg(world, 2, (590, 520), (590, 250), 205.0)])
        est = estimate_emitter(slots, channel, max_speed_m_s=VMAX)
        cv = estimate_emitter(slots, channel, max_speed_m_s=VMAX, maneuver_time_s=math.inf)
        e = error_m(est, world)
        assert e <= est.radius95_m and e < 10.0
        assert est.radius95_m <= 15.0
        assert error_m(cv, world) > cv.radius95_m  # the CV fit is dragged towards the old position


def test_static_and_cv_people_keep_their_coverage(sc, channel):
    """i.i.d. shadowing, CV truth, two crossing looks ~20-40 s apart: the maneuver model still
    covers ~95 % and does not blow the radius up."""
    rng = np.random.default_rng(11)
    hits, ratio = 0, []
    n = 40
    for k in range(n):
        ang, sp = rng.uniform(0, 2 * np.pi), VMAX * math.sqrt(rng.uniform())
        world = World.with_people(sc, [[560.0, 320.0]], [[sp * math.cos(ang), sp * math.sin(ang)]], seed=500 + k)
        y, x = 320.0 - rng.uniform(0, 80), 560.0 - rng.uniform(0, 80)
        slots = SlotBatch.concat([leg(world, 1, (330, y), (790, y), 0.0), leg(world, 1, (x, 90), (x, 550), 23.0)])
        est = estimate_emitter(slots, channel, max_speed_m_s=VMAX)
        cv = estimate_emitter(slots, channel, max_speed_m_s=VMAX, maneuver_time_s=math.inf)
        hits += error_m(est, world) <= est.radius95_m
        ratio.append(est.mode_radius95_m / cv.mode_radius95_m)
    assert hits >= 0.85 * n
    assert np.median(ratio) < 1.3


def test_irw_covariance_known_values():
    q = 0.01
    lags = np.array([-100.0, -40.0, 0.0, 30.0])
    c = irw_covariance(lags, q)
    assert c[0, 0] == pytest.approx(q * 100.0**3 / 3.0)
    assert c[0, 1] == pytest.approx(q * 40.0**2 * (3 * 100.0 - 40.0) / 6.0)
    assert c[0, 3] == 0.0 and c[2, 2] == 0.0  # opposite sides of the anchor are independent
    assert np.all(np.linalg.eigvalsh(c) >= -1e-9)
    # the same numbers from simulated white-noise acceleration
    rng = np.random.default_rng(0)
    dt = 0.5
    acc = rng.standard_normal((4000, 200)) * math.sqrt(q / dt)
    dev = np.cumsum(np.cumsum(acc, axis=1) * dt, axis=1) * dt  # deviation after t = (k+1) dt
    i40, i100 = int(40 / dt) - 1, int(100 / dt) - 1
    emp = np.cov(dev[:, [i100, i40]].T)
    assert emp[0, 0] == pytest.approx(c[0, 0], rel=0.1)
    assert emp[0, 1] == pytest.approx(c[0, 1], rel=0.1)


def test_state_noise_is_the_irw_prediction_noise():
    n = state_noise(0.02, 10.0)
    assert n[0, 0] == pytest.approx(0.02 * 1000 / 3) and n[2, 2] == pytest.approx(0.2)
    assert n[0, 2] == pytest.approx(0.02 * 50) and n[0, 1] == 0.0
    assert np.all(state_noise(0.0, 10.0) == 0) and np.all(state_noise(0.02, 0.0) == 0)
    assert np.all(np.linalg.eigvalsh(state_noise(0.02, -7.0)) >= -1e-12)
    assert intensity_m2_s3(VMAX, math.inf) == 0.0 and intensity_m2_s3(0.0) == 0.0


def test_passes_from_slot_times():
    q = intensity_m2_s3(VMAX)
    t = np.concatenate([np.arange(0, 8, 0.1), np.arange(40, 48, 0.1), np.arange(150, 158, 0.1)])
    ps = find_passes(t, 158.0, q)
    assert ps.count == 2  # the last pass is the anchor's: on the CV line, no offset
    assert np.all(ps.index[t >= 150] == -1)
    assert len(set(ps.index[t < 8])) == 1 and len(set(ps.index[(t >= 40) & (t < 48)])) == 1
    assert ps.index[0] != ps.index[-81]
    assert find_passes(t[t >= 150], 158.0, q) is None  # one pass: nothing to deviate
    assert find_passes(t, 158.0, 0.0) is None  # pure CV
    many = np.concatenate([np.arange(k * 20.0, k * 20.0 + 3, 0.1) for k in range(20)])
    assert find_passes(many, many[-1], q).count == MAX_PASSES


def test_hours_of_data_keep_the_turn_prior_finite(channel):
    """A person heard again two hours after the first pass: P(no turn) = exp(-lag / 200 s) is
    below the float spacing at 1, and ln(1 - P(a turn)) was a math domain error that ended a whole
    search (tests/test_e2e_vehicle_faults.py, 7,600 s of one person's slots)."""
    from uavloc_gcs.estimation.estimate import _turn_log_prior

    no_turn, a_turn = _turn_log_prior(7600.0, 200.0)
    assert no_turn == -38.0 and a_turn == pytest.approx(0.0, abs=1e-15)
    assert _turn_log_prior(1e-3, 200.0)[1] == pytest.approx(math.log(5e-6), rel=1e-6)
    world = World.with_people(load_scenario(EXAMPLES / "paper.toml"), [[560.0, 320.0]], [[0.0, 0.0]], seed=2)
    slots = SlotBatch.concat([leg(world, 1, (400, 250), (720, 250), 0.0), leg(world, 1, (720, 350), (400, 350), 20.0),
                              leg(world, 1, (400, 250), (720, 250), 7600.0)])
    est = estimate_emitter(slots, channel, max_speed_m_s=VMAX)
    assert est.ok and math.isfinite(est.radius95_m)
    assert np.linalg.norm(est.position_xy_m - [560.0, 320.0]) <= est.radius95_m
