"""Genetic algorithm with the two-part chromosome (Carter & Ragsdale, EJOR 175(1), 2006).

Part 1 is a permutation of the ``n`` targets, part 2 the ``m`` route sizes (non-negative, summing
to ``n``). Binary tournament selection, order crossover (OX) on part 1 with part 2 taken from the
first parent, swap/inversion mutation on part 1, and moving one target between two routes'
sizes on part 2; the best ``elite`` individuals survive unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .fitness import Evaluator
from .localsearch import LocalSearch
from .stopping import limit_reached


@dataclass
class GAOptions:
    population: int = 40
    crossover_rate: float = 0.9
    mutation_rate: float = 0.2
    size_mutation_rate: float = 0.3
    elite: int = 2
    ls_every: int = 5


def order_crossover(p1: np.ndarray, p2: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """OX: keep a random slice of ``p1``, fill the rest in ``p2``'s order."""
    n = len(p1)
    a, b = sorted(rng.integers(0, n + 1, size=2))
    child = np.empty(n, dtype=p1.dtype)
    keep = p1[a:b]
    mask = np.ones(n, dtype=bool)
    mask[keep] = False  # targets are 0..n-1
    rest = p2[mask[p2]]
    child[a:b] = keep
    child[:a] = rest[:a]
    child[b:] = rest[a:]
    return child


def random_sizes(n: int, m: int, size: int, rng: np.random.Generator) -> np.ndarray:
    return rng.multinomial(n, np.full(m, 1.0 / m), size=size)


def genetic(ev: Evaluator, *, rng: np.random.Generator, deadline: float, max_iter: int | None,
            local_search: bool, seeds: list[list[list[int]]],
            callback: Callable[[np.ndarray, float, int], bool] | None,
            opts: GAOptions) -> tuple[np.ndarray, float, int, str]:
    """Returns (best chromosome = concat(permutation, sizes), fitness, generations, message)."""
    n, m, P = ev.n, ev.m, opts.population
    perm = np.array([rng.permutation(n) for _ in range(P)]).reshape(P, n)
    sizes = random_sizes(n, m, P, rng)
    for k, routes in enumerate(seeds[:P]):
        perm[k], sizes[k] = ev.from_routes(routes)
    f = ev.evaluate(perm, sizes).fitness
    ls = LocalSearch(ev) if local_search else None
    it = 0
    while (message := limit_reached(it, max_iter, deadline)) is None:
        it += 1
        elite = np.argsort(f)[:opts.elite]
        new_perm = [perm[e].copy() for e in elite]
        new_sizes = [sizes[e].copy() for e in elite]
        while len(new_perm) < P:
            i, j = rng.integers(0, P, 2), rng.integers(0, P, 2)
            a = i[np.argmin(f[i])]
            b = j[np.argmin(f[j])]
            child = order_crossover(perm[a], perm[b], rng) if rng.random() < opts.crossover_rate \
                else perm[a].copy()
            cs = sizes[a].copy()
            if n > 1 and rng.random() < opts.mutation_rate:
                x, y = sorted(rng.choice(n, 2, replace=False))
                if rng.random() < 0.5:
                    child[x], child[y] = child[y], child[x]
                else:
                    child[x:y + 1] = child[x:y + 1][::-1]
            if m > 1 and rng.random() < opts.size_mutation_rate:
                src = rng.choice(np.flatnonzero(cs > 0)) if cs.sum() else 0
                dst = rng.integers(0, m)
                if cs[src] > 0:
                    cs[src] -= 1
                    cs[dst] += 1
            new_perm.append(child)
            new_sizes.append(cs)
        perm, sizes = np.array(new_perm), np.array(new_sizes)
        f = ev.evaluate(perm, sizes).fitness
        if ls is not None and (it - 1) % opts.ls_every == 0:
            b = int(np.argmin(f))
            routes, fl = ls.run(ev.to_routes(perm[b], sizes[b]), deadline)
            if fl < f[b]:
                perm[b], sizes[b] = ev.from_routes(routes)
                f[b] = fl
        b = int(np.argmin(f))
        if callback is not None and callback(np.concatenate([perm[b], sizes[b]]), float(f[b]), it):
            message = "stopped by callback"
            break
    b = int(np.argmin(f))
    return np.concatenate([perm[b], sizes[b]]), float(f[b]), it, message
