"""The optimizers: brute-force optima on tiny instances, validity, energy, determinism, errors,
warm starts, callbacks and the anchors."""

import itertools

import numpy as np
import pytest

from uavloc_gcs.errors import ConfigError, InfeasibleError
from uavloc_gcs.planning import RoutingProblem, Target, VehicleState, lower_bound_s, solve
from uavloc_gcs.planning.fitness import Evaluator
from uavloc_gcs.planning.swarm import adaptive_inertia

from .helpers import check_plan, random_problem


def brute_force_optimum(problem: RoutingProblem) -> float:
    """Every assignment and order, each with converged edge access (energy ignored: budgets are
    generous in these instances)."""
    n, m = len(problem.targets), len(problem.vehicles)
    ev = Evaluator(problem)
    orders, counts = [], []
    for perm in itertools.permutations(range(n)):
        for cuts in itertools.combinations_with_replacement(range(n + 1), m - 1):
            c = np.diff([0, *cuts, n])
            orders.append(perm)
            counts.append(c)
    orders, counts = np.array(orders), np.array(counts)
    # Prune with the quick evaluation (an upper bound), then converge the promising ones.
    quick = ev.evaluate(orders, counts).makespan_s
    keep = quick <= quick.min() * 1.05 + 1e-9
    return float(ev.refine(orders[keep], counts[keep]).makespan_s.min())


TINY = [
    random_problem(5, 2, seed=1, size=(600, 400)),
    random_problem(5, 2, seed=2, r_range=(0.0, 0.0), size=(600, 400)),  # classic min-max mTSP
    random_problem(4, 3, seed=3, size=(600, 400)),
    RoutingProblem(  # different starts and homes
        (VehicleState("a", (-200.0, 0.0), (0.0, 0.0), 1e6), VehicleState("b", (250.0, 100.0), (0.0, 0.0), 1e6)),
        tuple(Target(f"t{i}", xy, (0.0, 0.0), r) for i, (xy, r) in
              enumerate([((-250.0, 150.0), 40.0), ((100.0, -200.0), 30.0), ((300.0, -50.0), 60.0),
                         ((0.0, 250.0), 20.0), ((-100.0, -100.0), 50.0)])),
        25.0),
]


@pytest.mark.parametrize("k", range(len(TINY)))
def test_epso_finds_the_brute_force_optimum(k):
    p = TINY[k]
    best = brute_force_optimum(p)
    res = solve(p, method="epso", rng=0, time_limit_s=10, max_iter=30)
    check_plan(p, res.plan)
    assert res.success
    assert res.fun == pytest.approx(best, rel=1e-5)
    assert lower_bound_s(p) <= best + 1e-9


@pytest.mark.parametrize("method", ["pso", "ga"])
def test_baselines_with_local_search_find_the_optimum_too(method):
    p = TINY[0]
    res = solve(p, method=method, rng=0, time_limit_s=10, max_iter=30)
    assert res.fun == pytest.approx(brute_force_optimum(p), rel=1e-5)


@pytest.mark.parametrize("method", ["epso", "pso", "ga"])
@pytest.mark.parametrize("local_search", [True, False])
def test_all_optimizers_give_valid_plans_on_the_same_instance(method, local_search):
    p = random_problem(25, 4, seed=11)
    res = solve(p, method=method, rng=3, time_limit_s=0.5, local_search=local_search)
    assert res.success, res.message
    check_plan(p, res.plan)
    assert res.nit > 0 and res.nfev > 0
    assert res.fun == res.plan.makespan_s
    assert res.fun >= lower_bound_s(p)


def test_local_search_beats_plain_epso():
    p = random_problem(30, 4, seed=12)
    plain = solve(p, method="epso", rng=1, time_limit_s=0.6, local_search=False)
    ls = solve(p, method="epso", rng=1, time_limit_s=0.6, local_search=True)
    assert ls.fun < plain.fun


@pytest.mark.parametrize("method", ["epso", "pso", "ga"])
def test_same_seed_same_plan(method):
    p = random_problem(12, 3, seed=5)
    a = solve(p, method=method, rng=42, time_limit_s=30, max_iter=15)
    b = solve(p, method=method, rng=np.random.default_rng(42), time_limit_s=30, max_iter=15)
    assert a.fun == b.fun
    assert a.plan.assignment() == b.plan.assignment()
    np.testing.assert_array_equal(a.x, b.x)


def test_energy_budget_is_respected_and_binds():
    # One vehicle has little energy: it can serve only nearby people.
    p = random_problem(10, 2, seed=8, size=(800, 500))
    free = solve(p, method="epso", rng=0, time_limit_s=30, max_iter=20)
    lengths = sorted(r.duration_s * p.speed_m_s for r in free.plan.routes)
    e_per_m = p.energy_per_m_j
    small = 0.5 * lengths[0] * e_per_m  # half of what the shorter route needed
    tight = RoutingProblem((VehicleState("uav0", (0.0, 0.0), (0.0, 0.0), 1e6),
                            VehicleState("uav1", (0.0, 0.0), (0.0, 0.0), small)), p.targets, p.speed_m_s)
    res = solve(tight, method="epso", rng=0, time_limit_s=30, max_iter=20)
    assert res.success
    check_plan(tight, res.plan)
    by = {r.vehicle_id: r for r in res.plan.routes}
    assert by["uav1"].energy_j <= small
    assert res.fun >= free.fun - 1e-9


def test_unreachable_target_names_it_and_the_numbers():
    p = RoutingProblem((VehicleState("uav1", (0.0, 0.0), (0.0, 0.0), 5000.0),),
                       (Target("near", (50.0, 0.0), (0.0, 0.0), 10.0), Target("far", (2000.0, 0.0), (0.0, 0.0), 10.0)),
                       25.0)
    with pytest.raises(InfeasibleError, match=r"target far .*radius 10\.0 m.*uav1.*3980\.0 m.*5000 J") as err:
        solve(p)
    # the reason in the target's own terms, for a person's row (which says who): no id in it
    assert err.value.target_id == "far" and "far" not in err.value.why
    assert err.value.why.startswith("a look at (2000, 0) m, passing within 10 m of it: the best vehicle uav1 needs 3980.0 m")


def test_a_person_given_up_for_energy_is_told_why_without_an_internal_id():
    """The field demo's rows read "(target 6995899769478 at (955.6, 430.2) m, radius 86.2 m is out
    of reach ...)" beside "P01 #06:5c:dc:1e:e2:86" (issue 40 item 3)."""
    from types import SimpleNamespace

    from uavloc_gcs.search.policy import SearchPolicy

    p = RoutingProblem((VehicleState(2, (0.0, 0.0), (0.0, 0.0), 5000.0),),
                       (Target(6995899769478, (2000.0, 0.0), (0.0, 0.0), 86.2),), 25.0)
    with pytest.raises(InfeasibleError) as err:
        solve(p)
    person = SimpleNamespace(gave_up="")
    me = SimpleNamespace(_people={6995899769478: person})
    assert SearchPolicy._drop_unreachable(me, p, err.value)
    assert "6995899769478" not in person.gave_up
    assert person.gave_up.startswith("no vehicle has the energy for a look that could locate it (a look at (2000, 0) m")


def test_vehicle_that_cannot_get_home():
    p = RoutingProblem((VehicleState("uav1", (5000.0, 0.0), (0.0, 0.0), 1000.0),), (), 25.0)
    with pytest.raises(InfeasibleError, match="vehicle uav1 cannot reach home"):
        solve(p)


@pytest.mark.parametrize("problem, pattern", [
    (RoutingProblem((), (Target("a", (0.0, 0.0)),), 25.0), "no vehicles"),
    (RoutingProblem((VehicleState("u", (0.0, 0.0), (0.0, 0.0), 1e5),), (Target("a", (0.0, 0.0), (0.0, 0.0), -5.0),), 25.0),
     r"target a: negative radius -5\.0"),
    (RoutingProblem((VehicleState("u", (0.0, float("nan")), (0.0, 0.0), 1e5),), (), 25.0), "vehicle u: non-finite"),
    (RoutingProblem((VehicleState("u", (0.0, 0.0), (0.0, 0.0), 1e5),), (Target("a", (float("inf"), 0.0)),), 25.0),
     "target a: non-finite"),
    (RoutingProblem((VehicleState("u", (0.0, 0.0), (0.0, 0.0), 1e5),), (), 0.0), "speed must be a positive"),
    (RoutingProblem((VehicleState("u", (0.0, 0.0), (0.0, 0.0), 1e5),), (Target("a", (0.0, 0.0)), Target("a", (1.0, 0.0))), 25.0),
     "appears twice"),
])
def test_bad_input_is_a_config_error(problem, pattern):
    with pytest.raises(ConfigError, match=pattern):
        solve(problem)


def test_unknown_method_and_option():
    p = random_problem(3, 1)
    with pytest.raises(ConfigError, match="unknown planner method"):
        solve(p, method="aco")
    with pytest.raises(ConfigError, match="unknown planner option"):
        solve(p, method="epso", swarm_size=3)


def test_no_targets_sends_everyone_home():
    p = RoutingProblem((VehicleState("u", (300.0, 400.0), (0.0, 0.0), 1e6),), (), 25.0)
    res = solve(p)
    assert res.fun == pytest.approx(20.0)
    assert res.plan.routes[0].target_ids == ()


def test_warm_start_after_targets_changed():
    p = random_problem(20, 3, seed=21)
    first = solve(p, method="epso", rng=0, time_limit_s=0.5)
    # Two people resolved, three new ones appear.
    extra = random_problem(3, 3, seed=99).targets
    extra = tuple(Target(f"new{i}", t.xy_m, t.velocity_m_s, t.radius_m) for i, t in enumerate(extra))
    p2 = RoutingProblem(p.vehicles, p.targets[2:] + extra, p.speed_m_s)
    warm = solve(p2, method="epso", rng=0, time_limit_s=30, max_iter=0, local_search=False,
                 warm_start=first.plan)
    check_plan(p2, warm.plan)
    cold = solve(p2, method="epso", rng=0, time_limit_s=30, max_iter=0, local_search=False)
    # With no iterations the answer is the best initial particle: the warm start must be it.
    assert warm.fun < cold.fun


def test_callback_can_stop_the_search():
    p = random_problem(15, 3, seed=2)
    seen = []

    def cb(progress):
        seen.append(progress.fun)
        return progress.nit >= 3

    res = solve(p, method="epso", rng=0, time_limit_s=30, callback=cb, local_search=False)
    assert res.nit == 3 and res.message == "stopped by callback"
    assert seen == sorted(seen, reverse=True)  # the best value never gets worse


def test_moving_targets_plan_is_valid():
    p = random_problem(20, 4, seed=31, speed_person=1.5)
    res = solve(p, method="epso", rng=0, time_limit_s=0.5)
    check_plan(p, res.plan, tol_m=1e-3)


def test_adaptive_inertia_follows_the_paper():
    f = np.array([1.0, 2.0, 3.0, 10.0])  # mean 4
    w = adaptive_inertia(f, 0.4, 0.9)
    np.testing.assert_allclose(w, [0.4, 0.4 + 0.5 / 3, 0.4 + 1.0 / 3, 0.9])
    assert np.all(adaptive_inertia(np.ones(3)) == 0.4)


@pytest.mark.parametrize("method", ["ortools", "pyvrp"])
def test_anchors_give_valid_plans(method):
    p = random_problem(12, 3, seed=41)
    res = solve(p, method=method, rng=0, time_limit_s=0.3)
    assert res.success
    check_plan(p, res.plan)


def test_warm_start_after_a_vehicle_is_lost():
    p = random_problem(12, 3, seed=23)
    first = solve(p, method="epso", rng=0, time_limit_s=0.3)
    p2 = RoutingProblem(p.vehicles[:2], p.targets, p.speed_m_s)  # uav2 went silent
    res = solve(p2, method="epso", rng=0, time_limit_s=0.3, warm_start=first.plan)
    check_plan(p2, res.plan)
    assert {r.vehicle_id for r in res.plan.routes} == {"uav0", "uav1"}
