"""RL-NM: the hovering, grid-discretized tabular Q-learning baseline (SPEC §2.4, science.md §6).

A simplified multi-vehicle version of Ebrahimi, Sharafeddine, Ho, Assi (IEEE TMC 20(4), 2021):

- **Grid.** Coverage cells ``C_x = L_x / ceil(L_x / R)``, ``C_y = L_y / ceil(L_y / R)`` over the
  area's bounding box; each split into ``omega x omega`` RL cells (omega = 2: 22 x 12 cells of
  about 51 x 53 m in the paper scenario). Cells whose centre is outside the area are dropped.
- **One agent per vehicle strip**: the columns are split into contiguous strips with about the same
  number of cells.
- **Measurements** only while hovering ``hover_s`` (5 s) over a cell centre: every phone in range
  gives one annulus from the ML range of all its samples (static-person assumption: the annuli of
  different hovers are intersected as if nobody moved; see :mod:`sim_link.experiments.rl_annuli`).
- **Phase 1** (scan): the staggered coverage waypoints of the paper's Alg. 1 inside the strip,
  nearest-neighbour order, Q updated online. **Training**: episodes on the model built from the
  phase-1 estimates (expected annuli, no flying). **Phase 2**: greedy on Q, Q still updated online.
- **MDP**: state = cell, actions = moves to the 8 neighbouring cells of the strip; reward =
  reduction of the mean annulus-intersection error bound of the not-yet-located people that the
  next cell hears, predicted from *expected* RSSI; Q updated for every action of the current state.
- A vehicle goes home when every person whose estimate lies in its strip has an error bound
  <= the required accuracy, or when its energy (same Zeng model and budget as the other methods)
  only just covers the way home. Its run time counts all Q-learning work (training included).

When no neighbouring cell promises any reduction the agent steps toward the nearest unlocated
person of its strip (the tabular Q alone would wander); this only helps the baseline.
"""

from __future__ import annotations

import heapq
import math
import time
from dataclasses import dataclass

import numpy as np

from uavloc_gcs.scenario import Scenario
from uavloc_gcs.search.targets import inside_area

from . import rl_annuli as an
from .missionsim import MissionResult, PersonResult
from ..world import World

METHOD = "RL-NM"
_MOVES = [(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)]
_MAX_BOUND_M = 300.0  # error bounds are capped here in rewards (a single annulus is huge)


@dataclass(frozen=True)
class RLConfig:
    omega: int = 2
    hover_s: float = 5.0
    alpha: float = 0.1
    gamma: float = 0.9
    epsilon: float = 0.1
    train_episodes: int = 20
    episode_steps: int = 25
    z: float = 3.0  # annulus half width in standard deviations of the log range (99.7 %)
    max_steps: int = 400  # per agent (the energy budget normally ends it first)
    step_penalty_m: float = 1.0  # reward cost of one move+hover (science.md: "minus lambda x energy")


@dataclass(frozen=True)
class Grid:
    x0_m: float
    y0_m: float
    cell_x_m: float
    cell_y_m: float
    nx: int
    ny: int
    coverage_nx: int
    coverage_ny: int
    valid: np.ndarray  # (nx, ny) bool

    def centre(self, i: int, j: int) -> np.ndarray:
        return np.array([self.x0_m + (i + 0.5) * self.cell_x_m, self.y0_m + (j + 0.5) * self.cell_y_m])

    def cell_of(self, xy) -> tuple[int, int]:
        i = int(np.clip((xy[0] - self.x0_m) // self.cell_x_m, 0, self.nx - 1))
        j = int(np.clip((xy[1] - self.y0_m) // self.cell_y_m, 0, self.ny - 1))
        return i, j


def make_grid(sc: Scenario, omega: int) -> Grid:
    area = sc.area_xy_m()
    r = sc.horizontal_range_m
    (x0, y0), (x1, y1) = area.min(axis=0), area.max(axis=0)
    ncx, ncy = max(1, math.ceil((x1 - x0) / r)), max(1, math.ceil((y1 - y0) / r))
    nx, ny = ncx * omega, ncy * omega
    g = Grid(float(x0), float(y0), (x1 - x0) / nx, (y1 - y0) / ny, nx, ny, ncx, ncy, np.zeros((nx, ny), bool))
    valid = np.array([[inside_area(area, g.centre(i, j)) for j in range(ny)] for i in range(nx)])
    return Grid(g.x0_m, g.y0_m, g.cell_x_m, g.cell_y_m, nx, ny, ncx, ncy, valid)


def strips(grid: Grid, m: int) -> list[tuple[int, int]]:
    """Contiguous column ranges [i0, i1) with about equal numbers of valid cells."""
    counts = grid.valid.sum(axis=1)
    cum = np.concatenate([[0], np.cumsum(counts)])
    cuts = [0]
    for k in range(1, m):
        cuts.append(int(np.clip(np.searchsorted(cum, cum[-1] * k / m), cuts[-1] + 1, grid.nx - (m - k))))
    cuts.append(grid.nx)
    return [(cuts[k], cuts[k + 1]) for k in range(m) if cuts[k + 1] > cuts[k]]


def scan_cells(grid: Grid, strip: tuple[int, int], omega: int) -> list[tuple[int, int]]:
    """Alg. 1's staggered coverage waypoints inside the strip, as RL cells, nearest-neighbour order
    from the launch point."""
    cells = set()
    cx, cy = grid.cell_x_m * omega, grid.cell_y_m * omega
    for k in range(grid.coverage_nx):
        x = grid.x0_m + (k + 0.5) * cx
        y = grid.y0_m + (0.5 + (k % 2)) * cy
        while y < grid.y0_m + grid.ny * grid.cell_y_m:
            i, j = grid.cell_of((x, y))
            if strip[0] <= i < strip[1] and grid.valid[i, j]:
                cells.add((i, j))
            y += 2 * cy
    if not cells:
        cells = {(i, j) for i in range(*strip) for j in range(grid.ny) if grid.valid[i, j]}
    order, here, left = [], np.zeros(2), sorted(cells)
    while left:
        k = int(np.argmin([np.hypot(*(grid.centre(*c) - here)) for c in left]))
        order.append(left.pop(k))
        here = grid.centre(*order[-1])
    return order


class _Shared:
    """Measurements and estimates of every emitter, shared by the agents."""

    def __init__(self):
        self.annuli: dict[int, list] = {}
        self.silent: dict[int, list] = {}  # hover points that did not hear a person
        self.used: dict[int, list] = {}
        self.est: dict[int, tuple[np.ndarray, float, float]] = {}  # id -> (xy, bound, t_ref)
        self.fix_t: dict[int, float] = {}
        self.est_runtime_s = 0.0

    def add(self, eid: int, annulus, t_s: float, required_m: float, range_m: float) -> None:
        if annulus is not None:
            self.annuli.setdefault(eid, []).append(annulus)
        t0 = time.perf_counter()
        prev = self.est.get(eid)
        x, bound, used = an.localize(self.annuli[eid], start=None if prev is None else prev[0],
                                     silent_xy_m=self.silent.get(eid), range_m=range_m)
        self.est_runtime_s += time.perf_counter() - t0
        self.est[eid] = (x, bound, max(a.t_s for a in used))
        self.used[eid] = list(used)  # the consistent recent annuli behind the estimate
        if bound > required_m:  # the static model's claim can get worse again: not located (now)
            self.fix_t.pop(eid, None)
        elif eid not in self.fix_t:
            self.fix_t[eid] = t_s


class _Agent:
    def __init__(self, index: int, strip, grid: Grid, sc: Scenario, cfg: RLConfig, rng):
        self.index, self.strip, self.grid, self.sc, self.cfg, self.rng = index, strip, grid, sc, cfg, rng
        self.q = np.zeros((grid.nx, grid.ny, len(_MOVES)))
        self.todo = scan_cells(grid, strip, cfg.omega)
        self.xy = np.zeros(2)
        self.cell: tuple[int, int] | None = None
        self.t_s = 0.0
        self.energy_j = 0.0
        self.home_t_s: float | None = None
        self.trained = False
        self.steps = 0
        self.runtime_s = 0.0

    def actions(self, cell):
        i, j = cell
        out = []
        for k, (di, dj) in enumerate(_MOVES):
            a, b = i + di, j + dj
            if self.strip[0] <= a < self.strip[1] and 0 <= b < self.grid.ny and self.grid.valid[a, b]:
                out.append((k, (a, b)))
        return out


def _expected_annulus(sc: Scenario, cfg: RLConfig, cell_xy, person_xy, t_s):
    h = sc.fleet.altitude_m
    d = math.sqrt(float(np.sum((np.asarray(cell_xy) - person_xy) ** 2)) + h * h)
    n = int(cfg.hover_s / sc.channel.slot_s) * sc.channel.samples_per_slot
    return an.annulus_from_slots(cell_xy, math.log(d), n, s_per_sample=sc.channel.log_range_sigma,
                                 altitude_m=h, z=cfg.z, t_s=t_s)


def _predicted_reward(sc, cfg, cell_xy, annuli: dict, est: dict, pending: list[int]) -> float:
    """Mean reduction of the (capped) error bound of pending people heard from ``cell_xy``."""
    r = sc.horizontal_range_m
    gains = []
    for eid in pending:
        x, bound, _ = est[eid]
        if np.hypot(*(x - cell_xy)) > r:
            continue
        trial = annuli[eid] + [_expected_annulus(sc, cfg, cell_xy, x, math.inf)]
        new = an.error_bound_m(trial, x)
        before = min(bound, _MAX_BOUND_M)
        gains.append(before - min(new, before) if math.isfinite(new) else 0.0)
    return (float(np.mean(gains)) if gains else 0.0) - cfg.step_penalty_m


def _q_update_all(agent: _Agent, cell, annuli, est, pending) -> list[tuple[int, tuple[int, int], float]]:
    """Predicted reward of every action from ``cell``; Q(cell, a) updated for all of them."""
    out = []
    for k, nxt in agent.actions(cell):
        rew = _predicted_reward(agent.sc, agent.cfg, agent.grid.centre(*nxt), annuli, est, pending)
        target = rew + agent.cfg.gamma * float(np.max(agent.q[nxt]))
        agent.q[cell][k] = (1 - agent.cfg.alpha) * agent.q[cell][k] + agent.cfg.alpha * target
        out.append((k, nxt, rew))
    return out


def _train(agent: _Agent, shared: _Shared, pending: list[int]) -> None:
    """Q-learning episodes on the model (expected annuli added along the way, nothing flown)."""
    cfg = agent.cfg
    for _ in range(cfg.train_episodes):
        annuli = {e: list(shared.used[e]) for e in pending}
        cell = agent.cell
        for _ in range(cfg.episode_steps):
            opts = _q_update_all(agent, cell, annuli, shared.est, pending)
            if not opts:
                break
            if agent.rng.random() < cfg.epsilon:
                _, nxt, _ = opts[int(agent.rng.integers(len(opts)))]
            else:
                _, nxt, _ = max(opts, key=lambda o: agent.q[cell][o[0]])
            xy = agent.grid.centre(*nxt)
            for e in pending:
                if np.hypot(*(shared.est[e][0] - xy)) <= agent.sc.horizontal_range_m:
                    annuli[e] = annuli[e][-(an.MAX_ANNULI - 1):] + [
                        _expected_annulus(agent.sc, cfg, xy, shared.est[e][0], math.inf)]
            cell = nxt


def _in_strip(agent: _Agent, xy) -> bool:
    i, _ = agent.grid.cell_of(xy)
    return agent.strip[0] <= i < agent.strip[1]


def _hover(world: World, agent: _Agent, shared: _Shared, required_m: float) -> None:
    sc, cfg = agent.sc, agent.cfg
    slot = sc.channel.slot_s
    t = agent.t_s + np.arange(round(cfg.hover_s / slot)) * slot
    xyz = np.column_stack([np.tile(agent.xy, (len(t), 1)), np.full(len(t), sc.fleet.altitude_m)])
    slots = world.hear_track(agent.index, t, xyz)
    agent.t_s += cfg.hover_s
    agent.energy_j += sc.power_model.hover_energy_j(cfg.hover_s)
    ch = sc.channel
    for eid in slots.emitters():
        s = slots.for_emitter(int(eid))
        # invert the calibrated path loss: ln r = ln d0 + (P0 - rssi) ln10 / (10 eta)
        ln_r = np.log(ch.reference_distance_m) + (ch.reference_power_dbm - s.rssi_dbm) * np.log(10) / (
            10 * ch.path_loss_exponent)
        n = int(np.sum(s.n_samples))
        mean = float(np.sum(ln_r * s.n_samples) / n)
        a = an.annulus_from_slots(agent.xy, mean, n, s_per_sample=ch.log_range_sigma,
                                  altitude_m=sc.fleet.altitude_m, z=cfg.z, t_s=float(t[-1]))
        shared.add(int(eid), a, agent.t_s, required_m, sc.horizontal_range_m)
    heard = {int(e) for e in slots.emitters()}
    for eid, (x, _, _) in list(shared.est.items()):  # expected in range but silent: not there
        if eid not in heard and np.hypot(*(x - agent.xy)) < 0.9 * sc.horizontal_range_m:
            known = shared.silent.setdefault(eid, [])
            if any(np.hypot(*(agent.xy - q)) < 1.0 for q in known):
                continue
            known.append(agent.xy.copy())
            shared.add(eid, None, agent.t_s, required_m, 0.95 * sc.horizontal_range_m)


def _fly_to(agent: _Agent, xy) -> None:
    d = float(np.hypot(*(np.asarray(xy) - agent.xy)))
    v = agent.sc.fleet.speed_m_s
    agent.t_s += d / v
    agent.energy_j += float(agent.sc.power_model.leg_energy_j(d, v))
    agent.xy = np.asarray(xy, dtype=float)


def _step(world: World, agent: _Agent, shared: _Shared, required_m: float) -> None:
    """One decision of one agent: choose a cell (or home), fly, hover, learn."""
    sc, cfg, grid = agent.sc, agent.cfg, agent.grid
    pending = [e for e in shared.est if e not in shared.fix_t]
    mine = [e for e in pending if _in_strip(agent, shared.est[e][0])]
    nxt = None
    if agent.todo:
        nxt = agent.todo.pop(0)
        if agent.cell is not None:
            t0 = time.perf_counter()
            _q_update_all(agent, agent.cell, shared.used, shared.est, pending)
            agent.runtime_s += time.perf_counter() - t0
    elif mine and agent.steps < cfg.max_steps:
        t0 = time.perf_counter()
        if not agent.trained:
            _train(agent, shared, pending)
            agent.trained = True
        opts = _q_update_all(agent, agent.cell, shared.used, shared.est, pending)
        if opts and max(o[2] for o in opts) > 1e-6 - cfg.step_penalty_m:
            # Acting on Q alone oscillated between two cells (stale values: the error landscape
            # changes with every measurement), so the fresh predicted reward leads, Q breaks ties.
            nxt = max(opts, key=lambda o: (round(o[2] * 2) / 2, agent.q[agent.cell][o[0]]))[1]
        elif opts:  # nothing promised nearby: head for the nearest unlocated person of the strip
            goal = min((shared.est[e][0] for e in mine), key=lambda x: np.hypot(*(x - agent.xy)))
            nxt = min(opts, key=lambda o: np.hypot(*(grid.centre(*o[1]) - goal)))[1]
        agent.runtime_s += time.perf_counter() - t0
    elif pending and agent.cell is not None and agent.steps < cfg.max_steps:
        nxt = agent.cell  # strip clear but others still searching: hover and listen
    if nxt is not None:
        target = grid.centre(*nxt)
        v = sc.fleet.speed_m_s
        step_j = float(sc.power_model.leg_energy_j(np.hypot(*(target - agent.xy)), v)) + \
            sc.power_model.hover_energy_j(cfg.hover_s)
        home_j = float(sc.power_model.leg_energy_j(np.hypot(*target), v))
        if agent.energy_j + step_j + home_j > sc.usable_energy_j:
            nxt = None
    if nxt is None:
        _fly_to(agent, np.zeros(2))
        agent.home_t_s = agent.t_s
        return
    _fly_to(agent, grid.centre(*nxt))
    agent.cell = nxt
    agent.steps += 1
    _hover(world, agent, shared, required_m)


def simulate_rl(scenario: Scenario, world: World, *, seed: int = 0, config: RLConfig = RLConfig()) -> MissionResult:
    """Fly one RL-NM mission on ``world``; same result record as the MLE methods."""
    grid = make_grid(scenario, config.omega)
    required = scenario.people.required_accuracy_m
    root = np.random.SeedSequence([seed, 7])
    agents = [_Agent(k + 1, st, grid, scenario, config, np.random.default_rng(s))
              for k, (st, s) in enumerate(zip(strips(grid, scenario.fleet.vehicles),
                                              root.spawn(scenario.fleet.vehicles)))]
    shared = _Shared()
    err_t, err_v = [], []
    queue = [(0.0, a.index) for a in agents]
    heapq.heapify(queue)
    by_index = {a.index: a for a in agents}
    while queue:
        _, k = heapq.heappop(queue)
        agent = by_index[k]
        _step(world, agent, shared, required)
        err_t.append(agent.t_s)
        err_v.append(_max_error(world, shared))
        if agent.home_t_s is None:
            heapq.heappush(queue, (agent.t_s, k))
    order = np.argsort(err_t, kind="stable")
    t_end = max(a.home_t_s for a in agents)
    return MissionResult(
        method=METHOD, people=len(world), seed=seed, completion_time_s=float(t_end),
        scan_time_s=math.nan,
        planner_runtime_s=float(sum(a.runtime_s for a in agents)), estimator_runtime_s=shared.est_runtime_s,
        replans=0, energy_j=tuple(a.energy_j for a in agents), persons=_persons(world, shared),
        error_times_s=np.asarray(err_t)[order], max_error_m=np.asarray(err_v)[order])


def _persons(world: World, shared: _Shared) -> tuple[PersonResult, ...]:
    out = []
    for i, eid in enumerate(world.emitter_ids):
        e = shared.est.get(int(eid))
        if e is None:
            out.append(PersonResult(int(eid), False, False, math.nan, math.nan, math.nan))
            continue
        x, bound, t_ref = e
        truth = world.positions(t_ref)[i]
        fix = shared.fix_t.get(int(eid), math.nan)
        out.append(PersonResult(int(eid), True, int(eid) in shared.fix_t, fix, float(np.hypot(*(x - truth))), bound))
    return tuple(out)


def _max_error(world: World, shared: _Shared) -> float:
    errs = [p.error_m for p in _persons(world, shared)]
    return float(np.max(errs)) if errs and not any(math.isnan(e) for e in errs) else math.nan
