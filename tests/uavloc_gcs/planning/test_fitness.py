"""The shared fitness: encodings and the optimal split."""

import itertools

import numpy as np

from uavloc_gcs.planning.fitness import Evaluator

from .helpers import random_problem


def _estimate(ev: Evaluator, order, counts) -> float:
    """The split's own route estimate (centre lengths minus visited radii), by hand."""
    b = np.concatenate([[0], np.cumsum(counts)])
    worst = 0.0
    for v in range(ev.m):
        chunk = order[b[v]:b[v + 1]]
        pts = np.vstack([ev.node_xy[ev.n + v], ev.node_xy[chunk], ev.node_xy[ev.n + ev.m + v]])
        length = np.linalg.norm(np.diff(pts, axis=0), axis=1).sum() - ev.node_r[chunk].sum()
        worst = max(worst, length)
    return worst


def test_split_is_optimal_for_its_estimate():
    p = random_problem(7, 3, seed=3)
    ev = Evaluator(p)
    rng = np.random.default_rng(0)
    order = np.array([rng.permutation(7) for _ in range(6)])
    counts = ev.split(order)
    assert np.all(counts.sum(axis=1) == 7)
    for k in range(6):
        best = min(_estimate(ev, order[k], np.diff([0, *cuts, 7]))
                   for cuts in itertools.combinations_with_replacement(range(8), 2))
        assert abs(_estimate(ev, order[k], counts[k]) - best) < 1e-9


def test_key_encodings_round_trip():
    p = random_problem(9, 3, seed=4)
    ev = Evaluator(p)
    routes = [[3, 1], [], [0, 2, 4, 5, 6, 7, 8]]
    order, counts = ev.decode_keys(ev.encode_keys(routes))
    assert ev.to_routes(order[0], counts[0]) == routes
    tour = np.array([4, 2, 0, 8, 1, 3, 5, 7, 6])
    order, _ = ev.decode_tour_keys(ev.encode_tour_keys(tour))
    np.testing.assert_array_equal(order[0], tour)
