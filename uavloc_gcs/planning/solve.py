"""``solve(problem, method=...)``: one entry point for EPSO, PSO, GA and the external anchors."""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, fields
from typing import Callable

import numpy as np

from ..errors import ConfigError
from .bounds import lower_bound_s
from .fitness import Evaluator
from .ga import GAOptions, genetic
from .localsearch import LocalSearch
from .problem import Plan, PlanResult, RoutingProblem, check_reachable, validate
from .swarm import SwarmOptions, particle_swarm

log = logging.getLogger(__name__)

METHODS = ("epso", "pso", "ga", "ortools", "pyvrp")


@dataclass
class Progress:
    """What a callback sees after each iteration. Return True (or raise StopIteration) to stop."""

    x: np.ndarray
    fun: float
    nit: int
    nfev: int
    elapsed_s: float


def _rng(rng) -> np.random.Generator:
    if isinstance(rng, np.random.Generator):
        return rng
    return np.random.default_rng(rng)


def _split_options(cls, options: dict) -> object:
    names = {f.name for f in fields(cls)}
    bad = set(options) - names
    if bad:
        raise ConfigError(f"unknown planner option(s) {sorted(bad)}; known: {sorted(names)}")
    return cls(**options)


def warm_routes(problem: RoutingProblem, ev: Evaluator, plan: Plan) -> list[list[int]]:
    """Routes of ``plan`` mapped onto ``problem``: vanished targets dropped, new ones inserted
    at their cheapest min-max position, vehicles no longer present dropped."""
    tindex = {t.id: i for i, t in enumerate(problem.targets)}
    by_vehicle = {r.vehicle_id: r.target_ids for r in plan.routes}
    routes, seen = [], set()
    for v in problem.vehicles:
        r = [tindex[t] for t in by_vehicle.get(v.id, ()) if t in tindex and t not in seen]
        seen.update(problem.targets[i].id for i in r)
        routes.append(r)
    new = [i for i, t in enumerate(problem.targets) if t.id not in seen]
    return LocalSearch(ev).insert(routes, new)


def greedy_routes(problem: RoutingProblem, ev: Evaluator) -> list[list[int]]:
    """Cheapest min-max insertion, farthest targets first (a seed for the search)."""
    c = problem.centres_xy_m
    depots = np.concatenate([problem.starts_xy_m, problem.homes_xy_m])
    far = np.min(np.linalg.norm(c[:, None] - depots[None], axis=2), axis=1)
    return LocalSearch(ev).insert([[] for _ in problem.vehicles], list(np.argsort(-far)))


def relaxed_routes(problem: RoutingProblem, deadline: float) -> list[list[int]]:
    """Routes of ``problem`` planned as if every pack were endless (greedy seed, then local search
    until ``deadline``): a seed for the multi-trip problem. Where the best routes need no swap it
    finds them; where they do, their order is still good and the fitness places the swaps. Without
    it the search starts from routes the sorties' swaps make costly to rebalance (a swap costs its
    minutes on the ground whatever the route gains)."""
    import dataclasses

    endless = dataclasses.replace(problem, vehicles=tuple(
        dataclasses.replace(v, energy_j=1e15, spare_packs=0, pack_energy_j=0.0) for v in problem.vehicles))
    ev = Evaluator(endless)
    routes, _ = LocalSearch(ev).run(greedy_routes(endless, ev), deadline)
    return routes


def solve(problem: RoutingProblem, *, method: str = "epso", rng=None, time_limit_s: float = 1.0,
          max_iter: int | None = None, local_search: bool = True, warm_start: Plan | None = None,
          callback: Callable[[Progress], bool | None] | None = None, **options) -> PlanResult:
    """Plan routes minimizing the makespan [s] under the vehicles' energy budgets.

    ``method``: "epso" (paper, adaptive inertia), "pso" (fixed inertia), "ga" (two-part
    chromosome), or the anchors "ortools" / "pyvrp" (optional extra). ``local_search`` and
    ``warm_start`` go beyond the paper; with ``local_search=False`` and no warm start EPSO/PSO/GA
    are the paper's plain optimizers. ``time_limit_s`` bounds the search (the final access-point
    refinement comes on top, a few milliseconds). ``options`` go to SwarmOptions / GAOptions.
    Raises ConfigError on malformed input and InfeasibleError when some target cannot be served.
    """
    t_start = time.perf_counter()
    if method not in METHODS:
        raise ConfigError(f"unknown planner method {method!r}; choose one of {', '.join(METHODS)}")
    if not (time_limit_s > 0):
        raise ConfigError(f"time limit must be positive, got {time_limit_s} s")
    validate(problem)
    check_reachable(problem)
    gen = _rng(rng)
    ev = Evaluator(problem)
    lb = lower_bound_s(problem)

    if method in ("ortools", "pyvrp"):
        from . import anchors  # optional extra, imported lazily

        routes, message = anchors.solve_anchor(problem, ev, method, time_limit_s, gen, **options)
        order, counts = ev.from_routes(routes)
        plan = ev.plan(order, counts, lb)
        return _result(ev, order, counts, plan, 1, message, t_start, np.concatenate([order, counts]))

    if ev.n == 0:
        order, counts = np.zeros(0, dtype=int), np.zeros(ev.m, dtype=int)
        plan = ev.plan(order, counts, lb)
        return _result(ev, order, counts, plan, 0, "no targets", t_start, np.zeros(0))

    seeds: list[list[list[int]]] = []
    if warm_start is not None:
        seeds.append(warm_routes(problem, ev, warm_start))
    if local_search:
        seeds.append(greedy_routes(problem, ev))
        if ev.sorties:
            seeds.append(relaxed_routes(problem, t_start + 0.15 * time_limit_s))

    # Keep back time for the final access-point refinement and, with local search, a last
    # polish of the best solution.
    # Steps are checked against the clock between rounds, so aim a little short of the limit.
    budget = 0.95 * time_limit_s - min(0.02, 0.1 * time_limit_s)
    reserve = 0.1 * budget
    polish = 0.05 * budget if local_search else 0.0
    deadline = t_start + budget - reserve - polish

    history: list[float] = []

    def cb(x, fun, nit):
        history.append(fun)
        if callback is None:
            return False
        try:
            return bool(callback(Progress(x, fun, nit, ev.nfev, time.perf_counter() - t_start)))
        except StopIteration:
            return True

    if method in ("epso", "pso"):
        opts = _split_options(SwarmOptions, options)
        x, (order, counts), fun, nit, message = particle_swarm(
            ev, adaptive=(method == "epso"), rng=gen, deadline=deadline, max_iter=max_iter,
            local_search=local_search, seeds=seeds, callback=cb, opts=opts)
    else:
        opts = _split_options(GAOptions, options)
        x, fun, nit, message = genetic(
            ev, rng=gen, deadline=deadline, max_iter=max_iter, local_search=local_search,
            seeds=seeds, callback=cb, opts=opts)
        order, counts = x[:ev.n].astype(int), x[ev.n:].astype(int)
    points = None
    if local_search:
        # Polish the final answer once more (cheap, and keeps the result locally optimal).
        ls = LocalSearch(ev)
        routes, _ = ls.run(ev.to_routes(order, counts), t_start + budget - reserve)
        order, counts = ev.from_routes(routes)
        points = ls.evaluate(routes)[1]
    plan = ev.plan(order, counts, lb, points=points, deadline=t_start + budget)
    res = _result(ev, order, counts, plan, nit, message, t_start, np.asarray(x))
    res.history = history
    return res


def _result(ev: Evaluator, order, counts, plan: Plan, nit: int, message: str, t_start: float,
            x: np.ndarray) -> PlanResult:
    if ev.sorties:
        return _sortie_result(ev, plan, nit, message, t_start, x)
    energy_m = np.array([r.energy_j for r in plan.routes]) / ev.problem.energy_per_m_j  # flight + services' energy, in metres
    feasible = bool(np.all(energy_m <= ev.max_len * (1 + 1e-9) + 1e-6))
    if not feasible:
        over = [(r.vehicle_id, r.energy_j, v.energy_j) for r, v in zip(plan.routes, ev.problem.vehicles)
                if r.energy_j > v.energy_j * (1 + 1e-9)]
        message = "no energy-feasible plan found: " + "; ".join(
            f"vehicle {vid} needs {need:.0f} J, has {have:.0f} J" for vid, need, have in over)
    return PlanResult(x=x, fun=plan.makespan_s, nit=nit, nfev=ev.nfev, success=feasible,
                      message=message, plan=plan, runtime_s=time.perf_counter() - t_start)


def _sortie_result(ev: Evaluator, plan: Plan, nit: int, message: str, t_start: float, x: np.ndarray) -> PlanResult:
    """As ``_result``, each sortie checked against its pack: the first against the vehicle's energy,
    the later ones against a fresh pack, and no more sorties than packs."""
    over = []
    for r, v in zip(plan.routes, ev.problem.vehicles):
        caps = [v.energy_j] + [v.pack_energy_j] * v.spare_packs
        if len(r.sortie_energy_j) > len(caps):
            over.append(f"vehicle {v.id} needs {len(r.sortie_energy_j)} packs, has {len(caps)}")
        for k, (need, have) in enumerate(zip(r.sortie_energy_j, caps)):
            if need > have * (1 + 1e-9) + 1e-6 * ev.problem.energy_per_m_j:
                over.append(f"vehicle {v.id} sortie {k + 1} needs {need:.0f} J, its pack has {have:.0f} J")
    if over:
        message = "no energy-feasible plan found: " + "; ".join(over)
    return PlanResult(x=x, fun=plan.makespan_s, nit=nit, nfev=ev.nfev, success=not over,
                      message=message, plan=plan, runtime_s=time.perf_counter() - t_start)
