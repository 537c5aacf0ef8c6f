"""EPSO and PSO over random keys.

A particle is ``n`` keys in ``[0, m)``: the integer part picks the vehicle, the order of the keys
within a vehicle is the visiting order (Bean 1994; SPV rule). Positions and velocities follow the
standard update ``v <- w v + c1 r1 (pbest - x) + c2 r2 (gbest - x)`` with velocity clamping.

* EPSO (the paper): per-particle adaptive inertia, minimization,
  ``w_i = w_min + (w_max - w_min)(f_i - f_min)/(f_avg - f_min)`` if ``f_i <= f_avg`` else ``w_max``:
  good particles slow down and search locally, poor ones keep exploring.
* PSO: fixed inertia ``w`` (Clerc's constriction-equivalent 0.7298).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .fitness import Evaluator
from .localsearch import LocalSearch
from .stopping import limit_reached


def adaptive_inertia(f: np.ndarray, w_min: float = 0.4, w_max: float = 0.9) -> np.ndarray:
    """The paper's per-particle inertia for minimization (see module docstring)."""
    f_min, f_avg = float(np.min(f)), float(np.mean(f))
    if not f_avg > f_min:
        return np.full(f.shape, w_min)
    w = w_min + (w_max - w_min) * (f - f_min) / (f_avg - f_min)
    return np.where(f <= f_avg, w, w_max)


@dataclass
class SwarmOptions:
    n_particles: int = 40
    c1: float = 1.5
    c2: float = 1.5
    w_min: float = 0.4
    w_max: float = 0.9
    w_fixed: float = 0.7298
    v_max: float = 0.1  # velocity clamp, as a fraction of the key range (tuned: 0.1 > 0.25 > 0.5)
    encoding: str = "split"  # "split": giant tour + optimal split; "vehicle": key = vehicle + order
    ls_every: int = 5  # iterations between local-search calls on the best particles
    ls_particles: int = 2
    ruin_rounds: int = 4  # ruin-and-recreate rounds on the best particle per local-search step


class _Codec:
    """Random keys <-> solutions for the two encodings."""

    def __init__(self, ev: Evaluator, encoding: str):
        if encoding not in ("split", "vehicle"):
            raise ValueError(f"unknown encoding {encoding!r}")
        self.ev = ev
        self.split = encoding == "split"
        self.span = 1.0 if self.split else float(ev.m)

    def decode(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.ev.decode_tour_keys(X) if self.split else self.ev.decode_keys(X)

    def encode(self, routes: list[list[int]]) -> np.ndarray:
        if self.split:
            return self.ev.encode_tour_keys(self.ev.from_routes(routes)[0])
        return self.ev.encode_keys(routes)


def particle_swarm(ev: Evaluator, *, adaptive: bool, rng: np.random.Generator, deadline: float,
                   max_iter: int | None, local_search: bool, seeds: list[list[list[int]]],
                   callback: Callable[[np.ndarray, float, int], bool] | None,
                   opts: SwarmOptions) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray], float, int, str]:
    """Run EPSO (``adaptive``) or PSO.

    Returns (best keys, best solution (order, counts), best fitness, iterations, message). The
    personal bests are kept as explicit solutions too, so local-search improvements survive even
    where the decoder would have split the tour differently.
    """
    codec = _Codec(ev, opts.encoding)
    n, P = ev.n, opts.n_particles
    span = codec.span
    hi = span * (1 - 1e-9)
    vmax = opts.v_max * span
    X = rng.uniform(0.0, span, size=(P, n))
    for k, routes in enumerate(seeds[:P]):
        X[k] = codec.encode(routes)
    Vel = rng.uniform(-vmax, vmax, size=(P, n)) * 0.5
    order, counts = codec.decode(X)
    for k, routes in enumerate(seeds[:P]):
        order[k], counts[k] = ev.from_routes(routes)
    f = ev.evaluate(order, counts).fitness
    pbest, pbest_f = X.copy(), f.copy()
    pb_order, pb_counts = order.copy(), counts.copy()
    ls = LocalSearch(ev) if local_search else None
    ls_done = np.zeros(P, dtype=bool)
    it = 0
    while (message := limit_reached(it, max_iter, deadline)) is None:
        it += 1
        g = int(np.argmin(pbest_f))
        w = adaptive_inertia(f, opts.w_min, opts.w_max) if adaptive else np.full(P, opts.w_fixed)
        r1 = rng.random((P, n))
        r2 = rng.random((P, n))
        Vel = w[:, None] * Vel + opts.c1 * r1 * (pbest - X) + opts.c2 * r2 * (pbest[g][None] - X)
        np.clip(Vel, -vmax, vmax, out=Vel)
        X = X + Vel
        # Reflect at the walls so particles do not pile up there.
        X = np.where(X < 0, -X, X)
        X = np.where(X > hi, 2 * hi - X, X)
        np.clip(X, 0.0, hi, out=X)
        order, counts = codec.decode(X)
        f = ev.evaluate(order, counts).fitness
        better = f < pbest_f
        pbest[better] = X[better]
        pbest_f[better] = f[better]
        pb_order[better] = order[better]
        pb_counts[better] = counts[better]
        ls_done[better] = False
        if ls is not None and (it - 1) % opts.ls_every == 0 and n > 1:
            for k in np.argsort(pbest_f)[:opts.ls_particles]:
                if ls_done[k]:
                    continue
                routes, fl = ls.run(ev.to_routes(pb_order[k], pb_counts[k]), deadline)
                ls_done[k] = True
                if fl < pbest_f[k]:
                    pbest[k] = codec.encode(routes)
                    pbest_f[k] = fl
                    pb_order[k], pb_counts[k] = ev.from_routes(routes)
                    X[k] = pbest[k]
            if opts.ruin_rounds:
                g = int(np.argmin(pbest_f))
                routes, fl = ls.ruin_recreate(ev.to_routes(pb_order[g], pb_counts[g]), float(pbest_f[g]),
                                              rng, deadline, opts.ruin_rounds)
                if fl < pbest_f[g]:
                    pbest[g] = codec.encode(routes)
                    pbest_f[g] = fl
                    pb_order[g], pb_counts[g] = ev.from_routes(routes)
        if callback is not None:
            g = int(np.argmin(pbest_f))
            if callback(pbest[g].copy(), float(pbest_f[g]), it):
                message = "stopped by callback"
                break
    g = int(np.argmin(pbest_f))
    return pbest[g].copy(), (pb_order[g].copy(), pb_counts[g].copy()), float(pbest_f[g]), it, message
