"""Local search on one solution (beyond the paper): 2-opt and or-opt inside routes, relocate and
swap of single targets between the longest route and the others, and cheapest insertion (used for
warm starts and the greedy seed).

Move values are computed with the current access points held fixed, and with the best point on
the moved target's disk between its new neighbours. For static disks that is an upper bound on
the length after the access points are re-optimized (the old points stay feasible), so an
improving move found here is a real improvement. After each round the access points are
re-optimized by the shared evaluator and the round is kept only if the makespan went down.

With spare packs (issue 38) the moves are filtered by a route's energy over all its packs
(``Evaluator.total_len``) and judged by the shared fitness, which places the trips home and the
swaps (planning/sorties.py); the move values do not count the swaps, so they only propose.
"""

from __future__ import annotations

import time

import numpy as np

from .access import _norm, best_point_between
from .fitness import Evaluator

_EPS = 1e-9


def _dmat(x: np.ndarray) -> np.ndarray:
    return np.sqrt(((x[:, None, :] - x[None, :, :]) ** 2).sum(-1))


def two_opt(x: np.ndarray, route: list[int], max_rounds: int = 200) -> tuple[list[int], np.ndarray]:
    """Improve ``route`` whose points (with start/home at both ends) are ``x`` ((k+2, 2))."""
    k = len(route)
    if k < 2:
        return route, x
    route = list(route)
    x = x.copy()
    for _ in range(max_rounds):
        d = _dmat(x)
        i, j = np.triu_indices(k, 1)
        i = i + 1
        j = j + 1
        delta = d[i - 1, j] + d[i, j + 1] - d[i - 1, i] - d[j, j + 1]
        b = int(np.argmin(delta))
        if delta[b] >= -_EPS:
            break
        a, c = i[b], j[b]
        x[a:c + 1] = x[a:c + 1][::-1]
        route[a - 1:c] = route[a - 1:c][::-1]
    return route, x


def or_opt(x: np.ndarray, route: list[int], max_len: int = 3, max_rounds: int = 100):
    """Move a segment of 1..3 targets (possibly reversed) elsewhere in the same route."""
    route = list(route)
    x = x.copy()
    for _ in range(max_rounds):
        k = len(route)
        d = _dmat(x)
        best = (-_EPS, None)
        for seg in range(1, min(max_len, k - 1) + 1):
            for i in range(1, k - seg + 2):
                e = i + seg - 1  # last slot of the segment
                gain = d[i - 1, i] + d[e, e + 1] - d[i - 1, e + 1]
                # Insertion edges (u, u+1) of the remaining sequence, outside the segment.
                u = np.array([p for p in range(0, k + 1) if p < i - 1 or p > e])
                w = np.where(u == i - 1, e + 1, u + 1)
                ok = (u != i - 1)
                u, w = u[ok], w[ok]
                if len(u) == 0:
                    continue
                fwd = d[u, i] + d[e, w] - d[u, w]
                rev = d[u, e] + d[i, w] - d[u, w]
                cost = np.minimum(fwd, rev) - gain
                b = int(np.argmin(cost))
                if cost[b] < best[0]:
                    best = (cost[b], (i, e, int(u[b]), bool(rev[b] < fwd[b])))
        if best[1] is None:
            break
        i, e, u, rev = best[1]
        seg_r = route[i - 1:e]
        seg_x = x[i:e + 1]
        if rev:
            seg_r, seg_x = seg_r[::-1], seg_x[::-1]
        rest_r = route[:i - 1] + route[e:]
        rest_x = np.concatenate([x[:i], x[e + 1:]])
        pos = u if u < i else u - (e - i + 1)  # insertion after rest slot ``pos``
        route = rest_r[:pos] + list(seg_r) + rest_r[pos:]
        x = np.concatenate([rest_x[:pos + 1], seg_x, rest_x[pos + 1:]])
    return route, x


class LocalSearch:
    """Local search bound to one evaluator (one problem)."""

    segment_moves = True

    def __init__(self, ev: Evaluator):
        self.ev = ev
        self.max_len = ev.total_len if ev.sorties else ev.max_len

    def evaluate(self, routes: list[list[int]], points: np.ndarray | None = None):
        """(fitness, per-target points (n,2), per-target centres (n,2), lengths (m,))."""
        ev = self.ev
        if ev.sorties:  # the shared fitness places the reloads
            sc, C = ev.evaluate_routes(routes, points, sweeps=12 if points is None else 4)
            lay, Q = sc.layout, sc.points_xy_m
            tmask = lay.seq[0] < ev.n
            pts = np.zeros((ev.n, 2))
            cen = np.zeros((ev.n, 2))
            pts[lay.seq[0, tmask]] = Q[0, tmask]
            cen[lay.seq[0, tmask]] = C[0, tmask]
            return float(sc.fitness[0]), pts, cen, sc.lengths_m[0]
        order, counts = ev.from_routes(routes)
        lay = ev.layout(order, counts)
        Q0 = ev.node_xy[lay.seq].copy()
        sweeps = 12
        if points is not None:
            tmask = lay.seq[0] < ev.n
            Q0[0, tmask] = points[lay.seq[0, tmask]]
            sweeps = 4
        Q = ev.access_points(lay, sweeps, 4, Q=Q0)
        ev.nfev += 1
        sc = ev._score(lay, Q)
        C = ev._centres(lay, Q)[0]
        pts = np.zeros((ev.n, 2))
        cen = np.zeros((ev.n, 2))
        tmask = lay.seq[0] < ev.n
        pts[lay.seq[0, tmask]] = Q[0, tmask]
        cen[lay.seq[0, tmask]] = C[tmask]
        return float(sc.fitness[0]), pts, cen, sc.lengths_m[0]

    def _route_x(self, v: int, route: list[int], pts: np.ndarray) -> np.ndarray:
        ev = self.ev
        return np.concatenate([ev.node_xy[ev.n + v][None], pts[route].reshape(-1, 2),
                               ev.node_xy[ev.n + ev.m + v][None]])

    def intra(self, routes, pts):
        new = []
        for v, r in enumerate(routes):
            x = self._route_x(v, r, pts)
            r2, x2 = two_opt(x, r)
            r2, x2 = or_opt(x2, r2)
            new.append(r2)
        return new

    def inter(self, routes, pts, cen, lengths) -> list[list[int]] | None:
        """Best relocate or swap that lowers the longest route without making another as long."""
        ev = self.ev
        rad = ev.node_r
        c = int(np.argmax(lengths))
        Lc = lengths[c]
        rc = routes[c]
        if not rc:
            return None
        xc = self._route_x(c, rc, pts)
        k = len(rc)
        idx = np.arange(1, k + 1)
        rem_gain = (_norm(xc[idx] - xc[idx - 1]) + _norm(xc[idx + 1] - xc[idx])
                    - _norm(xc[idx + 1] - xc[idx - 1]))
        # Edges of every other route: (u, w, route).
        U, W, R, POS = [], [], [], []
        for v, r in enumerate(routes):
            if v == c:
                continue
            x = self._route_x(v, r, pts)
            U.append(x[:-1]); W.append(x[1:]); R.append(np.full(len(r) + 1, v))
            POS.append(np.arange(len(r) + 1))
        if not U:
            return None
        U, W, R, POS = map(np.concatenate, (U, W, R, POS))
        tgt = np.array(rc)
        _, ins = best_point_between(U[None], W[None], cen[tgt][:, None], rad[tgt][:, None],
                                    newton_steps=4)
        svc = ev.node_svc_m  # an orbit look's service moves with its target
        ins = ins - _norm(W - U)[None] + svc[tgt][:, None]
        new_v = lengths[R][None] + ins
        new_c = (Lc - rem_gain - svc[tgt])[:, None]
        ok = new_v <= self.max_len[R][None] * (1 - 1e-12)
        score = np.where(ok, np.maximum(new_v, new_c), np.inf)
        b = np.unravel_index(int(np.argmin(score)), score.shape)
        best_reloc = score[b]
        # Swaps: target at position i of c with target j of route v.
        others = [(v, p, t) for v, r in enumerate(routes) if v != c for p, t in enumerate(r)]
        best_swap = np.inf
        if others:
            ov = np.array([o[0] for o in others])
            op = np.array([o[1] for o in others])
            ot = np.array([o[2] for o in others])
            xs = [self._route_x(v, r, pts) for v, r in enumerate(routes)]
            prev_o = np.array([xs[v][p] for v, p in zip(ov, op)])
            next_o = np.array([xs[v][p + 2] for v, p in zip(ov, op)])
            cur_o = pts[ot]
            base_o = _norm(cur_o - prev_o) + _norm(next_o - cur_o)
            # Put c's target i into the other slot, and the other target into c's slot i.
            _, into_o = best_point_between(prev_o[None], next_o[None], cen[tgt][:, None],
                                           rad[tgt][:, None], newton_steps=4)
            _, into_c = best_point_between(xc[idx - 1][:, None], xc[idx + 1][:, None],
                                           cen[ot][None], rad[ot][None], newton_steps=4)
            base_c = (_norm(xc[idx] - xc[idx - 1]) + _norm(xc[idx + 1] - xc[idx]))[:, None]
            new_c2 = Lc - base_c + into_c + (svc[ot][None] - svc[tgt][:, None])
            new_o2 = lengths[ov][None] - base_o[None] + into_o + (svc[tgt][:, None] - svc[ot][None])
            ok2 = new_o2 <= self.max_len[ov][None] * (1 - 1e-12)
            sc2 = np.where(ok2, np.maximum(new_c2, new_o2), np.inf)
            b2 = np.unravel_index(int(np.argmin(sc2)), sc2.shape)
            best_swap = sc2[b2]
        best_star, star_move = self._two_opt_star(routes, pts, lengths, c)
        best_seg, seg_move = (self._segment_relocate(routes, pts, lengths, c, U, W, R, POS)
                              if self.segment_moves else (np.inf, None))
        best = min(best_reloc, best_swap, best_star, best_seg)
        if best >= Lc - 1e-6:
            return None
        routes = [list(r) for r in routes]
        if best_seg == best:
            i, ln, e, rev = seg_move
            seg = routes[c][i:i + ln]
            del routes[c][i:i + ln]
            routes[R[e]][POS[e]:POS[e]] = seg[::-1] if rev else seg
        elif best_star == best:
            v, i, j = star_move
            tail_c, tail_v = routes[c][i:], routes[v][j:]
            routes[c] = routes[c][:i] + tail_v
            routes[v] = routes[v][:j] + tail_c
        elif best_reloc <= best_swap:
            i, e = b
            t = routes[c].pop(i)
            routes[R[e]].insert(POS[e], t)
        else:
            i, o = b2
            v, p, t = ov[o], op[o], ot[o]
            routes[c][i], routes[v][p] = t, routes[c][i]
        return routes

    def _segment_relocate(self, routes, pts, lengths, c, U, W, R, POS):
        """Best move of 2 or 3 consecutive targets of the longest route ``c`` into an edge
        (U, W) of another route (``R``, insertion position ``POS``), possibly reversed; access
        points held fixed (a conservative estimate)."""
        xc = self._route_x(c, routes[c], pts)
        k = len(routes[c])
        Lc = lengths[c]
        best, move = np.inf, None
        for ln in (2, 3):
            if k < ln:
                continue
            i = np.arange(k - ln + 1)  # first target index; slots i+1 .. i+ln
            first, last = xc[i + 1], xc[i + ln]
            inner = np.array([_norm(np.diff(xc[a + 1:a + ln + 1], axis=0)).sum() for a in i])
            gain = (_norm(first - xc[i]) + inner + _norm(xc[i + ln + 1] - last)
                    - _norm(xc[i + ln + 1] - xc[i]))
            base = _norm(W - U)[None]
            fwd = _norm(first[:, None] - U[None]) + _norm(W[None] - last[:, None]) - base
            rev = _norm(last[:, None] - U[None]) + _norm(W[None] - first[:, None]) - base
            add = np.minimum(fwd, rev) + inner[:, None]
            new_v = lengths[R][None] + add
            new_c = (Lc - gain)[:, None]
            ok = new_v <= self.max_len[R][None] * (1 - 1e-12)
            score = np.where(ok, np.maximum(new_v, new_c), np.inf)
            a, e = np.unravel_index(int(np.argmin(score)), score.shape)
            if score[a, e] < best:
                best, move = float(score[a, e]), (int(a), ln, int(e), bool(rev[a, e] < fwd[a, e]))
        return best, move

    def _two_opt_star(self, routes, pts, lengths, c):
        """Best exchange of route tails between the longest route ``c`` and another one:
        ``c`` keeps its first ``i`` targets then flies route ``v``'s tail after its first ``j``,
        and the other way round (both still end at their own homes)."""
        xc = self._route_x(c, routes[c], pts)
        seg_c = _norm(np.diff(xc, axis=0))
        pre_c = np.concatenate([[0.0], np.cumsum(seg_c)])  # start -> point a
        best, move = np.inf, None
        for v, r in enumerate(routes):
            if v == c:
                continue
            xv = self._route_x(v, r, pts)
            seg_v = _norm(np.diff(xv, axis=0))
            pre_v = np.concatenate([[0.0], np.cumsum(seg_v)])
            # Cut after slot a of c (a = 0..kc) and after slot b of v (b = 0..kv); tails start
            # at slot a+1 / b+1 (the home slot when the tail is empty).
            a = np.arange(len(xc) - 1)[:, None]
            b = np.arange(len(xv) - 1)[None, :]
            # Tail lengths measured to each route's own home; the last leg goes to the new home.
            tail_c = pre_c[-2] - pre_c[a + 1]  # from slot a+1 to the last target of c
            tail_v = pre_v[-2] - pre_v[b + 1]
            last_c = np.where(a + 1 <= len(xc) - 2, 1, 0)
            last_v = np.where(b + 1 <= len(xv) - 2, 1, 0)
            home_c, home_v = xc[-1], xv[-1]
            # New c: start..a, then v's tail from b+1, ending at c's home.
            end_v_tail = np.where(last_v[..., None] == 1, xv[-2], xc[a[:, 0]][:, None, :])
            new_c = (pre_c[a] + _norm(xv[b + 1] - xc[a]) * last_v + tail_v * last_v
                     + _norm(home_c - end_v_tail))
            end_c_tail = np.where(last_c[..., None] == 1, xc[-2][None, None, :], xv[b[0]][None, :, :])
            new_v = (pre_v[b] + _norm(xc[a + 1] - xv[b]) * last_c + tail_c * last_c
                     + _norm(home_v - end_c_tail))
            ok = (new_c <= self.max_len[c]) & (new_v <= self.max_len[v])
            ok &= ~((a == len(xc) - 2) & (b == len(xv) - 2))  # both tails empty: no move
            score = np.where(ok, np.maximum(new_c, new_v), np.inf)
            k = np.unravel_index(int(np.argmin(score)), score.shape)
            if score[k] < best:
                best, move = float(score[k]), (v, int(k[0]), int(k[1]))
        return best, move

    def _with_swaps(self, length_m: np.ndarray, veh: np.ndarray) -> np.ndarray:
        """Route lengths [m] with the swaps they need beyond the first pack, each costing its time on
        the ground and a trip home (the giant-tour split's estimate, Evaluator.split)."""
        ev = self.ev
        pack = np.where(ev.pack_len[veh] > 0, ev.pack_len[veh], np.inf)
        swaps = np.minimum(np.ceil(np.maximum(length_m - ev.max_len[veh], 0.0) / pack), ev.spares[veh])
        return length_m + swaps * (ev.swap_s * ev.speed + ev.sortie_detour_m[veh])

    def run(self, routes: list[list[int]], deadline: float, max_rounds: int = 200,
            points: np.ndarray | None = None):
        """Improve ``routes`` until no move helps or ``deadline`` (perf_counter) passes.
        ``points`` (n, 2): access points to warm-start the evaluation from."""
        f, pts, cen, lengths = self.evaluate(routes, points)
        self.last_points = pts
        for _ in range(max_rounds):
            if time.perf_counter() > deadline:
                break
            improved = False
            cand = self.intra(routes, pts)
            if cand != routes:
                fc, pc, cc, lc = self.evaluate(cand, pts)
                if fc < f - 1e-9:
                    routes, f, pts, cen, lengths = cand, fc, pc, cc, lc
                    improved = True
            moved = self.inter(routes, pts, cen, lengths)
            if moved is not None:
                fm, pm, cm, lm = self.evaluate(moved, pts)
                if fm < f - 1e-9:
                    routes, f, pts, cen, lengths = moved, fm, pm, cm, lm
                    improved = True
            if not improved:
                break
        self.last_points = pts
        return routes, f

    def ruin_recreate(self, routes: list[list[int]], f: float, rng: np.random.Generator,
                      deadline: float, rounds: int = 5, threshold: float = 0.02
                      ) -> tuple[list[list[int]], float]:
        """Iterated local search: remove a random person and its nearest neighbours (2 to n/6
        people), reinsert them at their cheapest min-max positions, run the local search.
        Record-to-record travel: the walk continues from any result within ``threshold`` of the
        best makespan seen, and the best is returned."""
        ev = self.ev
        n = ev.n
        if n < 3:
            return routes, f
        cen = ev.node_xy[:n]
        pts = self.evaluate(routes)[1]
        best, best_f = routes, f
        cur, cur_pts = routes, pts
        for _ in range(rounds):
            if time.perf_counter() > deadline:
                break
            k = int(rng.integers(2, max(3, n // 6) + 1))
            if rng.random() < 0.5:
                # A person and its nearest neighbours (they may sit on several routes).
                seed = int(rng.integers(n))
                removed = set(int(i) for i in np.argsort(_norm(cen - cen[seed]))[:k])
            else:
                # A stretch of one route, usually a long one.
                lens = np.array([len(r) for r in cur], dtype=float)
                v = int(rng.choice(len(cur), p=lens / lens.sum()))
                a = int(rng.integers(0, max(1, len(cur[v]) - k + 1)))
                removed = set(cur[v][a:a + k])
            partial = [[t for t in r if t not in removed] for r in cur]
            order = [int(i) for i in rng.permutation(list(removed))]
            cand, fc = self.run(self.insert(partial, order), deadline, points=cur_pts)
            if fc < best_f * (1 + threshold):
                cur, cur_pts = cand, self.last_points
                if fc < best_f - 1e-9:
                    best, best_f = cand, fc
        return best, best_f

    def insert(self, routes: list[list[int]], targets: list[int]) -> list[list[int]]:
        """Cheapest min-max insertion of ``targets`` (in the given order) into ``routes``."""
        ev = self.ev
        routes = [list(r) for r in routes]
        cen = ev.node_xy[:ev.n]
        for t in targets:
            U, W, R, POS, L = [], [], [], [], []
            for v, r in enumerate(routes):
                x = self._route_x(v, r, cen)
                U.append(x[:-1]); W.append(x[1:]); R.append(np.full(len(r) + 1, v))
                POS.append(np.arange(len(r) + 1))
                L.append(_norm(np.diff(x, axis=0)).sum())
            U, W, R, POS = map(np.concatenate, (U, W, R, POS))
            L = np.array(L)
            _, ins = best_point_between(U, W, cen[t], ev.node_r[t], newton_steps=6)
            new = L[R] + ins - _norm(W - U)
            over = np.maximum(new - self.max_len[R], 0.0)
            if ev.sorties:  # a route beyond its first pack pays for its swaps and trips home
                new, L = self._with_swaps(new, R), self._with_swaps(L, np.arange(len(L)))
            # Longest route other than the edge's own: the top route, or the second for the top one.
            top = int(np.argmax(L))
            second = float(np.max(np.delete(L, top))) if len(L) > 1 else 0.0
            others = np.where(R == top, second, L[top])
            score = np.maximum(new, others) + 1e6 * over + 1e-6 * ins
            e = int(np.argmin(score))
            routes[R[e]].insert(POS[e], t)
        return routes
