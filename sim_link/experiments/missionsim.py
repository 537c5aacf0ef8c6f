"""Fast in-process mission simulation (no sockets): scan -> localize -> plan -> fly -> replan -> home.

The same :class:`sim_link.world.World` (people, channel) and the same
:class:`uavloc_gcs.search.SearchPolicy` (estimator + planner) as the daemon drive it; only the
vehicles are idealized: each flies its current path as a polyline at the constant cruise speed
(pass-through waypoints, turns not modelled), hears one slot every ``channel.slot_s`` seconds
(``World.hear_track``), and hovers when it has nothing to do. Energy is the scenario's power model
(flight at cruise speed, hovering at P(0)).

Timeline: every vehicle flies its part of the initial scan (``uavloc_gcs.search.pod_plan.scan_for``:
planned for the POD target when the scenario gives one) from the launch point, waits (hovering)
for the others, then the adaptive phase starts: every ``dt_s`` the slots heard are given to the
policy, which re-estimates and, when it asks, replans from the vehicles' current positions and
remaining energy. The mission ends when every person heard is
located (or given up) and every vehicle is home; the completion time is the moment the last
vehicle lands (computed exactly from the path, not rounded to the step).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from uavloc_gcs.search.pod_plan import scan_for
from uavloc_gcs.scenario import Scenario
from uavloc_gcs.search import SearchPolicy

from ..world import World
from .truth import PersonResult, circle_claims, judge, max_error_m, person_results  # noqa: F401 (their home before)

METHODS = {
    # name: (model_motion, optimizer)
    "MLE-EPSO (M)": (True, "epso"),
    "MLE-EPSO (NM)": (False, "epso"),
    "MLE-PSO": (True, "pso"),
    "MLE-GA": (True, "ga"),
}
DEFAULT_MAX_TIME_S = 3600.0


@dataclass(frozen=True)
class MissionResult:
    method: str
    people: int
    seed: int
    completion_time_s: float  # last vehicle home [s]
    scan_time_s: float  # adaptive phase start [s]
    planner_runtime_s: float  # decision-making compute (planner; RL: training + decisions) [s]
    estimator_runtime_s: float
    replans: int
    energy_j: tuple[float, ...]  # per vehicle, used
    persons: tuple[PersonResult, ...]
    # the clairvoyant yardstick (see oracle_completion_time_s); NaN when not computed
    oracle_completion_time_s: float = math.nan
    error_times_s: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    pod_overall: float = math.nan  # achieved POD over the area from the flown tracks (search/coverage.py)
    pass_rounds: int = 0  # replans that added passes over cells below the POD target
    max_error_m: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    failsafe_returns: int = 0  # flights cut short by the battery failsafe at the reserve (all vehicles)
    # the search reached its time limit ([search] time_limit_s, else simulate_mission's max_time_s)
    # and every vehicle in the air was sent straight home from where it was, as the daemon does
    time_limited: bool = False
    # every circle reported at the end, duplicates of one phone included (circle_claims)
    claims: tuple = ()

    @property
    def located_fraction(self) -> float:
        return float(np.mean([p.located for p in self.persons])) if self.persons else 1.0

    @property
    def max_final_error_m(self) -> float:
        errs = [p.error_m for p in self.persons]
        return float(np.max(errs)) if errs else 0.0


class Flight:
    """A vehicle flying a polyline at constant speed from ``t0_s``; hovers at the end of it.
    ``seg_speeds_m_s`` (one per segment) flies some segments slower: an orbit look's circle at the
    orbit speed (search/orbit.py)."""

    def __init__(self, path_xy_m: np.ndarray, t0_s: float, speed_m_s: float, seg_speeds_m_s=None,
                 heights_m=None, vertical_m_s: tuple[float, float] = (1.5, 2.5)):
        self.path = np.asarray(path_xy_m, dtype=float).reshape(-1, 2)
        self.t0_s = float(t0_s)
        self.speed = float(speed_m_s)
        seg = np.linalg.norm(np.diff(self.path, axis=0), axis=1)
        self.cum_m = np.concatenate([[0.0], np.cumsum(seg)])
        self.seg_speeds = None if seg_speeds_m_s is None else np.asarray(seg_speeds_m_s, dtype=float)
        sp = np.full(len(seg), self.speed) if self.seg_speeds is None else self.seg_speeds
        # heights per path point [m above the ground] (None: the survey altitude throughout): a look
        # flown at its own height (search/orbit.py OrbitLook.alt_m) is reached by a vertical leg at
        # its entry, down at vertical_m_s[0] and up at vertical_m_s[1], as its mission flies it
        self.heights = None if heights_m is None else np.asarray(heights_m, dtype=float).reshape(-1)
        self.vert_s = np.zeros(len(seg))
        if self.heights is not None:
            dz = np.diff(self.heights)
            self.vert_s = np.maximum(-dz, 0.0) / vertical_m_s[0] + np.maximum(dz, 0.0) / vertical_m_s[1]
            if self.seg_speeds is None:
                self.seg_speeds = sp
        self.cum_t = np.concatenate([[0.0], np.cumsum(seg / sp + self.vert_s)])

    @property
    def length_m(self) -> float:
        return float(self.cum_m[-1])

    @property
    def end_t_s(self) -> float:
        if self.seg_speeds is None:  # as before orbits, to the last bit (the paper's reproduction)
            return self.t0_s + self.length_m / self.speed
        return self.t0_s + float(self.cum_t[-1])

    def flown_m(self, t_s) -> np.ndarray:
        if self.seg_speeds is not None:
            return np.interp(np.asarray(t_s, dtype=float) - self.t0_s, self.cum_t, self.cum_m)
        return np.clip((np.asarray(t_s, dtype=float) - self.t0_s) * self.speed, 0.0, self.length_m)

    def energy_j(self, t_from_s: float, t_to_s: float, pw) -> tuple[float, float]:
        """(propulsion energy [J], seconds in flight) between two times, each segment at its speed."""
        if self.seg_speeds is None:
            flown = float(self.flown_m(t_to_s) - self.flown_m(t_from_s))
            return float(pw.leg_energy_j(flown, self.speed)), flown / self.speed
        level_s = np.diff(self.cum_t) - self.vert_s
        seg_e = level_s * np.asarray(pw.power_w(self.seg_speeds), dtype=float)
        if self.heights is not None:  # a vertical leg: hovering power and the climb's work W dh
            seg_e = seg_e + self.vert_s * pw.hover_power_w() + pw.weight_n * np.maximum(np.diff(self.heights), 0.0)
        cum_e = np.concatenate([[0.0], np.cumsum(seg_e)])
        a, b = (min(max(x - self.t0_s, 0.0), float(self.cum_t[-1])) for x in (t_from_s, t_to_s))
        return float(np.interp(b, self.cum_t, cum_e) - np.interp(a, self.cum_t, cum_e)), b - a

    def height(self, t_s, survey_m: float) -> np.ndarray:
        """Height(s) [m] at time(s) t_s: ``survey_m`` throughout unless the path has its own."""
        if self.heights is None:
            return np.full(np.shape(t_s), float(survey_m))
        return np.interp(np.asarray(t_s, dtype=float) - self.t0_s, self.cum_t, self.heights)

    def position(self, t_s) -> np.ndarray:
        """(2,) or (N, 2) position [m] at time(s) t_s."""
        s = self.flown_m(t_s)
        x = np.interp(s, self.cum_m, self.path[:, 0])
        y = np.interp(s, self.cum_m, self.path[:, 1])
        return np.stack([x, y], axis=-1)


SWAP_BELOW = 0.5  # a landed vehicle with a spare pack gets it when less than this share of its pack is left


class Vehicle:
    """Energy and flight bookkeeping of one simulated vehicle (with ``fleet.batteries`` > 1, the
    packs it flies one after another, a swap of ``fleet.battery_swap_s`` on the ground between)."""

    def __init__(self, index: int, sc: Scenario):
        self.index = index  # world/MAVLink vehicle number (1-based)
        self.id = str(index)
        self.sc = sc
        self.flight = Flight(np.zeros((1, 2)), 0.0, sc.fleet.speed_m_s)
        self.energy_j = 0.0  # used from the pack it flies now
        self.spent_j = 0.0  # used from the packs swapped out before it (sorties)
        self.accounted_t_s = 0.0
        self.home_t_s: float | None = None
        # sorties (issue 38): the packs waiting at home, and the end of a swap in progress
        self.spare_packs = int(getattr(sc.fleet, "batteries", 1)) - 1
        self.swap_until_s: float | None = None
        self.sorties_flown = 0
        self.failsafe_home = False  # going home on the battery failsafe: plans are not taken until it lands
        self.failsafe_returns = 0

    @property
    def total_energy_j(self) -> float:
        return self.spent_j + self.energy_j

    def swap_if_due(self, t_s: float) -> bool:
        """On the ground with a spare pack and less than SWAP_BELOW of the usable energy left: the
        team swaps it (``fleet.battery_swap_s`` on the ground). True when a swap ends at ``t_s``:
        the vehicle is ready again with a fresh pack."""
        if self.home_t_s is None:
            return False
        if self.swap_until_s is None:
            left = self.sc.usable_energy_j - self.energy_j
            if self.spare_packs > 0 and left < SWAP_BELOW * self.sc.usable_energy_j:
                self.swap_until_s = self.home_t_s + float(self.sc.fleet.battery_swap_s)
            else:
                return False
        if t_s + 1e-9 < self.swap_until_s:
            return False
        self.account(t_s)
        self.spent_j += self.energy_j
        self.energy_j = 0.0
        self.spare_packs -= 1
        self.swap_until_s = None
        return True

    @property
    def in_swap(self) -> bool:
        return self.swap_until_s is not None

    def fly(self, path_xy_m: np.ndarray, t_s: float, seg_speeds_m_s=None, heights_m=None) -> None:
        if self.in_swap or self.failsafe_home:  # not before its fresh pack is in (a plan made during the
            return  # swap waits for it), nor while its battery failsafe takes it home
        self.account(t_s)
        if self.home_t_s is not None and len(path_xy_m) > 1:
            self.sorties_flown += 1
        survey = float(self.sc.fleet.altitude_m)
        now_m = float(self.flight.height(t_s, survey))
        if heights_m is not None:  # starting where the last flight left it (a look at its own height)
            heights_m = np.asarray(heights_m, float).copy()
            heights_m[0] = now_m
        elif abs(now_m - survey) > 0.5:  # replanned during a low look: back up where it is, then on
            path_xy_m = np.vstack([np.asarray(path_xy_m, float)[:1], path_xy_m])
            heights_m = np.concatenate([[now_m], np.full(len(path_xy_m) - 1, survey)])
            n_seg = len(path_xy_m) - 1
            base = (np.full(n_seg - 1, self.sc.fleet.speed_m_s) if seg_speeds_m_s is None
                    else np.asarray(seg_speeds_m_s, float))
            seg_speeds_m_s = np.concatenate([[self.sc.fleet.speed_m_s], base])
        vertical = (self.sc.terrain.max_descent_m_s, self.sc.terrain.max_climb_m_s) if heights_m is not None else (1.5, 2.5)
        self.flight = Flight(path_xy_m, t_s, self.sc.fleet.speed_m_s, seg_speeds_m_s, heights_m, vertical)
        self.home_t_s = None

    def account(self, t_s: float) -> None:
        """Charge flight and hover energy from the last accounting time up to ``t_s``."""
        if t_s <= self.accounted_t_s:
            return
        pw = self.sc.power_model
        if self.home_t_s is not None:  # landed
            self.accounted_t_s = t_s
            return
        f = self.flight
        e_fly, fly_s = f.energy_j(self.accounted_t_s, t_s, pw)
        self.energy_j += e_fly + pw.hover_energy_j(max(0.0, t_s - self.accounted_t_s - fly_s))
        self.accounted_t_s = t_s

    def land_if_home(self, t_s: float) -> None:
        """Mark the vehicle landed if its path ends at the launch point and it got there by t_s."""
        f = self.flight
        if self.home_t_s is None and np.allclose(f.path[-1], 0.0) and f.end_t_s <= t_s:
            self.account(f.end_t_s)
            self.home_t_s = f.end_t_s
            self.failsafe_home = False

    def failsafe(self, t_s: float) -> bool:
        """The battery failsafe: a vehicle in the air that has used its pack's usable energy (down to
        the reserve, ``fleet.energy_reserve_fraction``) flies straight home from where it is and takes
        no plan until it has landed. The planner keeps the reserve, but take-offs, climbs and the
        hover at a plan's end are charged here and not planned: without it a vehicle flew on into
        its reserve and past its packs (790 kJ on three 250 kJ packs). PX4 returns at its critical
        level by default (``COM_LOW_BAT_ACT`` 3, docs/guide/sitl.md "Battery"); on ArduPilot it is
        ``BATT_FS_LOW_ACT`` 2 (RTL), which a team sets for a search. True when it triggers now."""
        if self.home_t_s is not None or self.failsafe_home or self.in_swap:
            return False
        self.account(t_s)
        if self.energy_j < self.sc.usable_energy_j:
            return False
        planned = self.flight
        self.fly(np.vstack([self.flight.position(t_s).reshape(1, 2), np.zeros((1, 2))]), t_s)
        self.failsafe_home = True
        if np.allclose(planned.path[-1], 0.0) and planned.end_t_s <= self.flight.end_t_s + 1.0:
            self.flight = planned  # on its way home already, as soon as straight home: not a failsafe return
            return False
        self.failsafe_returns += 1
        return True

    def recall(self, t_s: float) -> None:
        """The search's time is up: straight home from where it is (the daemon's end of a search);
        a vehicle on the ground, or already on its battery failsafe's way home, stays as it is."""
        if self.home_t_s is None and not self.failsafe_home:
            self.fly(np.vstack([self.flight.position(t_s).reshape(1, 2), np.zeros((1, 2))]), t_s)

    def state(self, t_s: float):
        """The planner's view (planning.VehicleState): position now, home, usable energy left."""
        from uavloc_gcs.planning import VehicleState

        self.account(t_s)
        xy = self.flight.position(t_s)
        left = 0.0 if self.in_swap else max(0.0, self.sc.usable_energy_j - self.energy_j)
        if self.spare_packs > 0:  # on the ground in a swap: energy 0 with its packs (search/policy.py)
            return VehicleState(self.id, (float(xy[0]), float(xy[1])), (0.0, 0.0), left, self.spare_packs,
                                float(self.sc.usable_energy_j))
        return VehicleState(self.id, (float(xy[0]), float(xy[1])), (0.0, 0.0), left)


class _Clairvoyant(SearchPolicy):
    """The policy's planner with every pending person's true track in place of the estimate
    (same look radii, no mirror, no miss): what the follow-up looks would cost if the estimator
    knew where everyone is."""

    world: World

    def _targets(self, t_s, vehicles, planned_times, previous=None):
        out = []
        pos, vel = self.world.positions(t_s), self.world.velocities(t_s)
        for tgt in super()._targets(t_s, vehicles, planned_times, previous):
            i = int(self.world.person_of([int(tgt.id)])[0])  # the person behind the id reported
            if i < 0:
                out.append(tgt)
                continue
            v = vel[i] if self.model_motion else np.zeros(2)
            out.append(replace(tgt, xy_m=(float(pos[i][0]), float(pos[i][1])), velocity_m_s=(float(v[0]), float(v[1]))))
        return out


def oracle_completion_time_s(policy: SearchPolicy, world: World, vehicles: list["Vehicle"], t_s: float) -> float:
    """Completion time [s] of the clairvoyant yardstick: at the end of the scan (``t_s``), the same
    planner plans one look at every person the policy has not located, aimed at the true track
    with the look radius the real estimate needs, and every vehicle then flies home. A lower
    bound on what better estimation alone could gain (the real method may need more looks)."""
    import copy

    oracle = copy.deepcopy(policy)
    oracle.__class__ = _Clairvoyant
    oracle.world = world
    plan = oracle.replan(t_s, [copy.deepcopy(v).state(t_s) for v in vehicles])
    return float(max((task.eta_s for task in plan.tasks), default=t_s))


def slot_times(t_from_s: float, t_to_s: float, slot_s: float) -> np.ndarray:
    """Slot start times k*slot_s in [t_from_s, t_to_s)."""
    k0 = math.ceil(t_from_s / slot_s - 1e-9)
    k1 = math.ceil(t_to_s / slot_s - 1e-9)
    return np.arange(k0, k1) * slot_s


# Where the policy learns the vehicles listened (its silences): "flown", the whole flight (a
# companion that reported every slot it listened); "heard", only the slots where it heard some
# phone (what the daemon knows: SearchPolicy.tracks_from_slots); "none", no silences.
LISTENING = "flown"
COVERAGE_STEP_S = 1.0  # flown positions given to the coverage accumulator this often [s]


def hear(world: World, vehicles: list[Vehicle], t_from_s: float, t_to_s: float, policy=None):
    """Slots every vehicle hears in [t_from_s, t_to_s) along its current flight; with ``policy``,
    where each vehicle listened is recorded too (``SearchPolicy.ingest_track``)."""
    from uavloc_gcs.observations import SlotBatch

    sc = world.scenario
    t = slot_times(t_from_s, t_to_s, sc.channel.slot_s)
    if len(t) == 0:
        return SlotBatch.empty()
    out = []
    for v in vehicles:
        tt = t if v.home_t_s is None else t[t < v.home_t_s]
        tt = tt[tt >= v.flight.t0_s]  # on the ground before a flight (a swap): deaf
        if len(tt) == 0:
            continue
        xy = v.flight.position(tt)
        xyz = np.column_stack([xy, v.flight.height(tt, sc.fleet.altitude_m)])
        out.append(world.hear_track(v.index, tt, xyz))
        if policy is not None and not policy.tracks_from_slots:
            policy.ingest_track(v.index, tt, xyz)
        cov = getattr(policy, "coverage", None)
        if cov is not None:  # what was flown within hearing (uavloc_gcs/search/coverage.py), as the daemon
            step = max(1, int(round(COVERAGE_STEP_S / sc.channel.slot_s)))
            cov.add_track(v.index, tt[::step], xyz[::step])
    return SlotBatch.concat(out)


def _orbit_path(task, start_xy_m, cruise_m_s: float, survey_m: float = 0.0):
    """A task's path with its orbit looks flown (search/orbit.py), each segment's speed, and each
    point's height where a look flies at its own (else None)."""
    from uavloc_gcs.search.orbit import expand_path

    pts = np.asarray(task.waypoints_xy_m, dtype=float).reshape(-1, 2)
    path, seg_orbit = expand_path(pts[:-1], task.orbits, start_xy_m)
    path = np.vstack([path, pts[-1:]])  # home
    seg_orbit = np.append(seg_orbit, -1)
    speeds = np.array([cruise_m_s if k < 0 else task.orbits[k].speed_m_s for k in seg_orbit])
    alts = [None if k < 0 else getattr(task.orbits[k], "alt_m", None) for k in seg_orbit]
    if all(a is None for a in alts):
        return path, speeds, None
    return _with_heights(path, speeds, alts, survey_m)


def _with_heights(path, speeds, alts, survey_m: float):
    """The path with a vertical leg (a repeated point) down to each look's height at its entry and
    back up at its end, and the height of every point."""
    out_p, out_s, out_z = [path[0]], [], [survey_m]
    for i, a in enumerate(alts):
        z = survey_m if a is None else float(a)
        if abs(z - out_z[-1]) > 1e-9:  # change height where the vehicle is, then fly the segment
            out_p.append(out_p[-1])
            out_s.append(speeds[i])
            out_z.append(z)
        out_p.append(path[i + 1])
        out_s.append(speeds[i])
        out_z.append(z)
    return np.asarray(out_p), np.asarray(out_s), np.asarray(out_z)


def simulate_mission(
    scenario: Scenario,
    world: World,
    method: str = "MLE-EPSO (M)",
    *,
    seed: int = 0,
    dt_s: float = 1.0,
    scan_update_s: float = 10.0,
    time_limit_s: float | None = None,
    max_iter: int | None = None,
    max_time_s: float = DEFAULT_MAX_TIME_S,
    oracle: bool = False,
    hearing_evidence: bool = True,
    coverage: bool = True,
    adaptive: bool = True,
) -> MissionResult:
    """Fly one mission with one of :data:`METHODS` and report completion time, run times, errors.
    ``adaptive=False``: the scan alone (a conventional search): every vehicle flies home after its
    scan, and the people are what the estimator makes of the scan's data. The search ends at
    ``[search] time_limit_s`` (at most ``max_time_s``): then every vehicle in the air flies straight
    home from where it is and nothing more is heard (:attr:`MissionResult.time_limited`)."""
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; expected one of {', '.join(METHODS)}")
    model_motion, optimizer = METHODS[method]
    # the scan the scenario asks for: planned for its POD target (at the speed chosen for it), else [scan]'s
    given = scenario
    scenario, scan = scan_for(scenario)
    policy = SearchPolicy(scenario, model_motion=model_motion, optimizer=optimizer,
                          local_search=scenario.planner.local_search, seed=seed, time_limit_s=time_limit_s,
                          max_iter=max_iter)
    policy.hearing_evidence = hearing_evidence and LISTENING != "none" and math.isfinite(scenario.fleet.comm_range_m)
    policy.tracks_from_slots = LISTENING == "heard"
    if coverage:
        from uavloc_gcs.search.coverage import attach

        attach(scenario, policy)  # cells below the POD target get another pass, as in the daemon
    m = scenario.fleet.vehicles
    vehicles = [Vehicle(i + 1, scenario) for i in range(m)]
    home = np.zeros((1, 2))
    queued: dict[int, list] = {}  # scan sorties still to fly after a swap, per vehicle (sorties)
    if int(getattr(scenario.fleet, "batteries", 1)) > 1:
        from uavloc_gcs.search.pod_plan import scan_pod_plan
        from uavloc_gcs.sorties import scan_sorties

        # the plan scan_for chose, asked of the scenario as given (the flown one, with the chosen
        # speed, is another key: it planned the scan a second time, 80 s, and could choose another)
        pp = scan_pod_plan(given)
        sorties = pp.sorties if pp is not None and pp.sorties else scan_sorties(scenario, scan)
        for vs, sp in zip(scan.vehicles, sorties):
            paths = [np.vstack([home, s.waypoints_xy_m, home]) for s in sp.sorties]
            vehicles[vs.index].fly(paths[0], 0.0)
            queued[vs.index] = paths[1:]
    else:
        for vs in scan.vehicles:
            vehicles[vs.index].fly(np.vstack([home, vs.waypoints_xy_m]), 0.0)

    def scanning(t_s: float) -> bool:
        for i, v in enumerate(vehicles):
            v.land_if_home(t_s)
            v.failsafe(t_s)
            if v.swap_if_due(t_s) and queued.get(i):
                v.fly(queued[i].pop(0), t_s)  # the next sortie of its scan, on the fresh pack
        return any(queued.values()) or any(v.flight.end_t_s > t_s for v in vehicles)

    # the search's time limit, the scan's too: at it every vehicle in the air flies home (below)
    given_limit = scenario.search.time_limit_s
    limit_s = float(max_time_s) if given_limit is None else min(float(max_time_s), float(given_limit))
    err_t, err_v = [], []
    t = 0.0
    if not queued:  # one pack each: the scan as one flight per vehicle
        t_scan = max((v.flight.end_t_s for v in vehicles), default=0.0)
        scan_cut = t_scan > limit_s  # the scan itself outlasts the search's time
        t_scan = min(t_scan, limit_s)
        while t < t_scan:  # the scan: listen, re-estimate now and then for the error curve
            for v in vehicles:
                v.failsafe(t)
            t_next = min(t + scan_update_s, t_scan)
            policy.ingest(hear(world, vehicles, t, t_next, policy))
            policy.update(t_next)
            t = t_next
            err_t.append(t)
            err_v.append(max_error_m(world, policy.people(t)))
    else:  # sorties: each lands, is swapped and flies the next part of its scan
        while t < limit_s and scanning(t):
            nxt = [v.swap_until_s for v in vehicles if v.swap_until_s is not None and v.swap_until_s > t]
            nxt += [v.flight.end_t_s for v in vehicles if v.flight.end_t_s > t]
            t_next = min([t + scan_update_s, limit_s, *nxt])
            policy.ingest(hear(world, vehicles, t, t_next, policy))
            policy.update(t_next)
            t = t_next
            err_t.append(t)
            err_v.append(max_error_m(world, policy.people(t)))
        t_scan = t
        scan_cut = t >= limit_s  # stopped by the limit, not by the scan's end

    replans = 0
    limited = scan_cut
    changed = policy.update(t)
    t_oracle = oracle_completion_time_s(policy, world, vehicles, t) if oracle else math.nan
    if not adaptive:
        for v in vehicles:
            v.fly(np.vstack([v.flight.position(t).reshape(1, 2), np.zeros((1, 2))]), t)
    while True:
        fresh = False
        for v in vehicles:
            v.land_if_home(t)
            v.failsafe(t)
            fresh |= adaptive and not policy.done(t) and v.swap_if_due(t)
        all_home = all(v.home_t_s is not None for v in vehicles)
        swapping = any(v.in_swap for v in vehicles)
        if (policy.done(t) or not adaptive) and all_home:
            break
        force = fresh or (all(v.home_t_s is not None or v.flight.end_t_s <= t for v in vehicles)
                          and not policy.done(t) and not swapping)
        if t >= limit_s:  # the search's time is up: everyone home from where they are, as the daemon does
            # (cut short: a scan sortie or a look not flown, not a vehicle merely on its way home)
            limited |= any(queued.values()) or (adaptive and not policy.done(t))
            for v in vehicles:
                planned_end = v.flight.end_t_s if v.home_t_s is None else -math.inf
                v.recall(t)
                limited |= v.home_t_s is None and v.flight.end_t_s < planned_end - 1.0
            break
        if adaptive and (force or policy.needs_replan(t, changed) or (policy.done(t) and policy.current_plan is None)):
            plan = policy.replan(t, [v.state(t) for v in vehicles])
            replans += 1
            for task, v in zip(plan.tasks, vehicles):
                start = v.flight.position(t).reshape(1, 2)
                if any(o is not None for o in getattr(task, "orbits", ())):
                    path, speeds, heights = _orbit_path(task, start[0], scenario.fleet.speed_m_s,
                                                        scenario.fleet.altitude_m)
                    v.fly(path, t, speeds, heights)
                else:
                    v.fly(np.vstack([start, task.waypoints_xy_m]), t)
        t_next = t + dt_s
        if policy.done(t):  # nothing left to learn: jump to the last landing
            t_next = max(t_next, max(v.flight.end_t_s for v in vehicles))
        policy.ingest(hear(world, vehicles, t, t_next, policy))
        t = t_next
        changed = policy.update(t)
        err_t.append(t)
        err_v.append(max_error_m(world, policy.people(t)))

    for v in vehicles:
        v.land_if_home(math.inf)
    t_end = max((v.home_t_s if v.home_t_s is not None else t) for v in vehicles)
    for v in vehicles:
        v.account(t_end)
    statuses = policy.people(t_end)
    persons, claims = judge(world, statuses, t_end, policy.heard_slots)
    return MissionResult(
        method=method, people=len(world), seed=seed, completion_time_s=float(t_end), scan_time_s=float(t_scan),
        planner_runtime_s=policy.planner_runtime_s, estimator_runtime_s=policy.estimator_runtime_s,
        replans=replans, energy_j=tuple(v.total_energy_j for v in vehicles),
        persons=persons, claims=claims, oracle_completion_time_s=t_oracle,
        error_times_s=np.asarray(err_t), max_error_m=np.asarray(err_v),
        pod_overall=policy.coverage.overall() if getattr(policy, "coverage", None) is not None else math.nan,
        pass_rounds=policy.coverage.pass_rounds if getattr(policy, "coverage", None) is not None else 0,
        failsafe_returns=sum(v.failsafe_returns for v in vehicles), time_limited=limited)
