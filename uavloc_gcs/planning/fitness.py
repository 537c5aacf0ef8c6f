"""The one fitness all optimizers share: makespan with edge access and an energy penalty,
evaluated for a whole population at once.

A solution is a giant ordering of the targets grouped by vehicle (``order``, ``(P, n)`` target
indices) and the number of targets per vehicle (``counts``, ``(P, m)``, summing to ``n``): the
route of vehicle ``v`` is the next ``counts[v]`` targets of ``order``. EPSO/PSO random keys and
the GA's two-part chromosome both decode to this. For evaluation each solution becomes one
sequence of ``n + 2m`` slots ``[start_1, targets..., home_1, start_2, ...]``; starts and homes
are disks of radius 0, so one coordinate-descent sweep over the sequence handles everything.

Vehicles with spare packs (issue 38) fly their routes in sorties: ``planning/sorties.py`` decides
the trips home and the swaps and adds their slots; without spare packs nothing here changes.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from . import sorties as _sorties
from .access import _norm, best_point_between, best_point_in_intersection
from .problem import Plan, Route, RoutingProblem

# Penalty [s of makespan per s of flight beyond a vehicle's energy]: makes any energy overrun cost
# far more than it could save.
ENERGY_PENALTY = 100.0
SEARCH_SWEEPS = 2
SEARCH_NEWTON = 2
FINAL_NEWTON = 20
SMOOTHING_M = (10.0, 1.0, 0.1, 0.01, 0.001)
SMOOTH_SWEEPS = 100


@dataclass
class Layout:
    seq: np.ndarray  # (P, L) node index per slot
    start_slot: np.ndarray  # (P, m)
    home_slot: np.ndarray  # (P, m)
    route_start: np.ndarray  # (P, L) slot of the start of this slot's route
    par_p: tuple[np.ndarray, np.ndarray]  # flat (particle, slot) of target slots, odd then even
    par_j: tuple[np.ndarray, np.ndarray]


@dataclass
class Evaluation:
    fitness: np.ndarray  # (P,) makespan [s] + penalty
    makespan_s: np.ndarray  # (P,)
    lengths_m: np.ndarray  # (P, m)
    feasible: np.ndarray  # (P,) bool
    points_xy_m: np.ndarray  # (P, L, 2)
    layout: Layout


class Evaluator:
    """Precomputed arrays of one problem; ``evaluate`` scores a population."""

    def __init__(self, problem: RoutingProblem):
        self.problem = problem
        self.n = len(problem.targets)
        self.m = len(problem.vehicles)
        self.speed = float(problem.speed_m_s)
        self.node_xy = np.concatenate([problem.centres_xy_m, problem.starts_xy_m, problem.homes_xy_m])
        self.node_r = np.concatenate([problem.radii_m, np.zeros(2 * self.m)])
        self.node_vel = np.concatenate([problem.velocities_m_s, np.zeros((2 * self.m, 2))])
        self.moving = bool(np.any(self.node_vel != 0))
        self.max_len = problem.max_length_m
        # services (orbit looks): seconds, and as metres of makespan (s * V) and of energy (J / J-per-m)
        zeros = np.zeros(2 * self.m)
        self.node_svc_s = np.concatenate([problem.service_s, zeros]) if self.n else zeros
        self.node_svc_m = self.node_svc_s * self.speed
        self.node_svc_e_m = (np.concatenate([problem.service_energy_j, zeros]) if self.n else zeros) \
            / problem.energy_per_m_j
        self.has_service = bool(np.any(self.node_svc_s > 0) or np.any(self.node_svc_e_m > 0))
        self.total_len = self.max_len  # with spare packs: the first pack and every spare one
        self.sorties = problem.has_sorties
        if self.sorties:
            _sorties.extend_nodes(self)
        self.nfev = 0

    # --- encodings ------------------------------------------------------------------------------
    def decode_keys(self, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Random keys in [0, m): integer part = vehicle, order within a vehicle by key."""
        keys = np.atleast_2d(keys)
        veh = np.clip(np.floor(keys).astype(int), 0, self.m - 1)
        order = np.argsort(veh * 2.0 + (keys - veh), axis=1, kind="stable")
        counts = np.stack([np.count_nonzero(veh == v, axis=1) for v in range(self.m)], axis=1)
        return order, counts

    def split(self, order: np.ndarray) -> np.ndarray:
        """Counts (P, m) of the best min-max split of giant tours ``order`` (P, n) into m
        consecutive routes (route v to vehicle v), by dynamic programming over the split points.

        Route lengths here are estimates: centre-to-centre lengths minus each visited disk's radius
        (edge access saves between 0 and 2 r per disk); energy limits add a large penalty.
        """
        order = np.atleast_2d(order)
        P, n, m = order.shape[0], self.n, self.m
        pos = self.node_xy[order]  # (P, n, 2)
        rad = self.node_r[order]
        step = _norm(np.diff(pos, axis=1))  # (P, n-1)
        D = np.concatenate([np.zeros((P, 1)), np.cumsum(step, axis=1)], axis=1)  # (P, n)
        R = np.concatenate([np.zeros((P, 1)), np.cumsum(rad, axis=1)], axis=1)  # (P, n+1)
        # services count as metres of makespan (a chunk's is SC_j - SC_i)
        R = R - np.concatenate([np.zeros((P, 1)), np.cumsum(self.node_svc_m[order], axis=1)], axis=1)
        i = np.arange(n + 1)
        empty = i[:, None] == i[None, :]  # chunk [i, j) with i == j
        invalid = i[:, None] > i[None, :]
        ii = np.minimum(i, n - 1)
        jj = np.maximum(i - 1, 0)
        f_prev = None
        args = []
        for v in range(m):
            s_xy = self.node_xy[n + v]
            h_xy = self.node_xy[n + m + v]
            # A non-empty chunk's estimate separates: L(i, j) = X[i] + Y[j] with
            # X = |start - e_i| - D_i + R_i and Y = D_{j-1} + |e_{j-1} - home| - R_j.
            X = _norm(pos[:, ii] - s_xy) - D[:, ii] + R
            Y = D[:, jj] + _norm(pos[:, jj] - h_xy) - R
            L = X[:, :, None] + Y[:, None, :]
            L[:, empty] = float(_norm(s_xy - h_xy))
            if self.sorties and self.spares[v] > 0:  # sorties: a swap (and a trip home) per pack beyond the first
                more = np.ceil(np.maximum(L - self.max_len[v], 0.0) / self.pack_len[v])
                L = (L + np.minimum(more, self.spares[v]) * (self.swap_s * self.speed + self.sortie_detour_m[v])
                     + ENERGY_PENALTY * np.maximum(L - self.total_len[v], 0.0))
            elif self.max_len[v] < np.inf:
                L = L + ENERGY_PENALTY * np.maximum(L - self.max_len[v], 0.0)
            if f_prev is None:
                f_v = L[:, 0, :]
                args.append(np.zeros((P, n + 1), dtype=int))
            else:
                M = np.maximum(f_prev[:, :, None], L)
                M[:, invalid] = np.inf
                a = np.argmin(M, axis=1)
                f_v = np.take_along_axis(M, a[:, None, :], axis=1)[:, 0, :]
                args.append(a)
            f_prev = f_v
        counts = np.zeros((P, m), dtype=int)
        j = np.full(P, n)
        for v in range(m - 1, 0, -1):
            start = args[v][np.arange(P), j]
            counts[:, v] = j - start
            j = start
        counts[:, 0] = j
        return counts

    def decode_tour_keys(self, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Random keys in [0, 1) read as a giant tour (argsort), then the optimal split."""
        keys = np.atleast_2d(keys)
        order = np.argsort(keys, axis=1, kind="stable")
        return order, self.split(order)

    @staticmethod
    def encode_tour_keys(order: np.ndarray) -> np.ndarray:
        """Keys in [0, 1) whose argsort is ``order``."""
        x = np.empty(len(order))
        x[np.asarray(order, dtype=int)] = (np.arange(len(order)) + 0.5) / len(order)
        return x

    def encode_keys(self, routes: list[list[int]]) -> np.ndarray:
        """Random keys (n,) reproducing ``routes`` (lists of target indices per vehicle)."""
        x = np.zeros(self.n)
        for v, route in enumerate(routes):
            k = len(route)
            for rank, i in enumerate(route):
                x[i] = v + (rank + 0.5) / k
        return x

    @staticmethod
    def to_routes(order: np.ndarray, counts: np.ndarray) -> list[list[int]]:
        bounds = np.concatenate([[0], np.cumsum(counts)])
        return [list(map(int, order[bounds[v]:bounds[v + 1]])) for v in range(len(counts))]

    @staticmethod
    def from_routes(routes: list[list[int]]) -> tuple[np.ndarray, np.ndarray]:
        order = np.array([i for r in routes for i in r], dtype=int)
        return order, np.array([len(r) for r in routes], dtype=int)

    # --- evaluation -----------------------------------------------------------------------------
    def layout(self, order: np.ndarray, counts: np.ndarray) -> Layout:
        order = np.atleast_2d(order)
        counts = np.atleast_2d(counts)
        P, n, m = order.shape[0], self.n, self.m
        L = n + 2 * m
        cum = np.cumsum(counts, axis=1)
        excl = cum - counts
        vs = np.arange(m)
        start_slot = excl + 2 * vs
        home_slot = cum + 2 * vs + 1
        rows = np.arange(P)[:, None]
        seq = np.empty((P, L), dtype=int)
        route_start = np.empty((P, L), dtype=int)
        if n:
            pos = np.arange(n)
            veh = (pos[None, :, None] >= cum[:, None, :]).sum(-1)  # (P, n)
            tslot = pos[None, :] + 2 * veh + 1
            seq[rows, tslot] = order
            route_start[rows, tslot] = np.take_along_axis(start_slot, veh, axis=1)
        seq[rows, start_slot] = n + vs
        seq[rows, home_slot] = n + m + vs
        route_start[rows, start_slot] = start_slot
        route_start[rows, home_slot] = start_slot
        is_target = seq < n
        par_p, par_j = [], []
        for parity in (1, 0):
            mask = is_target & ((np.arange(L) % 2) == parity)[None, :]
            p, j = np.nonzero(mask)
            par_p.append(p)
            par_j.append(j)
        return Layout(seq, start_slot, home_slot, route_start, tuple(par_p), tuple(par_j))

    def _centres(self, lay: Layout, Q: np.ndarray) -> np.ndarray:
        C = self.node_xy[lay.seq]
        if self.moving:
            t = self._times_s(lay, Q)
            C = C + self.node_vel[lay.seq] * t[..., None]
        return C

    def _times_s(self, lay: Layout, Q: np.ndarray) -> np.ndarray:
        """Time [s] from the route start to the arrival at each slot (flight plus the services of
        the earlier targets of the route)."""
        seg = _norm(np.diff(Q, axis=1))
        cum = np.concatenate([np.zeros((Q.shape[0], 1)), np.cumsum(seg, axis=1)], axis=1)
        t = (cum - np.take_along_axis(cum, lay.route_start, axis=1)) / self.speed
        if self.has_service:
            svc = self.node_svc_s[lay.seq]
            cs = np.cumsum(svc, axis=1) - svc  # services before each slot
            t = t + cs - np.take_along_axis(cs, lay.route_start, axis=1)
        return t

    def _route_services(self, lay: Layout, per_node: np.ndarray) -> np.ndarray:
        """Sum over each route's targets of ``per_node`` (P, m)."""
        cs = np.concatenate([np.zeros((lay.seq.shape[0], 1)), np.cumsum(per_node[lay.seq], axis=1)], axis=1)
        return np.take_along_axis(cs, lay.home_slot, 1) - np.take_along_axis(cs, lay.start_slot, 1)

    def access_points(self, lay: Layout, sweeps: int, newton: int, Q: np.ndarray | None = None,
                      tol_m: float = 0.0, eps_m: float = 0.0,
                      deadline: float | None = None) -> np.ndarray:
        """Coordinate descent on the access points (P, L, 2); ``tol_m`` > 0 stops early, so does
        ``deadline`` (perf_counter); ``eps_m`` > 0 descends on the smoothed lengths
        sqrt(d^2 + eps^2)."""
        R = self.node_r[lay.seq]
        if Q is None:
            Q = self.node_xy[lay.seq].copy()
        for _ in range(sweeps):
            C = self._centres(lay, Q)
            moved = 0.0
            for p, j in zip(lay.par_p, lay.par_j):
                if len(p) == 0:
                    continue
                a, b, old = Q[p, j - 1], Q[p, j + 1], Q[p, j]
                c, r = C[p, j], R[p, j]
                q, cost = best_point_between(a, b, c, r, q_init=old, newton_steps=newton,
                                             eps_m=eps_m)
                old_cost = _norm(old - a) + _norm(b - old)
                old_ok = _norm(old - c) <= r * (1 + 1e-12) + 1e-9
                keep = old_ok & (old_cost <= cost) & (eps_m == 0)
                new = np.where(keep[:, None], old, q)
                if tol_m:
                    moved = max(moved, float(np.max(_norm(new - old))))
                Q[p, j] = new
            if tol_m and moved < tol_m:
                break
            if deadline is not None and time.perf_counter() > deadline:
                break
        return Q

    def evaluate(self, order: np.ndarray, counts: np.ndarray, sweeps: int = SEARCH_SWEEPS,
                 newton: int = SEARCH_NEWTON) -> Evaluation:
        order = np.atleast_2d(order)
        counts = np.atleast_2d(counts)
        if self.sorties:
            return self._evaluate_sorties(order, counts, sweeps, newton)
        lay = self.layout(order, counts)
        Q = self.access_points(lay, sweeps, newton)
        self.nfev += order.shape[0]
        return self._score(lay, Q)

    def _evaluate_sorties(self, order, counts, sweeps: int, newton: int, Q0=None, lay0=None) -> Evaluation:
        """Reloads decided on the points of one sweep without them (or ``Q0`` in ``lay0``), then the
        sweeps and the score with them (planning/sorties.py)."""
        if lay0 is None:
            lay0 = self.layout(order, counts)
            Q0 = self.access_points(lay0, 1, newton)
        mask = _sorties.reload_mask(self, order, counts, Q0)
        lay = _sorties.layout(self, order, counts, mask)
        Q = self.access_points(lay, sweeps, newton, Q=_sorties.initial_points(self, lay, lay0, Q0))
        if self.moving:  # the swaps delay the later looks, and moving disks move meanwhile: decide again
            Q0 = _sorties.plain_points(self, lay0, lay, Q)
            mask = _sorties.reload_mask(self, order, counts, Q0)
            lay = _sorties.layout(self, order, counts, mask)
            Q = self.access_points(lay, sweeps, newton, Q=_sorties.initial_points(self, lay, lay0, Q0))
        self.nfev += order.shape[0]
        return self._score(lay, Q)

    def evaluate_routes(self, routes: list[list[int]], points: np.ndarray | None = None,
                        sweeps: int = 12, newton: int = 4) -> tuple[Evaluation, np.ndarray]:
        """One solution given as routes (target indices per vehicle), its access points warm-started
        from ``points`` (n, 2) when given: (evaluation, its centres (P=1, L, 2))."""
        order, counts = self.from_routes(routes)
        order, counts = order[None, :], counts[None, :]
        lay0 = self.layout(order, counts)
        Q0 = self.node_xy[lay0.seq].copy()
        if points is not None:
            tmask = lay0.seq[0] < self.n
            Q0[0, tmask] = points[lay0.seq[0, tmask]]
        if not self.sorties:
            Q = self.access_points(lay0, sweeps, newton, Q=Q0)
            self.nfev += 1
            ev = self._score(lay0, Q)
        else:
            Q0 = self.access_points(lay0, 1 if points is None else 0, newton, Q=Q0)
            ev = self._evaluate_sorties(order, counts, sweeps, newton, Q0=Q0, lay0=lay0)
        return ev, self._centres(ev.layout, ev.points_xy_m)

    def _score(self, lay: Layout, Q: np.ndarray) -> Evaluation:
        if self.sorties:
            lengths, makespan, excess = _sorties.score(self, lay, Q)
            fitness = makespan + ENERGY_PENALTY * excess
            fitness = np.where(np.isfinite(fitness), fitness, np.inf)
            return Evaluation(fitness, makespan, lengths, excess <= 1e-9, Q, lay)
        seg = _norm(np.diff(Q, axis=1))
        cum = np.concatenate([np.zeros((Q.shape[0], 1)), np.cumsum(seg, axis=1)], axis=1)
        lengths = np.take_along_axis(cum, lay.home_slot, 1) - np.take_along_axis(cum, lay.start_slot, 1)
        energy_len = lengths
        if self.has_service:  # lengths become metres of makespan; the energy gets its own metres
            energy_len = lengths + self._route_services(lay, self.node_svc_e_m)
            lengths = lengths + self._route_services(lay, self.node_svc_m)
        makespan = lengths.max(axis=1) / self.speed
        excess = np.maximum(energy_len - self.max_len[None, :], 0.0).sum(axis=1) / self.speed
        fitness = makespan + ENERGY_PENALTY * excess
        if not np.all(np.isfinite(fitness)):  # never let a numerical accident look good
            fitness = np.where(np.isfinite(fitness), fitness, np.inf)
        return Evaluation(fitness, makespan, lengths, excess <= 1e-9, Q, lay)

    def refine(self, order: np.ndarray, counts: np.ndarray, max_sweeps: int = 300,
               tol_m: float = 1e-7, points: np.ndarray | None = None,
               deadline: float | None = None) -> Evaluation:
        """Converged access points of one or more solutions (used for final plans).

        ``points`` (n, 2) warm-starts the targets' access points. Past ``deadline``
        (perf_counter) the smoothing passes below are skipped (the result stays valid, it may be
        a little longer where disks overlap).
        """
        order = np.atleast_2d(order)
        counts = np.atleast_2d(counts)
        lay = self.layout(order, counts)
        Q = self.node_xy[lay.seq].copy()
        if points is not None:
            for p in range(Q.shape[0]):
                tm = lay.seq[p] < self.n
                Q[p, tm] = points[lay.seq[p, tm]]
        if self.sorties:  # the reloads, decided on the converged points of the routes without them
            lay, Q = self._final_reloads(order, counts, lay, Q, max_sweeps, deadline)
        Q = self.access_points(lay, max_sweeps, FINAL_NEWTON, Q=Q, tol_m=1e-4, deadline=deadline)
        # Coordinate descent can stall where consecutive access points coincide (the length is
        # not differentiable there, typically at a crossing of two overlapping circles).
        # Continuation on smoothed lengths, whose block minimizers are unique and differentiable,
        # pulls such points apart; the last pass is unsmoothed and only ever shortens the route.
        best = Q.copy()
        best_len = self._score(lay, Q).lengths_m.sum(axis=1)
        for eps in SMOOTHING_M if self._has_coincident(lay, Q) else ():
            if deadline is not None and time.perf_counter() > deadline:
                break
            Q = self.access_points(lay, SMOOTH_SWEEPS, FINAL_NEWTON, Q=Q, tol_m=0.01 * eps,
                                   eps_m=eps, deadline=deadline)
        Q = self.access_points(lay, max_sweeps, FINAL_NEWTON, Q=Q, tol_m=tol_m, deadline=deadline)
        for _ in range(5):
            if not self._merge_runs(lay, Q):
                break
            Q = self.access_points(lay, max_sweeps, FINAL_NEWTON, Q=Q, tol_m=tol_m,
                                   deadline=deadline)
        new = self._score(lay, Q)
        worse = new.lengths_m.sum(axis=1) > best_len
        if self.sorties:  # nor may the smoothing leave a sortie beyond its pack
            worse |= ~new.feasible & self._score(lay, best).feasible
        Q[worse] = best[worse]
        if self.moving:
            self._meet_moving(lay, Q)
        self.nfev += order.shape[0]
        return self._score(lay, Q)

    def _final_reloads(self, order, counts, lay0: Layout, Q0: np.ndarray, max_sweeps: int,
                       deadline: float | None, rounds: int = 3) -> tuple[Layout, np.ndarray]:
        """The reload layout of a final plan and its converged points: the reloads decided on the
        converged points without them, then again on the points with them while a sortie is over
        its pack (moving people: the swaps delay the later looks) -- at most ``rounds`` times."""
        Q0 = self.access_points(lay0, max_sweeps, FINAL_NEWTON, Q=Q0, tol_m=1e-4, deadline=deadline)
        plain = Q0
        # moving people: a swap delays the later looks and the disks move meanwhile, by up to the
        # people's speed over the vehicle's per metre of delay; the last rounds plan that much short
        slacks = [0.0] * rounds + ([self.people_speed_ratio] * 2 if self.moving else [])
        first = None
        for k, slack in enumerate(slacks):
            if k == rounds:
                Q0 = plain
            lay = _sorties.layout(self, order, counts, _sorties.reload_mask(self, order, counts, Q0, slack))
            Q = _sorties.initial_points(self, lay, lay0, Q0)
            Q = self.access_points(lay, max_sweeps, FINAL_NEWTON, Q=Q, tol_m=1e-4, deadline=deadline)
            if self.moving:
                self._meet_moving(lay, Q)
            if np.all(self._score(lay, Q).feasible):
                return lay, Q
            first = first or (lay, Q)
            Q0 = _sorties.plain_points(self, lay0, lay, Q)
        return first

    def _meet_moving(self, lay: Layout, Q: np.ndarray, passes: int = 20) -> None:
        """Make every access point lie in its disk at the time the vehicle gets there.

        Projects each point onto its disk at its current access time, then recomputes the times.
        A point moved by dq shifts later times by at most dq / V and their centres by
        |v| dq / V, so the violation shrinks by about |v| / V per pass."""
        R = self.node_r[lay.seq]
        for _ in range(passes):
            C = self._centres(lay, Q)
            off = Q - C
            d = _norm(off)
            over = d > R
            if not np.any(d - R > 1e-10):
                break
            scale = np.where(over, R / np.where(d > 0, d, 1.0), 1.0)
            Q[:] = C + off * scale[..., None]

    def _has_coincident(self, lay: Layout, Q: np.ndarray, tol_m: float = 0.01) -> bool:
        """Whether two consecutive target access points (nearly) coincide somewhere."""
        is_t = lay.seq < self.n
        both = is_t[:, :-1] & is_t[:, 1:]
        return bool(np.any(both & (_norm(np.diff(Q, axis=1)) < tol_m)))

    def _merge_runs(self, lay: Layout, Q: np.ndarray, tol_m: float = 1e-6) -> bool:
        """Move each run of coinciding consecutive access points jointly (see
        ``best_point_in_intersection``); True if some run moved."""
        C = self._centres(lay, Q)
        R = self.node_r[lay.seq]
        is_t = lay.seq < self.n
        changed = False
        for p in range(Q.shape[0]):
            same = (_norm(np.diff(Q[p], axis=0)) < tol_m) & is_t[p, :-1] & is_t[p, 1:]
            j = 0
            L = Q.shape[1]
            while j < L - 1:
                if not same[j]:
                    j += 1
                    continue
                e = j
                while e < L - 1 and same[e]:
                    e += 1
                # Slots j..e coincide.
                a, b = Q[p, j - 1], Q[p, e + 1]
                cur = float(_norm(Q[p, j] - a) + _norm(b - Q[p, e]))
                res = best_point_in_intersection(a, b, C[p, j:e + 1], R[p, j:e + 1])
                if res is not None and res[1] < cur - 1e-9:
                    Q[p, j:e + 1] = res[0]
                    changed = True
                else:
                    changed |= self._split_run(Q[p], C[p], R[p], j, e, cur)
                j = e + 1
        return changed

    @staticmethod
    def _split_run(q: np.ndarray, c: np.ndarray, r: np.ndarray, j: int, e: int, cur: float) -> bool:
        """Try pulling a stuck run j..e apart: a greedy forward pass towards the next centres,
        then coordinate descent on the run alone; keep it only if the run gets shorter."""
        trial = q.copy()
        for t in range(j, e + 1):
            nxt = c[t + 1] if t < e else trial[e + 1]
            trial[t], _ = best_point_between(trial[t - 1], nxt, c[t], r[t])
        for _ in range(200):
            old = trial[j:e + 1].copy()
            for t in range(j, e + 1):
                trial[t], _ = best_point_between(trial[t - 1], trial[t + 1], c[t], r[t])
            if np.max(_norm(trial[j:e + 1] - old)) < 1e-9:
                break
        new = float(_norm(np.diff(trial[j - 1:e + 2], axis=0)).sum())
        if new < cur - 1e-9:
            q[j:e + 1] = trial[j:e + 1]
            return True
        return False

    def plan(self, order: np.ndarray, counts: np.ndarray, lower_bound_s: float,
             points: np.ndarray | None = None, deadline: float | None = None) -> Plan:
        """The converged plan of one solution (``points``, ``deadline``: see ``refine``)."""
        ev = self.refine(order, counts, points=points, deadline=deadline)
        pb = self.problem
        Q = ev.points_xy_m[0]
        lay = ev.layout
        t = self._times_s(lay, Q[None])[0] + pb.t0_s
        e_per_m = pb.energy_per_m_j
        if self.sorties:
            return Plan(tuple(self._sortie_routes(ev, t)), float(ev.makespan_s[0]), float(lower_bound_s))
        routes = []
        for v, veh in enumerate(pb.vehicles):
            s0, h0 = lay.start_slot[0, v], lay.home_slot[0, v]
            idx = lay.seq[0, s0 + 1:h0]
            length = float(ev.lengths_m[0, v])  # metres of makespan: flight + services x V
            svc_s = float(self.node_svc_s[idx].sum()) if len(idx) else 0.0
            svc_e = float(self.node_svc_e_m[idx].sum()) * e_per_m if len(idx) else 0.0
            routes.append(Route(
                vehicle_id=veh.id,
                target_ids=tuple(pb.targets[i].id for i in idx),
                access_points_xy_m=Q[s0 + 1:h0].copy(),
                access_times_s=t[s0 + 1:h0].copy(),
                duration_s=length / self.speed,
                energy_j=(length - svc_s * self.speed) * e_per_m + svc_e,
            ))
        return Plan(tuple(routes), float(ev.makespan_s[0]), float(lower_bound_s))

    def _sortie_routes(self, ev: Evaluation, t: np.ndarray) -> list[Route]:
        """The routes of solution 0 of ``ev`` (laid out with reloads), with their swaps and sorties."""
        pb, n, lay = self.problem, self.n, ev.layout
        Q = ev.points_xy_m[0]
        e_per_m = pb.energy_per_m_j
        energies = _sorties.sortie_energies_m(self, lay, ev.points_xy_m, 0)
        routes = []
        for v, veh in enumerate(pb.vehicles):
            s0, h0 = lay.start_slot[0, v], lay.home_slot[0, v]
            idx = lay.seq[0, s0 + 1:h0]
            slots = np.arange(s0 + 1, h0)[idx < n]
            targets = idx[idx < n]
            reload_before = lay.seq[0, slots - 1] >= n + 2 * self.m  # the slot before is a reload (pads never are)
            length = float(ev.lengths_m[0, v])
            svc_s = float(self.node_svc_s[idx].sum()) if len(idx) else 0.0
            svc_e = float(self.node_svc_e_m[idx].sum()) * e_per_m if len(idx) else 0.0
            routes.append(Route(
                vehicle_id=veh.id,
                target_ids=tuple(pb.targets[i].id for i in targets),
                access_points_xy_m=Q[slots].copy(),
                access_times_s=t[slots].copy(),
                duration_s=length / self.speed,
                energy_j=(length - svc_s * self.speed) * e_per_m + svc_e,
                swaps_before=tuple(int(k) for k in np.flatnonzero(reload_before)),
                sortie_energy_j=tuple(e * e_per_m for u, e in energies if u == v),
            ))
        return routes
