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

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .fitness import Evaluator
from .localsearch import LocalSearch


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
    v_max: float = 0.5  # velocity clamp, in keys (a vehicle is 1.0 wide)
    ls_every: int = 5  # iterations between local-search calls on the best particles
    ls_particles: int = 2


def particle_swarm(ev: Evaluator, *, adaptive: bool, rng: np.random.Generator, deadline: float,
                   max_iter: int | None, local_search: bool, seeds: list[list[list[int]]],
                   callback: Callable[[np.ndarray, float, int], bool] | None,
                   opts: SwarmOptions) -> tuple[np.ndarray, float, int, str]:
    """Run EPSO (``adaptive``) or PSO. Returns (best keys, best fitness, iterations, message)."""
    n, m, P = ev.n, ev.m, opts.n_particles
    hi = m - 1e-9
    X = rng.uniform(0.0, m, size=(P, n))
    for k, routes in enumerate(seeds[:P]):
        X[k] = ev.encode_keys(routes)
    Vel = rng.uniform(-opts.v_max, opts.v_max, size=(P, n)) * 0.5
    f = ev.evaluate(*ev.decode_keys(X)).fitness
    pbest, pbest_f = X.copy(), f.copy()
    g = int(np.argmin(f))
    gbest, gbest_f = X[g].copy(), float(f[g])
    ls = LocalSearch(ev) if local_search else None
    it = 0
    message = "time limit reached"
    ls_done = np.zeros(P, dtype=bool)
    while True:
        if max_iter is not None and it >= max_iter:
            message = "iteration limit reached"
            break
        if time.perf_counter() >= deadline:
            break
        it += 1
        w = adaptive_inertia(f, opts.w_min, opts.w_max) if adaptive else np.full(P, opts.w_fixed)
        r1 = rng.random((P, n))
        r2 = rng.random((P, n))
        Vel = w[:, None] * Vel + opts.c1 * r1 * (pbest - X) + opts.c2 * r2 * (gbest[None] - X)
        np.clip(Vel, -opts.v_max, opts.v_max, out=Vel)
        X = X + Vel
        # Reflect at the walls so particles do not pile up on the last vehicle.
        X = np.where(X < 0, -X, X)
        X = np.where(X > hi, 2 * hi - X, X)
        np.clip(X, 0.0, hi, out=X)
        f = ev.evaluate(*ev.decode_keys(X)).fitness
        better = f < pbest_f
        pbest[better] = X[better]
        pbest_f[better] = f[better]
        g = int(np.argmin(pbest_f))
        if pbest_f[g] < gbest_f:
            gbest, gbest_f = pbest[g].copy(), float(pbest_f[g])
        ls_done[better] = False
        if ls is not None and (it - 1) % opts.ls_every == 0 and n > 1:
            for k in np.argsort(pbest_f)[:opts.ls_particles]:
                if ls_done[k]:
                    continue
                routes = ev.to_routes(*(a[0] for a in ev.decode_keys(pbest[k])))
                routes, fl = ls.run(routes, deadline)
                ls_done[k] = True
                if fl < pbest_f[k]:
                    pbest[k] = ev.encode_keys(routes)
                    pbest_f[k] = fl
                    X[k] = pbest[k]
            g = int(np.argmin(pbest_f))
            if pbest_f[g] < gbest_f:
                gbest, gbest_f = pbest[g].copy(), float(pbest_f[g])
        if callback is not None and callback(gbest.copy(), gbest_f, it):
            message = "stopped by callback"
            break
    return gbest, gbest_f, it, message
