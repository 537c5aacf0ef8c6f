"""The adaptive search loop's decisions (SPEC §2.3), shared by the daemon and the experiments.

A :class:`SearchPolicy` holds every RSSI slot received so far, re-estimates the emitters that got
new data, says who is located, decides when the plan is stale and plans the next flights::

    policy = SearchPolicy(scenario, model_motion=True, optimizer="epso", seed=0)
    policy.ingest(slots)                      # any time slots arrive
    changed = policy.update(t_s)              # re-estimate emitters with new slots
    if policy.needs_replan(t_s, changed):
        plan = policy.replan(t_s, vehicle_states)   # -> one VehicleTask per vehicle
    if policy.done(t_s): ...                  # everyone located (or given up): go home

It is pure and deterministic: no sockets, files or clocks decide anything (the planner's run time
is measured for reporting only); time and seeds are passed in. The caller owns the scan: call
``replan`` once the initial scan is over.

A *look* is a pass of a vehicle within the person's access radius (``access_radius_m``) of the
predicted position; the vehicle flies through the access point without stopping. When a person is
mirror-ambiguous the look goes to the more likely candidate with a radius small enough to keep
the pass off the mirror line; if the pass hears nothing, the next look goes to the other candidate.
Mirror candidates well outside the search area are discarded (people are inside it); once a person
has been ambiguous, the mirror must fall under judging.AMBIGUITY_SETTLED_MASS before a fix. A repeated look
(the last one heard the person without locating them) has half the radius (targets.LOOK_SHRINK)
and goes beside the person, across the line from the vehicle (:data:`.aiming.SIDEWAYS_LOOK_FRACTION`). A person
is given up only when no look can locate them: two looks did not hear them (with a mirror
ambiguity, one at each candidate), or no vehicle has the energy left for a look -- which ends
every mission (:data:`.judging.MAX_LOOKS` can cap looks per person; off). A look is judged R/V after its
planned time, or -- when the caller reports flown looks (``look_reports``, ``look_flown``, as the
daemon does) -- R/V after the vehicle really passed it.

What the policy heard and how it becomes each person's data (slots, linking, listening tracks,
bursts and silences) is :mod:`.hearing`'s, the base of :class:`SearchPolicy`; whether each person is
located or given up is :mod:`.judging`'s; where each look goes is :mod:`.aiming`'s; this module
plans and routes.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, replace

import numpy as np

from ..errors import InfeasibleError
from ..observations import SlotBatch
from ..radios import radio_of
from ..scenario import Scenario
from . import orbit as orb
from .aiming import Aiming
from .hearing import _Person

log = logging.getLogger(__name__)

RADIUS_RECHECK_FRACTION = 0.85  # replan once more if a planned radius shrinks below this fraction


@dataclass(frozen=True)
class PersonStatus:
    """What the policy believes about one emitter.

    ``located``: estimate ok, calibrated 95 % radius <= required accuracy, no mirror ambiguity.
    ``xy_m`` [m], ``velocity_m_s`` and ``t_ref_s`` [s] are the believed candidate (the mirror
    candidate if that one was chosen) that ``radius95_m`` belongs to: for a located person the
    candidate at the fix (``estimate`` is then the fix estimate), otherwise the latest estimate's.
    ``fix_t_s`` is the time the person became located (None if not yet).
    """

    emitter_id: int
    estimate: object
    located: bool
    reason: str
    xy_m: tuple[float, float] | None = None
    t_ref_s: float | None = None
    fix_t_s: float | None = None
    looks: int = 0
    radius95_m: float = math.inf  # calibrated radius of the believed candidate (at the fix if located)
    velocity_m_s: tuple[float, float] | None = None  # of the believed candidate [m/s]


@dataclass(frozen=True)
class VehicleTask:
    """Where one vehicle flies next: pass points in order, then home (last row). ``eta_s`` is the
    planned time home [s]."""

    vehicle_id: str
    waypoints_xy_m: np.ndarray  # (k, 2)
    target_ids: tuple[int, ...]
    eta_s: float
    access_times_s: tuple[float, ...] = ()
    orbits: tuple = ()  # per target: search.orbit.OrbitLook (an orbit look) or None (a fly-by)


@dataclass(frozen=True)
class SearchPlan:
    tasks: tuple[VehicleTask, ...]
    makespan_s: float
    planner_runtime_s: float
    plan: object = None  # planning.Plan (None when nobody needs a look)
    t0_s: float = 0.0


class SearchPolicy(Aiming):
    """Estimator + planner decisions of the adaptive loop for one mission (see module docstring)."""

    def __init__(
        self,
        scenario: Scenario,
        *,
        model_motion: bool = True,
        optimizer: str = "epso",
        local_search: bool = True,
        seed: int = 0,
        time_limit_s: float | None = None,
        max_iter: int | None = None,
        fitter=None,
    ) -> None:
        from ..estimation import (
            ChannelModel,  # local: keeps `import uavloc_gcs.search` light
        )

        self.scenario = scenario
        self.model_motion = model_motion
        self.optimizer = optimizer
        self.local_search = local_search
        self.seed = int(seed)
        self.time_limit_s = scenario.planner.time_limit_s if time_limit_s is None else float(time_limit_s)
        self.max_iter = max_iter  # None: stop on the time limit; set it (and a long time limit) for
        # run-to-run determinism
        # NM (the paper's variant) believes people are static: speed bound 0, so its radius does not
        # grow with the data's age. Its true error on moving people shows what that belief costs.
        self.model_speed_m_s = scenario.people.max_speed_m_s if model_motion else 0.0
        self.channel = ChannelModel.from_scenario(scenario)
        self.required_m = scenario.people.required_accuracy_m
        self.area_xy_m = scenario.area_xy_m()
        self.range_m = scenario.horizontal_range_m
        self.speed_m_s = scenario.fleet.speed_m_s
        self._people: dict[int, _Person] = {}
        self._plan: SearchPlan | None = None
        self._awaiting: dict[int, float] = {}  # emitter -> planned access time [s] (re-based on reports)
        self._look_vehicle: dict[int, str] = {}  # emitter -> vehicle planned to look at it
        self._flown: dict[int, float] = {}  # emitter -> time [s] a look was flown, not judged yet
        # vehicle -> time [s] up to which its receiver has reported all it heard (heard_until); a
        # vehicle not in it is taken as reporting at once (the experiments, old receivers)
        self._heard_until: dict[int, float] = {}
        # Set by a caller that reports flown looks (``look_flown``, the daemon): a look is then
        # judged from when it was flown, not from its planned time (real flights run late).
        self.look_reports = False
        self._replans = 0
        # Pending people the last replan could not plan for and did not give up: planning again
        # with nothing new would give the same answer, so only new data about them (or someone
        # else) asks for another replan. Never replan in a loop when nothing can change.
        self._unplanned: set[int] = set()
        self._access_cache: dict[tuple[int, float], tuple[object, float]] = {}  # (emitter, t) -> (est, m)
        self._target_t_pass: dict[int, float] = {}  # emitter -> pass time its current radius is for
        self.planner_runtime_s = 0.0  # total over all replans
        self.estimator_runtime_s = 0.0
        # where each vehicle listened (ingest_track): the estimator's silences (estimation.evidence)
        self._tracks: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}
        # silences of the recorded tracks (ingest_track) go to the estimator; measured on missions
        # (docs/science/estimator.md): more people located, sooner
        self.hearing_evidence = math.isfinite(scenario.fleet.comm_range_m)
        self.tracks_from_slots = False  # see hearing.SLOT_TRACK_QUIET_S
        # slots of a sensor that reports fingerprints, not yet linked into people (see _relink)
        self._raw: list[SlotBatch] = []
        self.linking = None  # estimation.identity.Linking of everything heard, once linking is on
        # phones heard in bursts, not elicited: a fly-by look rarely hears them (judging.FLYBY_LOOKS_FOR_BURSTS)
        self._bursts = scenario.emission.model == "probe-bursts" and scenario.emission.elicitation_rate_hz == 0
        # phones that send probe bursts, with or without an access point's answers: the grid estimate
        self._probe_bursts = scenario.emission.model == "probe-bursts"
        self._reach_poly = None  # the area grown by LOOK_AREA_MARGIN (_inside_reach)
        self._frames_prior = None  # estimation.evidence.FramesPrior of the scenario's bursts (frames_prior)
        self._burst_rates = None  # and their rate law (burst_rates), for the bursts nobody heard
        self._deferred: set[int] = set()  # people waiting for a fresh pack in the current plan (replan)
        self._grid = None  # radio -> estimation.burst_grid.GridSpec (the field world, _grid_spec)
        # where the estimates are computed (estimation.fitting): in this thread by default; the
        # daemon passes a ProcessFitter so that fitting never stops its event loop
        if fitter is None:
            from ..estimation.fitting import InlineFitter

            fitter = InlineFitter(self.channel, scenario.dem)
        self.fitter = fitter

    # -- data in ---------------------------------------------------------------------------
    def update(self, t_s: float) -> set[int]:
        """Re-estimate emitters with new data; return the ids whose state changed materially
        (new person, located, ambiguity, estimate moved, a planned look happened or failed).

        Fits go to ``self.fitter``: with the default (in this thread) every person with new data is
        fitted before this returns; with a worker process (the daemon) as many as it takes now, the
        people a look is under way for first, and their results are applied when a later call
        finds them done. People already located or given up are not fitted again: no decision
        reads them (the end of the search refits them for the report)."""
        from ..estimation.fitting import FitJob

        changed: set[int] = set()
        if len(self._raw) > 1 or (self._raw and self.linking is None):
            self._relink()
        for p in self._fit_order():
            if not self.fitter.can_take():
                break
            p.dirty, p.fitting = False, True
            if len(p.batches) > 1:
                p.batches = [SlotBatch.concat(p.batches).sorted_by_time()]
            spec = self._grid_spec(radio_of(p.batches[0]))
            if spec is not None:  # the field world: the grid posterior of the person's bursts
                job = FitJob(p.emitter_id, p.version, p.batches[0], self.model_speed_m_s, p.last_slot_t_s,
                             self.model_motion, check_within_m=self.required_m, grid=spec,
                             bursts=self._bursts_of(p))
            else:
                job = FitJob(p.emitter_id, p.version, p.batches[0], self.model_speed_m_s, p.last_slot_t_s,
                             self.model_motion, p.estimate, self._silence(p), self._censored(p),
                             check_within_m=self.required_m)
            self.fitter.submit(job)
        for res in self.fitter.results():
            if self._apply_fit(res, t_s):
                changed.add(res.emitter_id)
        changed |= self._check_looks(t_s)
        return changed

    def _apply_fit(self, res, t_s: float) -> bool:
        """A finished fit (estimation.fitting.FitResult) into its person's state; True when that
        changed materially. A fit of data that have grown since counts for what it says about the
        person at its reference time (a fix is dated there), and the person is fitted again."""
        p = self._people.get(res.emitter_id)
        if p is None:  # their bursts were linked to someone else meanwhile
            return False
        p.fitting = False
        self.estimator_runtime_s += res.runtime_s
        if p.fix_t_s is not None or p.gave_up:
            return False
        before = self._signature(p)
        if res.estimate is not None:
            p.estimate, p.error = self._unsettled(p, res.estimate), ""
            p.contradicted = res.contradicted
            if res.contradicted:
                log.info("emitter %d: not located: %s", p.emitter_id, res.contradicted)
        elif res.error:
            p.error = res.error
        else:  # a defect in the estimator, not bad data: said loudly (logged where it ran), and the
            # person reported with it, while the search goes on for everyone else
            p.error = f"the estimator failed ({res.crash})"
        self._classify(p, t_s)
        if res.version != p.version:
            p.dirty = True  # data came meanwhile: fitted again with them
        return before is None or self._material(before, self._signature(p))

    def close(self) -> None:
        """Stop the fitting under way (a worker process ends at once)."""
        self.fitter.close()

    # -- views -----------------------------------------------------------------------------
    def people(self, t_s: float) -> list[PersonStatus]:
        """Status of every emitter heard so far, by id."""
        out = []
        for eid, p in sorted(self._people.items()):
            located = p.fix_t_s is not None
            # position and radius always of the same candidate: the fix's when located
            cand = p.fix_candidate if located else self._candidate(p)
            est = p.fix_estimate if located else p.estimate
            out.append(PersonStatus(
                emitter_id=eid, estimate=est, located=located, reason=self._reason(p),
                xy_m=None if cand is None else (float(cand.xy_m[0]), float(cand.xy_m[1])),
                t_ref_s=None if cand is None else cand.t_ref_s, fix_t_s=p.fix_t_s, looks=p.looks,
                radius95_m=p.fix_radius95_m if located else (
                    self._radius95(p) if p.estimate is not None else math.inf),
                velocity_m_s=None if cand is None else (float(cand.velocity_m_s[0]),
                                                        float(cand.velocity_m_s[1]))))
        return out

    def pending_ids(self) -> list[int]:
        """Emitters that still need a look (not located, not given up)."""
        return [e for e, p in sorted(self._people.items()) if p.fix_t_s is None and not p.gave_up]

    @property
    def current_plan(self) -> SearchPlan | None:
        return self._plan

    def done(self, t_s: float) -> bool:
        """True when every emitter heard is located or given up and no look is outstanding, and no
        pass over cells below the POD target is wanted (search/coverage.py, with ``coverage``)."""
        from .passes import passes_wanted

        return not self.pending_ids() and not passes_wanted(self)

    def needs_replan(self, t_s: float, changed: set[int]) -> bool:
        """True if the current plan no longer fits what is known."""
        pending = set(self.pending_ids())
        if self._plan is None:
            from .passes import passes_wanted

            return bool(pending) or passes_wanted(self)
        planned = {e for task in self._plan.tasks for e in task.target_ids}
        if planned - pending:  # someone in the plan is already located or given up
            return True
        if pending - planned - self._unplanned:  # someone new needs a look
            return True
        # an orbit whose person's estimate moved off it is re-centred (search/orbit.py ADAPTIVE_ORBITS)
        for e in changed & set(self._flown):
            p = self._people.get(e)
            cand = self._candidate(p) if p is not None and self._ok(p) else None
            if cand is not None and orb.recentre_due(self, e, cand.at(t_s)):
                return True
        # Estimates shift while a vehicle is passing a person; re-routing it mid-look would only
        # thrash. The look's end (see update) or a fix triggers the replan instead.
        lead_s = 2.0 * self.range_m / self.speed_m_s
        relevant = {e for e in changed if e not in self._flown
                    and not (e in self._awaiting and t_s >= self._awaiting[e] - lead_s)}
        return bool(relevant & (pending | planned))

    # -- planning --------------------------------------------------------------------------
    def replan(self, t_s: float, vehicles: list) -> SearchPlan:
        """Plan looks at every pending person from the vehicles' current states (planning.VehicleState,
        remaining usable energy). Persons no vehicle can reach within its energy are given up."""
        from ..planning import RoutingProblem, solve

        self._replans += 1
        # drop superseded estimates, and those of people whose bursts are now linked to someone else
        # (hearing.py removes them: a three-pack field search crashed here with a KeyError)
        self._access_cache = {k: v for k, v in self._access_cache.items()
                              if k[0] in self._people and v[0] is self._people[k[0]].estimate}
        self._target_t_pass = {}
        rng = np.random.default_rng([self.seed, self._replans])
        runtime = 0.0
        # Sorties (issue 38): looks are routed on the packs the vehicles fly now; a person whom no
        # pack in the air can reach but a fresh pack from home can (a vehicle with spare_packs) waits
        # for the swap instead of being given up (self._deferred, for this plan)
        spare = [v for v in vehicles if getattr(v, "spare_packs", 0) > 0]
        vehicles = [replace(v, spare_packs=0, pack_energy_j=0.0) if getattr(v, "spare_packs", 0) else v
                    for v in vehicles]
        self._deferred = set()
        targets = self._targets(t_s, vehicles, None)
        result = None
        # minus those that can only just get home (they are sent home) and those on the ground in a
        # swap (at home, no energy, a spare pack: planned once the fresh pack is in)
        swapping = {v.id for v in spare if v.energy_j <= 1.0
                    and math.dist(v.start_xy_m, v.home_xy_m) < 1.0}
        flyable = [v for v in vehicles if v.id not in swapping]
        if not flyable:
            targets = []
        while targets:
            problem = RoutingProblem(tuple(flyable), tuple(targets), self.speed_m_s, t0_s=t_s,
                                     power=self.scenario.power_model)
            t0 = time.perf_counter()
            try:
                result = solve(problem, method=self.optimizer, rng=rng, time_limit_s=self.time_limit_s,
                               max_iter=self.max_iter, local_search=self.local_search,
                               warm_start=self._warm_start() if len(flyable) == len(vehicles) else None)
            except InfeasibleError as exc:
                runtime += time.perf_counter() - t0
                stuck = [v for v in flyable if str(exc).startswith(f"vehicle {v.id} cannot reach home")]
                if stuck and len(flyable) > 1:
                    flyable.remove(stuck[0])
                    log.info("vehicle %s is left out of the looks: %s", stuck[0].id, exc)
                    continue
                if spare and stuck:  # nobody in the air can fly a look: they wait for fresh packs
                    for t in problem.targets:
                        if not self._defer_for_pack(problem, f"target {t.id} ", spare):
                            self._people[int(t.id)].gave_up = (
                                f"no vehicle has the energy for a look that could locate it, even on a fresh pack "
                                f"({getattr(exc, 'why', None) or exc})")
                    targets, result = [], None
                    break
                if spare and self._defer_for_pack(problem, str(exc), spare):
                    targets = self._targets(t_s, flyable, None)
                    continue
                if not self._drop_unreachable(problem, exc):
                    # no single person to blame (a vehicle cannot even get home): nobody can be
                    # looked at with the energy left, which a replan a tick later will not change
                    self._give_up_all(problem, str(exc))
                    targets, result = [], None
                    break
                targets = self._targets(t_s, flyable, None)
                continue
            runtime += time.perf_counter() - t0
            planned_times = {int(tid): float(ta) for r in result.plan.routes
                             for tid, ta in zip(r.target_ids, r.access_times_s)}
            rechecked = self._targets(t_s, flyable, planned_times, targets)
            shrunk = any(b.radius_m < RADIUS_RECHECK_FRACTION * a.radius_m for a, b in zip(targets, rechecked))
            if not shrunk:
                break
            problem = RoutingProblem(tuple(flyable), tuple(rechecked), self.speed_m_s, t0_s=t_s,
                                     power=self.scenario.power_model)
            t0 = time.perf_counter()
            try:
                result = solve(problem, method=self.optimizer, rng=rng, time_limit_s=self.time_limit_s,
                               max_iter=self.max_iter, local_search=self.local_search, warm_start=result.plan)
            except InfeasibleError:
                pass  # keep the first plan (its radii were a little optimistic)
            runtime += time.perf_counter() - t0
            break
        self.planner_runtime_s += runtime
        if not self.look_reports:
            # Without look reports a look counts as flown at its planned time. One whose time has
            # passed was flown: a replan must not erase it, or a vehicle that lands after each
            # look and is sent again (the simulator replans when all are home) has looks that are
            # never judged -- measured in `bench looks`: 90 such looks in a row, each a little
            # further off, over 1,100 s, before one was judged.
            for e, ta in self._awaiting.items():
                if ta <= t_s and e not in self._flown:
                    self._flown[e] = ta
        self._plan = orb.attach_orbits(self, self._to_search_plan(t_s, vehicles, result, runtime))
        if getattr(self, "coverage", None) is not None:  # cells below the POD target get another pass
            from .passes import add_passes

            self._plan = add_passes(self, t_s, vehicles, self._plan)
        self._awaiting = {e: ta for task in self._plan.tasks for e, ta in zip(task.target_ids, task.access_times_s)}
        self._unplanned = set(self.pending_ids()) - {e for task in self._plan.tasks for e in task.target_ids}
        self._look_vehicle = {e: task.vehicle_id for task in self._plan.tasks for e in task.target_ids}
        # looks already flown keep their pending judgment (self._flown) across the replan
        return self._plan

    def heard_until(self, vehicle, t_s: float) -> None:
        """``vehicle``'s receiver has reported everything it heard before ``t_s`` [s] (its keepalives,
        dialect.rssi). A look is judged only once the looking vehicle's reports cover it: a slot
        still on its way must not read as silence (issue 42: under load, looks were judged missed
        before their slots arrived, and people given up "not heard on 2 looks")."""
        v = int(vehicle)
        self._heard_until[v] = max(self._heard_until.get(v, -math.inf), float(t_s))

    def _reported_through(self, emitter_id: int, t_s: float) -> bool:
        """Whether the vehicle that looks at ``emitter_id`` has reported what it heard up to ``t_s``."""
        vid = self._look_vehicle.get(emitter_id)
        try:
            until = self._heard_until.get(int(vid)) if vid is not None else None
        except (TypeError, ValueError):
            until = None
        return until is None or until >= t_s

    def look_flown(self, emitter_id: int, t_s: float) -> None:
        """The vehicle planned to look at ``emitter_id`` passed its access point at ``t_s`` [s].

        The look is judged (heard or missed) from ``t_s``, and the same vehicle's later looks are
        re-based by its delay, so a vehicle running late (turns, climb, upload) is not taken for
        a miss. Unknown or already judged looks are ignored."""
        eid = int(emitter_id)
        if eid not in self._awaiting or eid in self._flown:
            return
        planned = self._awaiting.pop(eid)
        self._flown[eid] = float(t_s)
        delay = float(t_s) - planned
        if delay > 0:
            vid = self._look_vehicle.get(eid)
            for other, ta in self._awaiting.items():
                if self._look_vehicle.get(other) == vid and ta > planned:
                    self._awaiting[other] = ta + delay

    # -- internals -------------------------------------------------------------------------
    def _warm_start(self):
        if self._plan is None or not self.scenario.planner.warm_start:
            return None
        return self._plan.plan

    def _defer_for_pack(self, problem, message: str, spare: list) -> bool:
        """The target named in an InfeasibleError waits for a fresh pack if a vehicle with a spare
        pack could reach its look from home and come back on one (home -> look -> home within the
        pack's energy); False if none can, or no target is named."""
        from ..planning import RoutingProblem, VehicleState
        from ..planning.problem import check_reachable

        for t in problem.targets:
            if f"target {t.id} " not in message or int(t.id) in self._deferred:
                continue
            for v in spare:  # the vehicle at home on a fresh pack, alone with this target
                fresh = VehicleState(v.id, v.home_xy_m, v.home_xy_m, float(v.pack_energy_j))
                try:
                    check_reachable(RoutingProblem((fresh,), (t,), problem.speed_m_s, t0_s=problem.t0_s,
                                                   power=problem.power))
                except InfeasibleError:
                    continue
                self._deferred.add(int(t.id))
                log.info("emitter %s waits for a fresh pack (vehicle %s has %d)", t.id, v.id, v.spare_packs)
                return True
        return False

    def _drop_unreachable(self, problem, exc: InfeasibleError) -> bool:
        """Give up the target an InfeasibleError blames; False if it blames none. The person's
        reason says why in its own terms (the row names the person; no internal id)."""
        message = str(exc)
        for t in problem.targets:
            if getattr(exc, "target_id", None) == t.id or f"target {t.id} " in message:
                p = self._people[int(t.id)]
                p.gave_up = f"no vehicle has the energy for a look that could locate it ({exc.why or message})"
                log.info("emitter %s given up: %s", t.id, message)
                return True
        return False

    def _give_up_all(self, problem, message: str) -> None:
        for t in problem.targets:
            p = self._people[int(t.id)]
            p.gave_up = f"no vehicle has the energy left for a look ({message})"
        log.info("no look can be planned: %s", message)

    def _to_search_plan(self, t_s: float, vehicles: list, result, runtime: float) -> SearchPlan:
        tasks = []
        routes = {} if result is None else {r.vehicle_id: r for r in result.plan.routes}
        for v in vehicles:
            home = np.asarray(v.home_xy_m, dtype=float).reshape(1, 2)
            r = routes.get(v.id)
            if r is None or not len(r.target_ids):
                dur = float(np.linalg.norm(home[0] - np.asarray(v.start_xy_m, dtype=float))) / self.speed_m_s
                tasks.append(VehicleTask(v.id, home, (), t_s + dur))
                continue
            pts = np.vstack([self._inside_reach(np.asarray(r.access_points_xy_m, dtype=float).reshape(-1, 2)),
                             home])
            tasks.append(VehicleTask(v.id, pts, tuple(int(i) for i in r.target_ids), t_s + float(r.duration_s),
                                     tuple(float(a) for a in r.access_times_s)))
        makespan = max((task.eta_s for task in tasks), default=t_s) - t_s
        return SearchPlan(tuple(tasks), makespan, runtime, None if result is None else result.plan, t_s)
