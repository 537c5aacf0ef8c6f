"""Sorties in the shared fitness (issue 38): routes that go home, swap the pack and go on.

A vehicle with spare packs flies its route (its targets in order, as the encodings give it) in
sorties. The reloads are decided when a solution is scored, the way the issue states the rule:
walking the route, when the pack cannot cover the next look *and the way home from it*, the
vehicle goes home first, swaps (``battery_swap_s`` on the ground) and takes the look on a fresh
pack -- as long as it has packs. Every route of every solution of the population is walked at
once, one target position per step (numpy over (particles, vehicles)), on access points from one
sweep over the route without reloads; then the solutions are laid out with their reloads and
scored by the same coordinate descent as single trips.

Layout with reloads: each route ``v`` gets ``R_v = min(spare_packs_v, n)`` extra slots, so the
arrays keep one shape across the population: ``[start, t, t, RELOAD, t, ..., PAD, PAD, home]``.
A reload slot is a radius-0 disk at home whose service is the swap (seconds, no energy); unused
slots are pads at home without service, just before the home slot (zero-length legs). Node ids:
targets ``[0, n)``, starts ``[n, n+m)``, homes ``[n+m, n+2m)``, reloads ``[n+2m, n+3m)``, pads
``[n+3m, n+4m)``.

Score: the makespan counts the trips home and the swaps (services of the reload nodes); the energy
penalty is the overrun of each sortie over its pack (the first over the vehicle's ``energy_j``, the
later ones over ``pack_energy_j``). Moving a target's access point changes only its own two legs,
which belong to one sortie, so the descent after the reloads never makes a sortie longer on static
disks.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .access import _norm

if TYPE_CHECKING:  # pragma: no cover
    from .fitness import Evaluator, Layout


def extend_nodes(ev: "Evaluator") -> None:
    """Add the reload and pad nodes (home positions) to ``ev``'s node arrays."""
    pb = ev.problem
    m = ev.m
    homes = pb.homes_xy_m
    ev.spares = pb.spare_packs
    ev.pack_len = pb.pack_length_m
    ev.total_len = ev.max_len + ev.spares * ev.pack_len
    ev.reload_slots = np.minimum(ev.spares, ev.n)  # R_v
    ev.swap_s = float(pb.battery_swap_s)
    speeds = _norm(pb.velocities_m_s) if ev.n else np.zeros(0)
    ev.people_speed_ratio = float(speeds.max(initial=0.0)) / ev.speed
    ev.node_xy = np.concatenate([ev.node_xy, homes, homes])
    ev.node_r = np.concatenate([ev.node_r, np.zeros(2 * m)])
    ev.node_vel = np.concatenate([ev.node_vel, np.zeros((2 * m, 2))])
    ev.node_svc_s = np.concatenate([ev.node_svc_s, np.full(m, ev.swap_s), np.zeros(m)])
    ev.node_svc_m = ev.node_svc_s * ev.speed
    ev.node_svc_e_m = np.concatenate([ev.node_svc_e_m, np.zeros(2 * m)])
    ev.has_service = bool(np.any(ev.node_svc_s > 0) or np.any(ev.node_svc_e_m > 0))
    # a rough length of one more sortie for the giant-tour split: home -> the targets and back, twice
    # the median distance (only the split's estimate; the scoring is exact)
    d = _norm(pb.centres_xy_m[:, None, :] - homes[None, :, :]) if ev.n else np.zeros((0, m))
    ev.sortie_detour_m = 2.0 * (np.median(d, axis=0) if ev.n else np.zeros(m))


def reload_mask(ev: "Evaluator", order: np.ndarray, counts: np.ndarray, Q0: np.ndarray,
                slack: float = 0.0) -> np.ndarray:
    """(P, n) bool: a reload before the target at each position of ``order`` (see the module
    docstring). ``Q0`` (P, n + 2m, 2): access points in the plain layout (``ev.layout``).
    ``slack``: plan each sortie this share short of its pack."""
    P, n, m = order.shape[0], ev.n, ev.m
    mask = np.zeros((P, n), dtype=bool)
    if n == 0:
        return mask
    counts = np.asarray(counts)
    excl = np.cumsum(counts, axis=1) - counts  # (P, m): first order position of each route
    vs = np.arange(m)[None, :]
    rows = np.arange(P)[:, None]
    homes = ev.node_xy[n + m: n + 2 * m][None, :, :]  # (1, m, 2)
    prev = np.broadcast_to(ev.node_xy[n: n + m][None, :, :], (P, m, 2)).copy()
    used = np.zeros((P, m))  # metres of energy spent in the current sortie
    cap = np.broadcast_to(ev.max_len[None, :], (P, m)).astype(float).copy()
    left = np.broadcast_to(ev.spares[None, :], (P, m)).copy()
    pack = np.broadcast_to(ev.pack_len[None, :], (P, m))
    slack = 1.0 - slack
    for k in range(int(counts.max(initial=0))):
        valid = k < counts
        pos = np.minimum(excl + k, n - 1)
        tgt = order[rows, pos]  # (P, m)
        q = Q0[rows, pos + 2 * vs + 1]  # (P, m, 2): slot of order position i in route v is i + 2v + 1
        svc = ev.node_svc_e_m[tgt]
        leg = _norm(q - prev)
        back = _norm(q - homes)
        over = used + leg + svc + back > cap * slack * (1 + 1e-9)
        swap = valid & over & (left > 0)
        fresh = _norm(homes - q)
        used = np.where(swap, fresh + svc, np.where(valid, used + leg + svc, used))
        cap = np.where(swap, pack, cap)
        left = left - swap
        prev = np.where(valid[..., None], q, prev)
        r, v = np.nonzero(swap)
        mask[r, excl[r, v] + k] = True
    return mask


def layout(ev: "Evaluator", order: np.ndarray, counts: np.ndarray, mask: np.ndarray) -> "Layout":
    """The sequences with the reload slots (see the module docstring); ``mask`` from :func:`reload_mask`."""
    from .fitness import Layout

    order = np.atleast_2d(order)
    counts = np.atleast_2d(counts)
    P, n, m = order.shape[0], ev.n, ev.m
    R = ev.reload_slots
    L = n + 2 * m + int(R.sum())
    size = counts + 2 + R[None, :]
    block_end = np.cumsum(size, axis=1)
    block = block_end - size  # first slot of each route's block
    start_slot = block
    home_slot = block_end - 1
    rows = np.arange(P)[:, None]
    j = np.arange(L)
    veh_of_slot = (j[None, :, None] >= block_end[:, None, :]).sum(-1)  # (P, L)
    seq = n + 3 * m + veh_of_slot  # pads everywhere first
    route_start = np.take_along_axis(start_slot, veh_of_slot, axis=1)
    seq[rows, start_slot] = n + np.arange(m)[None, :]
    seq[rows, home_slot] = n + m + np.arange(m)[None, :]
    if n:
        cum = np.cumsum(counts, axis=1)
        pos = np.arange(n)
        veh = (pos[None, :, None] >= cum[:, None, :]).sum(-1)  # (P, n) route of each order position
        excl = cum - counts
        k = pos[None, :] - np.take_along_axis(excl, veh, axis=1)  # index within its route
        # reloads up to and including each position, counted within its route
        c = np.cumsum(mask, axis=1)
        c_before_route = np.take_along_axis(np.concatenate([np.zeros((P, 1), int), c], axis=1), excl[rows, veh], axis=1)
        within = c - c_before_route
        tslot = np.take_along_axis(block, veh, axis=1) + 1 + k + within
        seq[rows, tslot] = order
        rp, ri = np.nonzero(mask)
        seq[rp, tslot[rp, ri] - 1] = n + 2 * m + veh[rp, ri]
    is_target = seq < n
    par_p, par_j = [], []
    for parity in (1, 0):
        p, jj = np.nonzero(is_target & ((j % 2) == parity)[None, :])
        par_p.append(p)
        par_j.append(jj)
    return Layout(seq, start_slot, home_slot, route_start, tuple(par_p), tuple(par_j))


def initial_points(ev: "Evaluator", lay: "Layout", lay0: "Layout", Q0: np.ndarray) -> np.ndarray:
    """Access points for the reload layout ``lay``: each target's point from ``Q0`` (the plain
    layout ``lay0``), every depot slot at its node."""
    Q = ev.node_xy[lay.seq].copy()
    if ev.n:
        pts = np.zeros((lay.seq.shape[0], ev.n, 2))
        pp, jj = np.nonzero(lay0.seq < ev.n)
        pts[pp, lay0.seq[pp, jj]] = Q0[pp, jj]
        p1, j1 = np.nonzero(lay.seq < ev.n)
        Q[p1, j1] = pts[p1, lay.seq[p1, j1]]
    return Q


def plain_points(ev: "Evaluator", lay0: "Layout", lay: "Layout", Q: np.ndarray) -> np.ndarray:
    """The inverse of :func:`initial_points`: the targets' points of the reload layout ``lay`` put
    in the plain layout ``lay0`` (to decide the reloads again on them)."""
    Q0 = ev.node_xy[lay0.seq].copy()
    if ev.n:
        pts = np.zeros((lay.seq.shape[0], ev.n, 2))
        pp, jj = np.nonzero(lay.seq < ev.n)
        pts[pp, lay.seq[pp, jj]] = Q[pp, jj]
        p0, j0 = np.nonzero(lay0.seq < ev.n)
        Q0[p0, j0] = pts[p0, lay0.seq[p0, j0]]
    return Q0


def score(ev: "Evaluator", lay: "Layout", Q: np.ndarray):
    """(lengths (P, m) in metres of makespan, makespan [s], energy overrun of the sorties [s of flight])."""
    n, m = ev.n, ev.m
    P, L = lay.seq.shape
    seg = _norm(np.diff(Q, axis=1))
    cum = np.concatenate([np.zeros((P, 1)), np.cumsum(seg, axis=1)], axis=1)
    svc_m = np.concatenate([np.zeros((P, 1)), np.cumsum(ev.node_svc_m[lay.seq], axis=1)], axis=1)
    end = np.take_along_axis(cum, lay.home_slot, 1) + np.take_along_axis(svc_m, lay.home_slot + 1, 1)
    begin = np.take_along_axis(cum, lay.start_slot, 1) + np.take_along_axis(svc_m, lay.start_slot + 1, 1)
    lengths = end - begin  # flight + services (orbits, swaps) as metres of makespan
    makespan = lengths.max(axis=1) / ev.speed
    # energy of each sortie: from a start or reload slot to the next depot slot (reload or home)
    seq = lay.seq
    is_start = (seq >= n) & (seq < n + m)
    is_home = (seq >= n + m) & (seq < n + 2 * m)
    is_reload = (seq >= n + 2 * m) & (seq < n + 3 * m)
    depot = is_start | is_home | is_reload
    svc_e = np.cumsum(ev.node_svc_e_m[seq], axis=1)
    energy = cum + svc_e  # energy metres flown and spent up to (and at) each slot
    idx = np.where(depot, np.arange(L)[None, :], L)
    nxt = np.minimum.accumulate(idx[:, ::-1], axis=1)[:, ::-1]  # first depot at or after each slot
    nxt_after = np.concatenate([nxt[:, 1:], np.full((P, 1), L)], axis=1)  # ... strictly after
    opens = is_start | is_reload
    rp, rj = np.nonzero(opens)
    close = nxt_after[rp, rj]
    e_sortie = energy[rp, close] - energy[rp, rj]
    veh = np.where(seq[rp, rj] < n + m, seq[rp, rj] - n, seq[rp, rj] - n - 2 * m)
    cap = np.where(is_start[rp, rj], ev.max_len[veh], ev.pack_len[veh])
    over = np.maximum(e_sortie - cap, 0.0)
    excess = np.zeros(P)
    np.add.at(excess, rp, over)
    return lengths, makespan, excess / ev.speed


def sortie_energies_m(ev: "Evaluator", lay: "Layout", Q: np.ndarray, p: int) -> list[tuple[int, float]]:
    """Solution ``p``'s sorties in flight order: (vehicle, energy metres), one per start or reload."""
    n, m = ev.n, ev.m
    seq = lay.seq[p]
    seg = _norm(np.diff(Q[p], axis=0))
    energy = np.concatenate([[0.0], np.cumsum(seg)]) + np.cumsum(ev.node_svc_e_m[seq])
    out = []
    opens = [j for j, s in enumerate(seq) if n <= s < n + m or n + 2 * m <= s < n + 3 * m]
    for j in opens:
        k = j + 1
        while not (n + m <= seq[k] < n + 3 * m):  # the next home or reload
            k += 1
        v = seq[j] - n if seq[j] < n + m else seq[j] - n - 2 * m
        out.append((int(v), float(energy[k] - energy[j])))
    return out
