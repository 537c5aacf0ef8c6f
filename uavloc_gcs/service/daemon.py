"""The closed-loop search over MAVLink: scan, localize, plan, upload, replan, bring everyone home.

Structure (every task owned by one ``asyncio.TaskGroup``; every network wait has a deadline)::

    connect all vehicles (heartbeat) -> upload every scan mission (verified) -> start them
    (or wait for the operator) -> concurrently:
      * per-vehicle RSSI/telemetry, in the links' receive path -> queue + store;
      * the brain: every tick, feed the new slots to the search policy, re-estimate, and once
        the scan is over replan from the vehicles' current positions and remaining energy
        whenever the policy asks or the set of usable vehicles changes (a vehicle lost or back);
        upload only the missions that changed; when everyone is located (or given up) send
        every airborne vehicle home;
      * the monitor: lost/found vehicles, mission phases, the live view.

Resume: the store keeps the epoch, the slots and every acknowledged mission; a restarted daemon
reloads the slots into the policy, downloads each vehicle's current mission, compares it with
the last one it uploaded, and carries on from there (see docs/guide/daemon.md for the measured
loss window).
"""

from __future__ import annotations

import asyncio
import functools
import logging
import math
import time
from typing import Callable, Sequence

import numpy as np

from ..errors import LinkError, UavlocError
from ..observations import SlotBatch
from ..scenario import Scenario
from ..sorties import minutes
from .clock import MissionClock
from .commands import STOP_WAIT_S, WAYPOINT_TOLERANCE_M, VehicleCommands
from .liveview import LiveView, StatusSnapshot, VehicleStatus, person_view
from .lost import LastHeard, last_heard
from .missionstate import ClockRate
from .options import DaemonOptions
from .outcome import SearchOutcome, estimate_row, final_results, statement_for
from .preparing import FleetPreparation
from .store import Store, StoreReader, TelemetryRow
from .swaps import PackSwaps
from .vehiclelife import VehicleLife as _Vehicle
from .vehiclelife import read_facts as read_life_facts

log = logging.getLogger(__name__)

REPLAN_BACKOFF_S = 10.0  # mission seconds before planning again after the planner failed
LAND_WAIT_S = 300.0  # mission seconds to wait at most for the fleet to land after sending it home
LANDING_MARGIN_S = 30.0  # beyond the flight home and the descent at LANDING_RATE_M_S
LANDING_RATE_M_S = 1.0
JOB_WAIT_S = 3.0  # wall seconds the brain waits for a vehicle's exchanges before leaving them to it
IDLE_END_S = 10.0  # mission seconds with every vehicle home and no look planned before the search ends
CLOCK_ANCHOR_S = 2.0  # host seconds between two (mission s, UTC) anchors of the clock map (service/clock.py)


PARTIAL_TEXT = "PARTIAL RESULTS: the search was stopped before its end."


def _idle(vehicles) -> bool:
    """Every vehicle home with no exchange under way (a look's upload being retried may still send
    it out: the search does not end under it)."""
    return all(v.home and v.job is None for v in vehicles)


class Daemon(FleetPreparation, VehicleCommands, PackSwaps):
    """One search. ``connections``: [(vehicle system id, connection string)]."""

    def __init__(self, scenario: Scenario, connections: Sequence[tuple[int, str]], options: DaemonOptions,
                 *, view: LiveView | None = None, policy=None, wall: Callable[[], float] = time.monotonic):
        from ..search.pod_plan import scan_for, scan_pod_plan  # noqa: PLC0415

        # the scan it flies: planned for search.pod_target (at the speed chosen for it) when the
        # scenario gives one, else [scan]'s; everything after plans with that speed
        self._scan_pod = scan_pod_plan(scenario)
        self._given_sc = scenario  # re-planned by _setup_vehicles if the vehicles fly slower
        scenario, self._scan_plan = scan_for(scenario)
        self.sc = scenario
        self.opt = options
        self.view = view
        self.wall = wall
        self.frame = scenario.frame
        self.vehicles = {vid: _Vehicle(vid, conn) for vid, conn in connections}
        if policy is None:
            from ..estimation import ChannelModel  # noqa: PLC0415
            from ..estimation.fitting import ProcessFitter  # noqa: PLC0415
            from ..search import SearchPolicy  # noqa: PLC0415

            # the fits run in a worker process: in this one they would hold the interpreter lock
            # and stop the links from being read (estimation/fitting.py)
            policy = SearchPolicy(scenario, model_motion=True, optimizer=scenario.planner.optimizer,
                                  local_search=scenario.planner.local_search, seed=scenario.planner.seed,
                                  time_limit_s=options.planner_time_limit_s,
                                  fitter=ProcessFitter(ChannelModel.from_scenario(scenario), scenario.dem))
        self.policy = policy
        if hasattr(policy, "look_flown"):
            policy.look_reports = True  # looks are judged from when the vehicle really passed them
            # where each vehicle listened is known only from the slots it heard (SLOT_TRACK_QUIET_S);
            # under a receiver threshold (the field world) from its telemetry (_on_position): a
            # silence is evidence there only while some vehicle heard a burst, and bursts are sparse
            policy.tracks_from_slots = scenario.channel.receiver_sensitivity_dbm is None
        from ..search.coverage import attach  # noqa: PLC0415

        self.coverage = attach(scenario, policy)  # what was flown within hearing (search/coverage.py)
        self.store: Store | None = None
        self.epoch_unix_s: float | None = None
        self._slots_in: list[SlotBatch] = []
        self._n_slots = 0
        self._replans = 0
        self._last_fleet: frozenset | None = None
        self._finishing_since: float | None = None  # mission time of "done" (everyone sent home)
        self._time_up_s: float | None = None  # mission time the search's time limit was reached at
        self._idle_since: float | None = None  # mission time since which nobody flies and nothing is sent
        self._stop = asyncio.Event()
        self._rate = ClockRate()
        self._last_tel_store: dict[int, float] = {}
        self._people_cache: list = []
        self._seq_before_crash: dict[int, int] = {}
        self._planner_limit_s = getattr(policy, "time_limit_s", None)
        self._replan_not_before_s = -math.inf
        self._replan_due = False  # a vehicle with a plan not uploaded has passed a look
        self._ground_clock = False  # no vehicle gave its time: the mission clock is the ground's
        self._return_speed_m_s = scenario.fleet.speed_m_s  # RTL speed (the landing wait)
        self._rssi_links: list = []
        self.on_mission_acked: Callable[[int, str], None] | None = None
        self.stop_report: list[str] = []  # what each vehicle does, when the daemon was stopped
        self._job_crash: BaseException | None = None  # a vehicle task's unexpected error, for the brain
        self._finish_wall = -math.inf  # wall time the fleet was sent home
        self.partial_outcome: SearchOutcome | None = None  # the results so far, once stopped before the end
        self._clock_anchors: list[tuple[float, float]] = []  # (mission s, host UNIX s): clock()

    # -- clock ---------------------------------------------------------------------------------
    def now_s(self) -> float:
        """Mission time [s since the epoch]: the vehicles' newest clock, extrapolated."""
        if self.epoch_unix_s is None:
            return 0.0
        if self._ground_clock:
            return time.time() - self.epoch_unix_s
        best = -math.inf
        w = self.wall()
        for v in self.vehicles.values():
            t = v.agent.tel if v.agent else None
            if t is not None and t.unix_s is not None:
                best = max(best, t.unix_s + (w - t.unix_wall_s) * self._rate.rate)
        return (best - self.epoch_unix_s) if math.isfinite(best) else 0.0

    def clock(self) -> MissionClock:
        """Mission time to UTC (service/clock.py): the vehicles' clock when it ran in real time, else
        (a simulator's speed-up) this computer's clock at the moments the vehicles were there."""
        return MissionClock.of(self.epoch_unix_s, self._clock_anchors)

    def _anchor_clock(self) -> None:
        if self.epoch_unix_s is None or not any(v.agent is not None and v.agent.tel.unix_s is not None
                                                for v in self.vehicles.values()):
            return
        now = time.time()
        if not self._clock_anchors or now - self._clock_anchors[-1][1] >= CLOCK_ANCHOR_S:
            self._clock_anchors.append((self.now_s(), now))

    def _epoch(self) -> float | None:
        if self.epoch_unix_s is None:
            for v in self.vehicles.values():
                if v.agent is not None and v.agent.tel.unix_s is not None:
                    self.epoch_unix_s = float(math.floor(v.agent.tel.unix_s))
                    self.store.set_meta("epoch_unix_s", self.epoch_unix_s)
                    break
        return self.epoch_unix_s

    # -- events ----------------------------------------------------------------------------------
    def _event(self, kind: str, text: str, vehicle: int | None = None, *, view_text: str | None = None) -> None:
        """Log and store an event and show it on the console view (``view_text`` instead, if given)."""
        t = self.now_s()
        log.info("%s: %s", kind, text)
        if self.store is not None:
            self.store.add_event(kind, text, t_s=t, vehicle=vehicle)
        if self.view is not None:
            self.view.event(text if view_text is None else view_text, t)

    # -- entry point -------------------------------------------------------------------------------
    async def run(self) -> SearchOutcome:
        self.store = Store(self.opt.store_path)
        try:
            resumed = self._reload()
            self.store.set_meta("on_stop", self.opt.on_stop)
            await self._connect_all()
            try:
                # the monitor follows every vehicle from the start: one vehicle's slow start must
                # not hide another's scan finishing
                monitor = asyncio.create_task(self._monitor(), name="monitor")
                try:
                    try:
                        await self._prepare_all(resumed)
                        await self._brain()
                    finally:
                        self._stop.set()
                        await self._cancel_jobs()
                        await monitor  # ends at the next tick (raises what broke it, if anything)
                except asyncio.CancelledError:  # stopped by the operator (Ctrl-C, SIGTERM)
                    self.stop_report = await self._stopping()
                    # the results so far, for the files (service/run.py): the store stays resumable
                    self.partial_outcome = self._outcome(partial=PARTIAL_TEXT)
                    raise
                return self._outcome()
            finally:
                await self._close_links()
        finally:
            close = getattr(self.policy, "close", None)
            if close is not None:
                close()  # a fit under way is not waited for
            self.store.close()

    # -- start-up --------------------------------------------------------------------------------
    # -- each vehicle's exchanges run in its own task; the brain waits for them only so long -------
    def _launch(self, v: _Vehicle, coro) -> asyncio.Task:
        task = asyncio.ensure_future(coro)
        v.job, v.job_late = task, False
        task.add_done_callback(functools.partial(self._job_done, v))
        return task

    def _job_done(self, v: _Vehicle, task: asyncio.Task) -> None:
        if v.job is task:
            v.job = None
        if task.cancelled():
            return
        exc = task.exception()
        if isinstance(exc, LinkError):
            self._mark_unusable(v, exc)  # the fleet changed: the next tick replans without it
        elif isinstance(exc, UavlocError):
            self._event("error", str(exc), v.id)
        elif exc is not None:
            self._job_crash = exc
            return
        if v.job_late:
            self._replan_due = True  # it ended after the brain moved on: plan with what it does now

    async def _jobs(self, pairs: list, wait_s: float = JOB_WAIT_S) -> None:
        """Start each (vehicle, exchange) in the vehicle's own task and wait at most ``wait_s`` for
        them: a vehicle whose exchange is slow (retries, judgement) keeps it, the others go on."""
        tasks = [self._launch(v, coro) for v, coro in pairs]
        if tasks:
            _done, pending = await asyncio.wait(tasks, timeout=wait_s)
            for v, _ in pairs:
                if v.job is not None and v.job in pending:
                    v.job_late = True
        self._raise_job_crash()

    def _raise_job_crash(self) -> None:
        if self._job_crash is not None:
            crash, self._job_crash = self._job_crash, None
            raise crash

    async def _cancel_jobs(self) -> None:
        tasks = [v.job for v in self.vehicles.values() if v.job is not None]
        for t in tasks:
            t.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)

    async def _each(self, job, vehicles: list[_Vehicle]) -> None:
        """Run ``job(v)`` for every vehicle concurrently; a vehicle whose job fails with a link
        error is marked unusable (the others carry on); any other error ends the search."""
        results = await asyncio.gather(*(job(v) for v in vehicles), return_exceptions=True)
        for v, r in zip(vehicles, results):
            if isinstance(r, LinkError):
                self._mark_unusable(v, r)
            elif isinstance(r, BaseException):
                raise r

    # -- exchanges, judged from what the vehicle then reports (lifecycle.persist) --------------------
    # -- receive path callbacks ------------------------------------------------------------------------
    def _on_slots(self, batch: SlotBatch) -> None:
        self._slots_in.append(batch)
        self.store.add_slots(batch)

    def _on_position(self, vehicle: int, tel) -> None:
        self._rate.observe(tel)
        self.coverage.add_telemetry(vehicle, self.now_s(), tel.lat_deg, tel.lon_deg, tel.rel_alt_m)
        if self.wall() - self._last_tel_store.get(vehicle, -math.inf) >= 0.1:
            self._store_telemetry(vehicle, tel)
        if self.sc.channel.receiver_sensitivity_dbm is not None and hasattr(self.policy, "ingest_position"):
            e, n = self.frame.to_local(tel.lat_deg, tel.lon_deg)
            self.policy.ingest_position(vehicle, self.now_s(), (float(e), float(n), float(tel.rel_alt_m)))

    def _on_mission_seq(self, vehicle: int, tel) -> None:
        # at once, whatever the rate limit: a restart resumes the scan from the last item stored,
        # which must not lag the vehicle (before the first position there is nothing to store)
        if math.isfinite(tel.lat_deg):
            self._store_telemetry(vehicle, tel)

    def _store_telemetry(self, vehicle: int, tel) -> None:
        """One telemetry row (from positions at most ten a second; :meth:`_on_mission_seq`)."""
        self._last_tel_store[vehicle] = self.wall()
        self.store.add_telemetry([TelemetryRow(self.now_s(), vehicle, tel.lat_deg, tel.lon_deg, tel.rel_alt_m,
                                               tel.battery_pct, tel.mode, tel.mission_seq, self.vehicles[vehicle].lost)])

    def _on_text(self, vehicle: int, text: str) -> None:
        self.store.add_event("statustext", text, t_s=self.now_s(), vehicle=vehicle)

    # -- the monitor: lost/found, phases, live view ---------------------------------------------------
    async def _monitor(self) -> None:
        while not self._stop.is_set():
            self._anchor_clock()
            for v in self.vehicles.values():
                self._update_phase(v)
            self._save_sorties()  # sorties: kept in the store when they change (a restart resumes them)
            if self.view is not None:
                self.view.update(self.snapshot())
            await asyncio.sleep(self.opt.tick_s)

    def _update_phase(self, v: _Vehicle) -> None:
        """One step of ``v``'s state machine on the facts read now (service/vehiclelife.py)."""
        if v.agent is None:
            return
        for kind, text in v.observe(read_life_facts(v.agent), self.wall(), self.opt.lost_timeout_s, self._home_by):
            if kind == "lost":  # what it said last, kept for the statement, the files and the map
                v.last_heard = self._last_heard(v)
                if v.last_heard.airborne:
                    text += f"; LOST IN THE AIR: last heard at {v.last_heard.when()}, {v.last_heard.where()}"
            elif kind == "found":
                v.last_heard = None
            self._event(kind, text, v.id)
        self._pack_step(v)  # sorties: home at its reserve, it waits for a fresh pack (service/swaps.py)

    def _last_heard(self, v: _Vehicle) -> LastHeard:
        return last_heard(v.id, v.agent, self.frame, now_s=self.now_s(), wall_now_s=self.wall(),
                          unix_now_s=time.time(), clock_rate=self._rate.rate)

    def _home_by(self, v: _Vehicle) -> float:
        """Mission time by which ``v``, flying home from where it is now, should have landed."""
        xy = v.agent.position_xy_m() or (0.0, 0.0)
        alt = v.agent.tel.rel_alt_m if math.isfinite(v.agent.tel.rel_alt_m) else self.sc.fleet.altitude_m
        return self.now_s() + math.hypot(*xy) / self._return_speed_m_s + alt / LANDING_RATE_M_S + LANDING_MARGIN_S

    def _returning(self, v: _Vehicle) -> None:
        v.returning(self._home_by(v))

    def snapshot(self) -> StatusSnapshot:
        t = self.now_s()
        vs = [VehicleStatus(v.id, f"waiting for {v.waiting}" if v.waiting else v.phase,
                            v.agent.tel.mode if v.agent else "?",
                            v.agent.tel.battery_pct if v.agent else None,
                            v.agent.tel.mission_seq if v.agent else None, v.end_seq or None, v.lost,
                            v.last_heard.sentence() if v.lost and v.last_heard is not None and v.last_heard.airborne
                            else "")
              for v in self.vehicles.values()]
        people = [person_view(p) for p in self._people_cache]
        return StatusSnapshot(t, vs, people, self._n_slots, self.sc.people.required_accuracy_m, self._replans)

    # -- the brain ---------------------------------------------------------------------------------------
    async def _brain(self) -> None:
        try:
            while True:
                await asyncio.sleep(self.opt.tick_s)
                self._raise_job_crash()
                t = self.now_s()
                if self._slots_in:
                    batches, self._slots_in = self._slots_in, []
                    new = SlotBatch.concat(batches)
                    self._n_slots += len(new)
                    self.policy.ingest(new)
                self._tell_heard_until()
                self._report_looks(t)
                changed = await asyncio.to_thread(self.policy.update, t)
                self._report_looks(self.now_s())  # passed during the update, before anything acts on it
                people = self.policy.people(t)
                self._people_cache = people
                if changed:
                    by_id = {p.emitter_id: p for p in people}
                    self.store.add_estimates([estimate_row(by_id[e], t) for e in sorted(changed) if e in by_id])
                if await self._step(t, changed):
                    return
        finally:
            self._stop.set()

    def _tell_heard_until(self) -> None:
        """Tell the policy up to when each vehicle's receiver has reported everything it heard (only
        receivers that send keepalives: for the others silence cannot be told from delay). Read in
        the same step as the slots taken before it: every slot before that time is in the policy."""
        tell = getattr(self.policy, "heard_until", None)
        if tell is None:
            return
        for v in self.vehicles.values():
            if v.agent is not None and v.agent.keepalives:
                tell(v.id, v.agent.heard_until_s)

    def _report_looks(self, t: float) -> None:
        """Tell the policy which looks the vehicles have flown: a look waypoint is flown once the
        mission has moved past it (MISSION_CURRENT) or the vehicle is within WAYPOINT_TOLERANCE_M
        of it. A look passed also re-opens the vehicle to one more upload (search/uploads.py)."""
        for v in self._active():
            self._report_vehicle_looks(v, t)

    def _report_vehicle_looks(self, v: _Vehicle, t: float) -> None:
        """:meth:`_report_looks` for one vehicle. Also called, with the state read then, just before
        its look mission is replaced or it is sent home: a look passed since the brain last looked
        (a policy update can take 20 s of CPU over terrain) was otherwise lost with the mission, and
        the policy said "look not flown ...; planned again" of a look the vehicle had flown."""
        report = getattr(self.policy, "look_flown", None)
        if v.agent is None or v.purpose != "look" or v.look_xy_m is None or self.wall() < v.ignore_seq_until_wall:
            return
        seq = v.agent.tel.mission_seq
        passed = 0 if seq is None else (sum(k < seq for k in v.look_seqs) if v.look_seqs else
                                         int(np.clip(seq - v.look_first_seq, 0, len(v.look_xy_m))))
        xy = v.agent.position_xy_m()
        if passed < len(v.look_xy_m) and xy is not None and \
                math.dist(xy, v.look_xy_m[passed]) <= WAYPOINT_TOLERANCE_M:
            passed += 1
        while v.looks_reported < min(passed, len(v.targets)):  # (then passes: search/coverage.py)
            if report is not None:
                report(v.targets[v.looks_reported], t)
            v.looks_reported += 1
            v.uploads_since_look = 0
            if v.deferred:
                self._replan_due = True  # a plan it was not given can be uploaded now

    def _active(self) -> list[_Vehicle]:
        """The usable vehicles: in contact and commandable."""
        return [v for v in self.vehicles.values() if not v.lost and v.agent is not None and not v.unusable]

    async def _step(self, t: float, changed: set) -> bool:
        """One decision; True when the search is over."""
        active = self._active()
        if not active:
            why = "; ".join(f"vehicle {v.id} {'lost' if v.lost else 'unusable'}" for v in self.vehicles.values())
            self._event("end", f"no vehicle is usable ({why}); stopping the search")
            return True
        if t > self.opt.max_mission_s:
            self._event("end", f"mission time limit {self.opt.max_mission_s:g} s reached")
            return True
        limit = self.sc.search.time_limit_s
        if self._time_up_s is not None or (limit is not None and t >= limit):
            return await self._finish(time_up=True)
        starting = [v for v in active if v.job is not None and v.phase in ("starting", "uploading scan")]
        active = [v for v in active if v not in starting]  # planned for once started (replan then)
        waiting = [v for v in active if v.waiting]  # on the ground for a fresh pack: planned for once ready
        active = [v for v in active if not v.waiting]
        if not active:  # (all waiting for packs: the search ends only when it is done)
            return bool(waiting) and self.policy.done(t) and await self._finish()
        if not all(v.scan_done or v.home for v in active):
            return False
        if self.policy.done(t):
            return await self._finish()
        fleet = frozenset(v.id for v in active)
        usable = active
        if _idle(active) and self._idle_since is None:
            # Nobody is flying, people are still pending: plan once more with the whole fleet on
            # the ground. Without it a look flown and judged a miss, with nothing else changing,
            # ended the search with the person unlooked-at and no reason given.
            self._idle_since = t
            self._replan_due = True
        if (self.policy.needs_replan(t, changed) or fleet != self._last_fleet or self._replan_due) \
                and t >= self._replan_not_before_s:
            self._last_fleet = fleet
            self._replan_due = False
            await self._replan(t, usable)
        if _idle(active):  # (again: the replan may have sent vehicles out)
            if self._idle_since is not None and t - self._idle_since > IDLE_END_S and not self._replan_due \
                    and not waiting:
                pending = [str(p.emitter_id) for p in self.policy.people(t) if not p.located]
                self._event("end", "every vehicle is home and no look could be planned for person(s) "
                            f"{', '.join(pending) or '-'}: stopping the search")
                return True
        else:
            self._idle_since = None
        return False

    async def _replan(self, t: float, vehicles: list[_Vehicle]) -> None:
        if not vehicles:
            return
        states = [self._vehicle_state(v) for v in vehicles]
        if self.opt.planner_time_limit_s is None and self._planner_limit_s is not None:
            # under a speed-up, a second of planning is many seconds of flight: keep it ~2 mission s
            self.policy.time_limit_s = min(self._planner_limit_s, max(0.05, 2.0 / self._rate.rate))
        w0 = self.wall()
        try:
            plan = await asyncio.to_thread(self.policy.replan, t, states)
        except UavlocError as exc:  # keep flying the current missions; try again a little later
            self._replan_not_before_s = t + REPLAN_BACKOFF_S
            self._event("error", f"planning failed ({exc}); the vehicles keep their missions, retrying in "
                        f"{REPLAN_BACKOFF_S:g} s")
            return
        self._replans += 1
        self.store.add_plan(t, {"t_s": t, "makespan_s": plan.makespan_s, "runtime_s": plan.planner_runtime_s,
                                "wall_s": self.wall() - w0, "time_limit_s": getattr(self.policy, "time_limit_s", None),
                                "clock_rate": self._rate.rate,
                                "tasks": [{"vehicle": task.vehicle_id, "targets": list(task.target_ids),
                                           "waypoints_xy_m": np.asarray(task.waypoints_xy_m).tolist(),
                                           "access_times_s": list(task.access_times_s),
                                           "eta_s": task.eta_s} for task in plan.tasks]})
        jobs = []
        for task in plan.tasks:
            v = self.vehicles[int(task.vehicle_id)]
            pts = np.asarray(task.waypoints_xy_m, dtype=float).reshape(-1, 2)[:-1]  # last row is home
            if v.job is not None:
                continue  # still busy with an earlier exchange; planned again when it ends
            if len(pts) == 0:
                if not v.phase.startswith("returning") and not v.home:
                    jobs.append((v, self._send_home(v)))
                continue
            decision = self._worth_uploading(v, pts, tuple(task.target_ids))
            if not decision.upload:
                if decision.reason != "unchanged":
                    v.skipped += 1
                    v.deferred = True  # plan again once it has passed its next look
                    self._event("plan", f"vehicle {v.id}: new plan not uploaded ({decision.reason})", v.id)
                continue
            v.plans += 1
            v.deferred = False
            if decision.reason != "first look mission":  # it replaces looks in flight: a restarted leg
                v.uploads_since_look += 1
            jobs.append((v, self._upload_look(v, pts, tuple(task.target_ids))))
        self._save_counts()
        await self._jobs(jobs)

    async def _finish(self, time_up: bool = False) -> bool:
        """Send everyone home once the search is done or its time is up ([search] time_limit_s: no
        look is planned after it, whatever is pending); True once they are home or overdue."""
        if self._finishing_since is None:
            self._finishing_since = self.now_s()
            self._finish_wall = self.wall()
            if time_up:
                self._time_up_s = self._finishing_since
                self._event("done", f"the search's time limit ({minutes(self.sc.search.time_limit_s)}, "
                            "search.time_limit_s) is reached: no more looks; all vehicles return home")
            else:
                self._event("done", "every person heard is located or given up: all vehicles return home")
            # Whatever a vehicle was being told (a look's upload or start) is moot now, also for a
            # vehicle on the ground: left running, a start whose ACK is late sends it out again.
            moot = [v.job for v in self._active() if v.job is not None]
            for job in moot:
                job.cancel()
            if moot:
                await asyncio.wait(moot, timeout=JOB_WAIT_S)
        # Every call, not only the first: a vehicle can be airborne again after "done" (a start
        # that was on its way when its exchange was cancelled); it is sent home like the others.
        going = [v for v in self._active() if v.job is None and not v.home and not v.phase.startswith("returning")]
        if going:
            await self._jobs([(v, self._send_home(v)) for v in going])
        if any(v.job is not None for v in self._active()) and self.wall() - self._finish_wall < STOP_WAIT_S:
            return False  # a return-home exchange is still being retried: its outcome goes in the statement
        now = self.now_s()
        if all(v.home or (v.phase == "returning" and now > v.home_by_s) for v in self._active()):
            return True  # landed, or returning and overdue: report them as returning
        return now - self._finishing_since > LAND_WAIT_S

    # -- the end ------------------------------------------------------------------------------------------
    def _outcome(self, partial: str = "") -> SearchOutcome:
        t = self.now_s()
        self.store.flush()
        with StoreReader(self.opt.store_path) as rd:
            slots = rd.slots()
        # stopped (Ctrl-C): the policy's beliefs as they are, without waiting for refits; the field
        # world's grid estimates are the policy's own last word (a refit would be another model's)
        grid = getattr(self.policy, "_grid_spec", lambda: None)() is not None
        people = tuple(final_results(self.policy.people(t), slots, self.sc, self.frame,
                                     linking=getattr(self.policy, "linking", None), refit=not (partial or grid)))
        lost = tuple(v.id for v in self.vehicles.values() if v.lost)
        in_air = tuple(v.last_heard for v in self.vehicles.values()
                       if v.lost and v.last_heard is not None and v.last_heard.airborne)
        returning = tuple(v.id for v in self.vehicles.values() if not v.home and not v.lost and v.phase == "returning")
        other = tuple(v.id for v in self.vehicles.values() if not v.home and not v.lost and v.phase != "returning")
        text = statement_for(people, self.sc.people.required_accuracy_m, lost, other, returning, lost_in_air=in_air,
                             fleet=not partial)  # stopped: the stop report says what each vehicle does
        unflown = [v for v in self.vehicles.values() if v.start_failed and not v.scan_done]
        for v in unflown:  # a refused start is no scan flown: say so, whatever else is said
            text += f" Vehicle {v.id} did not fly its scan ({v.start_failed}); its part of the area was not searched."
        if self._time_up_s is not None:
            text += (f" The search's time limit ({minutes(self.sc.search.time_limit_s)}, search.time_limit_s) was "
                     f"reached at {self._time_up_s / 60.0:.1f} min of search: no look was planned after it.")
        if self.sc.fleet.batteries > 1:
            text += " " + self._packs_text()
        if partial:
            text = f"{partial} {text}"
        text = " ".join([*(x.sentence() for x in in_air), text])  # a vehicle lost in the air is said first
        # the statement is said once on the console: after the table when a report follows it
        # (service.run.run_search), here otherwise
        follows = not partial and getattr(self.view, "report_follows", False)
        self._event("end", text, view_text="the search has ended; the results follow" if follows else None)
        if not partial:  # a search stopped before its end can be resumed
            self.store.set_meta("finished", True)
        self.store.flush()
        per_vehicle = tuple((v.id, v.plans, v.uploads, v.skipped) for v in self.vehicles.values())
        self.store.set_meta("uploads", [list(row) for row in per_vehicle])
        self.store.set_meta("clock_anchors", [list(a) for a in self._clock_anchors])
        self._event("end", "replans " + str(self._replans) + "; per vehicle (plans for it, uploads incl. the scan, "
                    "plans not uploaded): " + ", ".join(f"{vid}: {pl}/{up}/{sk}" for vid, pl, up, sk in per_vehicle))
        return SearchOutcome(people, bool(people) and all(p.located for p in people), text, t, self._replans,
                             tuple(v.id for v in self.vehicles.values() if v.home), lost, returning, per_vehicle,
                             partial=partial, lost_in_air=in_air)
