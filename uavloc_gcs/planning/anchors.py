"""External anchors (optional extra ``uavloc[bench]``): Google OR-Tools and PyVRP.

Both see the disk *centres* (they have no notion of access disks; moving targets at ``t0_s``);
their assignment and order then get the same edge-access refinement as EPSO's, so the comparison
isolates the search. Energy budgets become per-vehicle distance limits.

* OR-Tools: a distance dimension with a global span cost (min-max; arc costs stay in as a
  tie-breaker), PATH_CHEAPEST_ARC then guided local search for the whole time budget.
* PyVRP: no min-max objective, so bisection on the vehicles' maximum route distance, each
  probe a PyVRP solve with an equal share of the time budget; the best feasible probe wins.
"""

from __future__ import annotations

import logging
import warnings

import numpy as np

from ..errors import ConfigError
from .fitness import Evaluator
from .problem import RoutingProblem

log = logging.getLogger(__name__)

SCALE = 100  # integer distances in centimetres


def _nodes(problem: RoutingProblem) -> tuple[np.ndarray, int, int]:
    """Node coordinates: targets 0..n-1, starts n..n+m-1, homes n+m..n+2m-1."""
    xy = np.concatenate([problem.centres_xy_m, problem.starts_xy_m, problem.homes_xy_m])
    return xy, len(problem.targets), len(problem.vehicles)


def _int_dist(xy: np.ndarray) -> np.ndarray:
    d = np.sqrt(((xy[:, None] - xy[None]) ** 2).sum(-1))
    return np.rint(d * SCALE).astype(np.int64)


def solve_anchor(problem: RoutingProblem, ev: Evaluator, method: str, time_limit_s: float,
                 rng: np.random.Generator, **options) -> tuple[list[list[int]], str]:
    if options:
        raise ConfigError(f"the {method} anchor takes no options, got {sorted(options)}")
    if ev.n == 0:
        return [[] for _ in range(ev.m)], "no targets"
    if method == "ortools":
        return solve_ortools(problem, time_limit_s, int(rng.integers(2**31)))
    return solve_pyvrp(problem, time_limit_s, int(rng.integers(2**31)))


def solve_ortools(problem: RoutingProblem, time_limit_s: float, seed: int = 0,
                  span_coefficient: int = 100) -> tuple[list[list[int]], str]:
    """Min-max routes on the centres with OR-Tools (global span cost + GLS)."""
    try:
        from ortools.constraint_solver import pywrapcp, routing_enums_pb2
    except ImportError as err:  # pragma: no cover - depends on the environment
        raise ConfigError("the ortools anchor needs the optional extra: pip install 'uavloc[bench]'") from err
    xy, n, m = _nodes(problem)
    dist = _int_dist(xy)
    starts = [n + v for v in range(m)]
    ends = [n + m + v for v in range(m)]
    manager = pywrapcp.RoutingIndexManager(n + 2 * m, m, starts, ends)
    routing = pywrapcp.RoutingModel(manager)
    dl = dist.tolist()

    def cb(i, j):
        return dl[manager.IndexToNode(i)][manager.IndexToNode(j)]

    transit = routing.RegisterTransitCallback(cb)
    routing.SetArcCostEvaluatorOfAllVehicles(transit)
    caps = [int(min(c * SCALE, 2**62)) for c in problem.max_length_m]
    routing.AddDimensionWithVehicleCapacity(transit, 0, caps, True, "Distance")
    routing.GetDimensionOrDie("Distance").SetGlobalSpanCostCoefficient(span_coefficient)
    params = pywrapcp.DefaultRoutingSearchParameters()
    params.first_solution_strategy = routing_enums_pb2.FirstSolutionStrategy.PATH_CHEAPEST_ARC
    params.local_search_metaheuristic = (
        routing_enums_pb2.LocalSearchMetaheuristic.GUIDED_LOCAL_SEARCH)
    params.time_limit.FromMilliseconds(max(1, int(time_limit_s * 1000)))
    sol = routing.SolveWithParameters(params)
    if sol is None:
        raise ConfigError("OR-Tools found no solution within the time limit")
    routes = []
    for v in range(m):
        idx = routing.Start(v)
        r = []
        idx = sol.Value(routing.NextVar(idx))
        while not routing.IsEnd(idx):
            r.append(manager.IndexToNode(idx))
            idx = sol.Value(routing.NextVar(idx))
        routes.append(r)
    return routes, "OR-Tools global span cost + guided local search"


def solve_pyvrp(problem: RoutingProblem, time_limit_s: float, seed: int = 0,
                probes: int = 8) -> tuple[list[list[int]], str]:
    """Min-max via bisection on the maximum route distance, PyVRP for each probe."""
    try:
        import pyvrp
        from pyvrp.stop import MaxRuntime
    except ImportError as err:  # pragma: no cover
        raise ConfigError("the pyvrp anchor needs the optional extra: pip install 'uavloc[bench]'") from err
    xy, n, m = _nodes(problem)
    dist = _int_dist(xy)
    caps = np.minimum(problem.max_length_m * SCALE, 2**62).astype(np.int64)
    # Upper end: one vehicle's worth of everything (a giant tour bound); lower end: 0.
    single = np.max(dist[n:n + m, :n], axis=0).sum() * 2 + int(dist.max()) + 1
    lo, hi = 0, int(single)
    best: list[list[int]] | None = None
    best_len = np.inf
    per_probe = time_limit_s / probes
    for _ in range(probes):
        limit = (lo + hi) // 2 if best is not None else hi
        routes = _pyvrp_probe(pyvrp, MaxRuntime, xy, dist, n, m, np.minimum(caps, limit),
                              per_probe, seed)
        if routes is not None:
            length = max(_route_len(dist, n, m, v, r) for v, r in enumerate(routes))
            if length < best_len:
                best, best_len = routes, length
            hi = min(limit, int(length))
        else:
            lo = limit
        if hi - lo <= 1:
            break
    if best is None:
        raise ConfigError("PyVRP found no feasible solution within the time limit")
    return best, "PyVRP, bisection on the maximum route distance"


def _route_len(dist, n, m, v, r) -> int:
    seq = [n + v, *r, n + m + v]
    return int(sum(dist[a, b] for a, b in zip(seq[:-1], seq[1:])))


def _pyvrp_probe(pyvrp, MaxRuntime, xy, dist, n, m, max_dist, runtime_s, seed):
    model = pyvrp.Model()
    locs = [model.add_location(x=int(round(p[0] * SCALE)), y=int(round(p[1] * SCALE))) for p in xy]
    depots = [model.add_depot(locs[n + k]) for k in range(2 * m)]
    for i in range(n):
        model.add_client(locs[i])
    for v in range(m):
        model.add_vehicle_type(num_available=1, start_depot=depots[v], end_depot=depots[m + v],
                               max_distance=int(max_dist[v]))
    for a in range(n + 2 * m):
        for b in range(n + 2 * m):
            model.add_edge(locs[a], locs[b], distance=int(dist[a, b]))
    with warnings.catch_warnings():
        # Probes below the optimal limit are infeasible by design; PyVRP warns about them.
        warnings.simplefilter("ignore")
        res = model.solve(stop=MaxRuntime(runtime_s), seed=seed, display=False)
    if not res.best.is_feasible():
        return None
    # Scheduled client activities carry the client index (add order = target index).
    routes = [[] for _ in range(m)]
    for route in res.best.routes():
        routes[route.vehicle_type()] = [int(a.idx) for a in route.schedule() if a.is_client()]
    if sorted(i for r in routes for i in r) != list(range(n)):
        return None
    return routes
