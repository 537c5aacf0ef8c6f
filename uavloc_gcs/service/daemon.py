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
the last one it uploaded, and carries on from there (see docs/readme/daemon.md for the measured
loss window).
"""

from __future__ import annotations

import asyncio
import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..errors import ConfigError, LinkError, UavlocError
from ..mission import NAV_WAYPOINT, flight_mission, to_wire
from ..observations import SlotBatch
from ..scenario import Scenario
from .liveview import LiveView, StatusSnapshot, VehicleStatus, person_view
from .missionstate import ClockRate, final_seq, same_route, same_stored_mission, without_final_rtl
from .outcome import SearchOutcome, estimate_row, final_results, statement_for
from .store import Store, StoreReader, TelemetryRow
from .vehicle import VehicleAgent

log = logging.getLogger(__name__)

MISSION_STATE_COMPLETE = 5
WAYPOINT_TOLERANCE_M = 10.0
REPLAN_BACKOFF_S = 10.0  # mission seconds before planning again after the planner failed  # a replanned look this close to the uploaded one is "unchanged"
LAND_WAIT_S = 300.0  # mission seconds to wait at most for the fleet to land after sending it home
LANDING_MARGIN_S = 30.0  # beyond the flight home and the descent at LANDING_RATE_M_S
LANDING_RATE_M_S = 1.0


@dataclass(frozen=True)
class DaemonOptions:
    store_path: Path
    start: str = "auto"  # "auto" or "operator"
    signing_key: bytes | None = None
    tlog_dir: Path | None = None
    lost_timeout_s: float = 5.0  # wall seconds of silence before a vehicle is lost
    connect_timeout_s: float = 15.0
    planner_time_limit_s: float | None = None  # None: the scenario's, capped to ~2 s of mission time
    tick_s: float = 0.05
    source_system: int = 255
    max_mission_s: float = 4 * 3600.0
    resume: bool = True


@dataclass
class _Vehicle:
    id: int
    connection: str
    link: object = None
    agent: VehicleAgent | None = None
    phase: str = "connecting"
    purpose: str = ""  # "scan" | "look" | "home"
    mission: list = field(default_factory=list)  # acknowledged wire items
    end_seq: int = 0  # seq of the final RTL item of the current mission
    targets: tuple = ()
    look_xy_m: np.ndarray | None = None
    look_first_seq: int = 0  # wire seq of the first look waypoint
    looks_reported: int = 0  # looks of the current mission reported flown to the policy
    lost: bool = False
    scan_done: bool = False
    home: bool = False
    ignore_seq_until_wall: float = 0.0
    home_by_s: float = math.inf  # mission time by which a returning vehicle should have landed


class Daemon:
    """One search. ``connections``: [(vehicle system id, connection string)]."""

    def __init__(self, scenario: Scenario, connections: Sequence[tuple[int, str]], options: DaemonOptions,
                 *, view: LiveView | None = None, policy=None, wall: Callable[[], float] = time.monotonic):
        self.sc = scenario
        self.opt = options
        self.view = view
        self.wall = wall
        self.frame = scenario.frame
        self.vehicles = {vid: _Vehicle(vid, conn) for vid, conn in connections}
        if policy is None:
            from ..search import SearchPolicy  # noqa: PLC0415

            policy = SearchPolicy(scenario, model_motion=True, optimizer=scenario.planner.optimizer,
                                  local_search=scenario.planner.local_search, seed=scenario.planner.seed,
                                  time_limit_s=options.planner_time_limit_s)
        self.policy = policy
        if hasattr(policy, "look_flown"):
            policy.look_reports = True  # looks are judged from when the vehicle really passed them
        self.store: Store | None = None
        self.epoch_unix_s: float | None = None
        self._slots_in: list[SlotBatch] = []
        self._n_slots = 0
        self._replans = 0
        self._last_fleet: frozenset | None = None
        self._finishing_since: float | None = None
        self._stop = asyncio.Event()
        self._rate = ClockRate()
        self._last_tel_store: dict[int, float] = {}
        self._people_cache: list = []
        self._seq_before_crash: dict[int, int] = {}
        self._planner_limit_s = getattr(policy, "time_limit_s", None)
        self._replan_not_before_s = -math.inf
        self.on_mission_acked: Callable[[int, str], None] | None = None

    # -- clock ---------------------------------------------------------------------------------
    def now_s(self) -> float:
        """Mission time [s since the epoch]: the vehicles' newest clock, extrapolated."""
        if self.epoch_unix_s is None:
            return 0.0
        best = -math.inf
        w = self.wall()
        for v in self.vehicles.values():
            t = v.agent.tel if v.agent else None
            if t is not None and t.unix_s is not None:
                best = max(best, t.unix_s + (w - t.unix_wall_s) * self._rate.rate)
        return (best - self.epoch_unix_s) if math.isfinite(best) else 0.0

    def _epoch(self) -> float | None:
        if self.epoch_unix_s is None:
            for v in self.vehicles.values():
                if v.agent is not None and v.agent.tel.unix_s is not None:
                    self.epoch_unix_s = float(math.floor(v.agent.tel.unix_s))
                    self.store.set_meta("epoch_unix_s", self.epoch_unix_s)
                    break
        return self.epoch_unix_s

    # -- events ----------------------------------------------------------------------------------
    def _event(self, kind: str, text: str, vehicle: int | None = None) -> None:
        t = self.now_s()
        log.info("%s: %s", kind, text)
        if self.store is not None:
            self.store.add_event(kind, text, t_s=t, vehicle=vehicle)
        if self.view is not None:
            self.view.event(text, t)

    # -- entry point -------------------------------------------------------------------------------
    async def run(self) -> SearchOutcome:
        self.store = Store(self.opt.store_path)
        try:
            resumed = self._reload()
            await self._connect_all()
            try:
                await self._prepare_all(resumed)
                async with asyncio.TaskGroup() as tg:
                    tg.create_task(self._monitor(), name="monitor")
                    tg.create_task(self._brain(), name="brain")
                return self._outcome()
            finally:
                await self._close_links()
        finally:
            self.store.close()

    async def _close_links(self) -> None:
        links = []
        for v in self.vehicles.values():
            if v.agent is not None:
                v.agent.close()
            if v.link is not None and all(v.link is not other for other in links):
                links.append(v.link)
        for link in links:
            await link.close()

    # -- start-up --------------------------------------------------------------------------------
    def _reload(self) -> dict:
        """Reload a previous run's state from the store; {vehicle: (purpose, items)} or {}."""
        if not self.opt.resume or not self.opt.store_path.exists():
            self.store.set_meta("scenario", self.sc.name)
            return {}
        with StoreReader(self.opt.store_path) as rd:
            meta = rd.meta()
            if "epoch_unix_s" not in meta:
                self.store.set_meta("scenario", self.sc.name)
                return {}
            if meta.get("finished"):
                raise ConfigError(f"{self.opt.store_path} holds a search that already finished; "
                                  "start a new one with --fresh or another --out")
            if meta.get("scenario") != self.sc.name:
                raise UavlocError(f"the store {self.opt.store_path} holds the search '{meta.get('scenario')}', "
                                  f"not '{self.sc.name}'; use another --store or --fresh")
            self.epoch_unix_s = float(meta["epoch_unix_s"])
            slots = rd.slots()
            missions = rd.latest_missions()
            self._seq_before_crash = rd.last_mission_seq()
        self.policy.ingest(slots)
        self._n_slots = len(slots)
        self._event("resume", f"resuming the search: {len(slots)} slots and {len(missions)} missions reloaded")
        return missions

    async def _connect_all(self) -> None:
        from ..link.connection import open_link  # noqa: PLC0415

        # Vehicles that share a connection (a router, a multipoint radio) share one link.
        by_conn: dict[str, list[_Vehicle]] = {}
        for v in self.vehicles.values():
            by_conn.setdefault(v.connection, []).append(v)
        opened: dict[str, asyncio.Future] = {}

        async def open_one(conn: str, group: list[_Vehicle]):
            tlog = None
            if self.opt.tlog_dir is not None:
                Path(self.opt.tlog_dir).mkdir(parents=True, exist_ok=True)
                tlog = Path(self.opt.tlog_dir) / f"uav{'-'.join(str(v.id) for v in group)}.tlog"
            return await open_link(conn, source_system=self.opt.source_system,
                                   signing_key=self.opt.signing_key, tlog_path=tlog)

        async def connect(v: _Vehicle) -> None:
            if v.connection not in opened:
                opened[v.connection] = asyncio.ensure_future(open_one(v.connection, by_conn[v.connection]))
            v.link = await opened[v.connection]
            v.agent = VehicleAgent(v.id, v.link, self.frame, autopilot=self.sc.fleet.autopilot,
                                   epoch_unix_s=self._epoch, on_slots=self._on_slots,
                                   on_position=self._on_position, on_status_text=self._on_text, wall=self.wall)
            await v.link.wait_heartbeat(v.id, timeout_s=self.opt.connect_timeout_s)
            v.phase = "connected"

        results = await asyncio.gather(*(connect(v) for v in self.vehicles.values()), return_exceptions=True)
        bad = [(v, r) for v, r in zip(self.vehicles.values(), results) if isinstance(r, BaseException)]
        if bad:
            await self._close_links()
            for _, r in bad:
                if not isinstance(r, Exception):
                    raise r
            names = ", ".join(f"{v.id} ({v.connection})" for v, _ in bad)
            first = next((r for _, r in bad if not isinstance(r, LinkError)), bad[0][1])
            if all(isinstance(r, LinkError) for _, r in bad):
                raise LinkError(f"no heartbeat within {self.opt.connect_timeout_s:g} s from vehicle(s) {names}; "
                                "check that they are powered and the connection strings in [link] are right",
                                operation="connect")
            raise first
        for v in self.vehicles.values():
            self._event("connect", f"vehicle {v.id} connected on {v.connection}", v.id)
        # wait for a clock (SYSTEM_TIME) so slot times have an epoch
        deadline = self.wall() + self.opt.connect_timeout_s
        while self._epoch() is None and self.wall() < deadline:
            await asyncio.sleep(0.05)
        if self.epoch_unix_s is None:
            raise LinkError("no vehicle sent SYSTEM_TIME; the search needs the vehicles' clock", operation="connect")

    async def _prepare_all(self, resumed: dict) -> None:
        """Upload every scan (or re-adopt the missions found after a restart), then start."""
        from ..scan import plan_scan, scan_missions  # noqa: PLC0415

        # The scan ends hovering at its last waypoint (no RTL): the adaptive phase starts from
        # there, as the experiments model it; the autopilot's own link-loss failsafe still applies.
        scans = [without_final_rtl(m) for m in scan_missions(self.sc, plan_scan(self.sc))]
        ap = self.sc.fleet.autopilot
        wires = {vid: to_wire(m, ap) for vid, m in zip(sorted(self.vehicles), scans)}
        to_start = []

        async def prepare(v: _Vehicle) -> None:
            previous = resumed.get(v.id)
            if previous is not None:
                on_board = await v.agent.download()
                purpose, items = previous
                if same_stored_mission(on_board, items, v.agent.flavour):
                    self._adopt(v, purpose, items)
                    v.scan_done = purpose != "scan"
                    if not v.agent.tel.armed and v.agent.on_ground() and purpose != "scan":
                        v.home, v.phase = True, "landed"
                    self._event("resume", f"vehicle {v.id} still flies its {purpose} mission "
                                f"(item {v.agent.tel.mission_seq})", v.id)
                    if v.agent.tel.armed:
                        if purpose == "scan":
                            await self._rewind_scan(v, items)
                        return
                    if purpose == "scan" and v.agent.on_ground():
                        to_start.append(v)
                    return
                self._event("resume", f"vehicle {v.id}: mission on board differs from the stored one", v.id)
                if purpose != "scan" or v.agent.tel.armed:
                    await self._upload(v, purpose, items, first_seq=None)
                    return
            items = wires.get(v.id)
            if items is None:  # more vehicles than scan parts: it helps with the looks later
                self._adopt(v, "home", [])
                v.scan_done = True
                v.home = True
                return
            v.phase = "uploading scan"
            await self._upload(v, "scan", items, first_seq=None)
            to_start.append(v)

        results = await asyncio.gather(*(prepare(v) for v in self.vehicles.values()), return_exceptions=True)
        for r in results:
            if isinstance(r, BaseException):
                raise r
        if self.opt.start == "operator":
            for v in to_start:
                v.phase = "waiting for operator"
            self._event("operator", "scan missions uploaded; start each vehicle's mission from your "
                        "ground station (arm + AUTO); the search follows")
            return
        starts = await asyncio.gather(*(self._start(v) for v in to_start), return_exceptions=True)
        for r in starts:
            if isinstance(r, BaseException):
                raise r

    async def _rewind_scan(self, v: _Vehicle, items: list) -> None:
        """Re-fly the part of the scan flown while the daemon was down (its RSSI never arrived):
        back to the leg the vehicle was on when the last telemetry was stored."""
        then = self._seq_before_crash.get(v.id)
        now = v.agent.tel.mission_seq
        if then is None or now is None or now <= then:
            return  # still on the leg it was on (or done before the crash): nothing worth re-flying
        waypoints = [it.seq for it in items if it.command == NAV_WAYPOINT and it.seq > 0]
        if not waypoints:
            return
        back = max(waypoints[0], min(then - 1, waypoints[-1]))
        await v.agent.switch_to(back, on_ground=False)
        v.agent.tel.mission_seq = back
        v.ignore_seq_until_wall = self.wall() + 1.0
        self._event("resume", f"vehicle {v.id} re-flies its scan from item {back} (flown while the daemon was "
                    f"down, now at item {now})", v.id)

    async def _start(self, v: _Vehicle) -> None:
        await v.agent.start()
        v.phase = "scanning"
        self._event("start", f"vehicle {v.id} started its scan", v.id)

    def _adopt(self, v: _Vehicle, purpose: str, items: list) -> None:
        v.purpose, v.mission = purpose, list(items)
        v.end_seq = final_seq(items)
        v.phase = {"scan": "scanning", "look": "localizing", "home": "returning"}.get(purpose, purpose)

    async def _upload(self, v: _Vehicle, purpose: str, items: list, first_seq: int | None,
                      on_ground: bool = False) -> None:
        await v.agent.upload(items)
        self._adopt(v, purpose, items)
        self.store.add_mission(self.now_s(), v.id, purpose, items)
        if self.on_mission_acked is not None:
            self.on_mission_acked(v.id, purpose)
        if first_seq is not None:
            await v.agent.switch_to(first_seq, on_ground=on_ground)
            v.agent.tel.mission_seq = first_seq
            v.ignore_seq_until_wall = self.wall() + 1.0
        self._event("upload", f"vehicle {v.id}: {purpose} mission of {len(items)} items acknowledged", v.id)

    # -- receive path callbacks ------------------------------------------------------------------------
    def _on_slots(self, batch: SlotBatch) -> None:
        self._slots_in.append(batch)
        self.store.add_slots(batch)

    def _on_position(self, vehicle: int, tel) -> None:
        self._rate.observe(tel)
        w = self.wall()
        if w - self._last_tel_store.get(vehicle, -math.inf) < 0.1:
            return
        self._last_tel_store[vehicle] = w
        v = self.vehicles[vehicle]
        self.store.add_telemetry([TelemetryRow(self.now_s(), vehicle, tel.lat_deg, tel.lon_deg, tel.rel_alt_m,
                                               tel.battery_pct, tel.mode, tel.mission_seq, v.lost)])

    def _on_text(self, vehicle: int, text: str) -> None:
        self.store.add_event("statustext", text, t_s=self.now_s(), vehicle=vehicle)

    # -- the monitor: lost/found, phases, live view ---------------------------------------------------
    async def _monitor(self) -> None:
        while not self._stop.is_set():
            for v in self.vehicles.values():
                self._update_phase(v)
            if self.view is not None:
                self.view.update(self.snapshot())
            await asyncio.sleep(self.opt.tick_s)

    def _update_phase(self, v: _Vehicle) -> None:
        a = v.agent
        silent = a.silent_for_s() > self.opt.lost_timeout_s
        if silent and not v.lost:
            v.lost = True
            self._event("lost", f"vehicle {v.id} silent for {self.opt.lost_timeout_s:g} s: marked lost; "
                        "its people go to the others", v.id)
        elif v.lost and not silent:
            v.lost = False
            self._event("found", f"vehicle {v.id} is back", v.id)
        if v.lost:
            return
        seq = a.tel.mission_seq
        if v.phase == "waiting for operator" and a.tel.armed and a.in_mission_mode:
            v.phase = "scanning"
            self._event("start", f"vehicle {v.id} started by the operator", v.id)
        fresh = self.wall() >= v.ignore_seq_until_wall
        past_end = seq is not None and v.end_seq and seq >= v.end_seq and fresh
        complete = fresh and (a.tel.mission_state == MISSION_STATE_COMPLETE or (
            past_end and a.tel.ground_speed_m_s < 1.0 and not a.on_ground()))
        if v.phase == "scanning" and complete:
            v.scan_done = True
            v.phase = "hovering (scan done)"
            self._event("scan", f"vehicle {v.id} finished its scan", v.id)
        elif v.phase == "localizing" and past_end:
            self._returning(v)
        if v.phase.startswith("returning") and a.on_ground() and not v.home:
            v.home = True
            v.phase = "landed"
            self._event("landed", f"vehicle {v.id} landed", v.id)
        if v.home and not a.on_ground() and a.tel.armed:
            v.home = False  # sent out again

    def _returning(self, v: _Vehicle) -> None:
        v.phase = "returning"
        xy = v.agent.position_xy_m() or (0.0, 0.0)
        alt = v.agent.tel.rel_alt_m if math.isfinite(v.agent.tel.rel_alt_m) else self.sc.fleet.altitude_m
        v.home_by_s = (self.now_s() + math.hypot(*xy) / self.sc.fleet.speed_m_s + alt / LANDING_RATE_M_S
                       + LANDING_MARGIN_S)

    def snapshot(self) -> StatusSnapshot:
        t = self.now_s()
        vs = [VehicleStatus(v.id, v.phase, v.agent.tel.mode if v.agent else "?",
                            v.agent.tel.battery_pct if v.agent else None,
                            v.agent.tel.mission_seq if v.agent else None, v.end_seq or None, v.lost)
              for v in self.vehicles.values()]
        people = [person_view(p) for p in self._people_cache]
        return StatusSnapshot(t, vs, people, self._n_slots, self.sc.people.required_accuracy_m, self._replans)

    # -- the brain ---------------------------------------------------------------------------------------
    async def _brain(self) -> None:
        try:
            while True:
                await asyncio.sleep(self.opt.tick_s)
                t = self.now_s()
                if self._slots_in:
                    batches, self._slots_in = self._slots_in, []
                    new = SlotBatch.concat(batches)
                    self._n_slots += len(new)
                    self.policy.ingest(new)
                self._report_looks(t)
                changed = await asyncio.to_thread(self.policy.update, t)
                people = self.policy.people(t)
                self._people_cache = people
                if changed:
                    by_id = {p.emitter_id: p for p in people}
                    self.store.add_estimates([estimate_row(by_id[e], t) for e in sorted(changed) if e in by_id])
                if await self._step(t, changed):
                    return
        finally:
            self._stop.set()

    def _report_looks(self, t: float) -> None:
        """Tell the policy which looks the vehicles have flown: a look waypoint is flown once the
        mission has moved past it (MISSION_CURRENT) or the vehicle is within WAYPOINT_TOLERANCE_M
        of it."""
        report = getattr(self.policy, "look_flown", None)
        if report is None:
            return
        for v in self._active():
            if v.purpose != "look" or v.look_xy_m is None or self.wall() < v.ignore_seq_until_wall:
                continue
            seq = v.agent.tel.mission_seq
            passed = 0 if seq is None else int(np.clip(seq - v.look_first_seq, 0, len(v.look_xy_m)))
            xy = v.agent.position_xy_m()
            if passed < len(v.look_xy_m) and xy is not None and \
                    math.dist(xy, v.look_xy_m[passed]) <= WAYPOINT_TOLERANCE_M:
                passed += 1
            while v.looks_reported < passed:
                report(v.targets[v.looks_reported], t)
                v.looks_reported += 1

    def _active(self) -> list[_Vehicle]:
        return [v for v in self.vehicles.values() if not v.lost and v.agent is not None]

    async def _step(self, t: float, changed: set) -> bool:
        """One decision; True when the search is over."""
        active = self._active()
        if not active:
            self._event("end", "every vehicle is lost; stopping the search")
            return True
        if t > self.opt.max_mission_s:
            self._event("end", f"mission time limit {self.opt.max_mission_s:g} s reached")
            return True
        if not all(v.scan_done or v.home for v in active):
            return False
        if self.policy.done(t):
            return await self._finish(active)
        fleet = frozenset(v.id for v in active)
        usable = active
        if (self.policy.needs_replan(t, changed) or fleet != self._last_fleet) and t >= self._replan_not_before_s:
            self._last_fleet = fleet
            await self._replan(t, usable)
        if all(v.home for v in active):
            # nobody is flying and nothing more can be planned: stop with who is not located
            if self._finishing_since is None:
                self._finishing_since = t
            elif t - self._finishing_since > 10.0:
                return True
        else:
            self._finishing_since = None
        return False

    def _vehicle_state(self, v: _Vehicle):
        from ..planning import VehicleState  # noqa: PLC0415

        xy = v.agent.position_xy_m() or (0.0, 0.0)
        budget = self.sc.fleet.energy_budget_j
        pct = v.agent.tel.battery_pct
        left = self.sc.usable_energy_j if pct is None else max(
            0.0, budget * pct / 100.0 - budget * self.sc.fleet.energy_reserve_fraction)
        return VehicleState(str(v.id), (float(xy[0]), float(xy[1])), (0.0, 0.0), float(left))

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
            if len(pts) == 0:
                if not v.phase.startswith("returning") and not v.home:
                    jobs.append(self._send_home(v))
                continue
            if v.purpose == "look" and self._still_flying(v, pts, tuple(task.target_ids)):
                continue  # the vehicle already flies this: do not upload
            jobs.append(self._upload_look(v, pts, tuple(task.target_ids)))
        if jobs:
            results = await asyncio.gather(*jobs, return_exceptions=True)
            for r in results:
                if isinstance(r, UavlocError):
                    self._event("error", str(r))
                elif isinstance(r, BaseException):
                    raise r

    def _still_flying(self, v: _Vehicle, pts: np.ndarray, targets: tuple) -> bool:
        """Whether the vehicle's current mission still has exactly these looks ahead of it."""
        if v.look_xy_m is None or v.lost:
            return False
        seq = v.agent.tel.mission_seq
        passed = 0 if seq is None else int(np.clip(seq - v.look_first_seq, 0, len(v.look_xy_m)))
        remaining_xy, remaining_ids = v.look_xy_m[passed:], v.targets[passed:]
        return tuple(targets) == tuple(remaining_ids) and same_route(pts, remaining_xy, WAYPOINT_TOLERANCE_M)

    async def _upload_look(self, v: _Vehicle, pts: np.ndarray, targets: tuple) -> None:
        latlon = self.frame.to_wgs84_latlon(pts)
        f = self.sc.fleet
        on_ground = v.home or v.agent.on_ground()
        plan = flight_mission(latlon.tolist(), alt_m=f.altitude_m, speed_m_s=f.speed_m_s, autopilot=f.autopilot,
                              home_latlon_deg=self.sc.launch_latlon_deg, include_takeoff=on_ground)
        items = to_wire(plan, f.autopilot)
        first = 1 if v.agent.flavour.home_at_seq0 else 0  # the takeoff (on the ground) or the speed item
        await self._upload(v, "look", items, first_seq=first, on_ground=on_ground)
        v.targets, v.look_xy_m, v.looks_reported = targets, pts, 0
        v.look_first_seq = next(it.seq for it in items if it.command == NAV_WAYPOINT and it.seq > 0)
        v.home = False
        self._event("plan", f"vehicle {v.id} looks at {', '.join(map(str, targets))}", v.id)

    async def _send_home(self, v: _Vehicle) -> None:
        v.purpose, v.targets, v.look_xy_m = "home", (), None
        if v.agent.on_ground():
            v.home, v.phase = True, "landed"
            return
        await v.agent.return_home()
        self._returning(v)
        self._event("home", f"vehicle {v.id} has nothing left to look at: returning home", v.id)

    async def _finish(self, active: list[_Vehicle]) -> bool:
        if self._finishing_since is None:
            self._finishing_since = self.now_s()
            self._event("done", "every person heard is located or given up: all vehicles return home")
            jobs = [self._send_home(v) for v in active if not v.home and not v.phase.startswith("returning")]
            for r in await asyncio.gather(*jobs, return_exceptions=True):
                if isinstance(r, UavlocError):
                    self._event("error", str(r))
        now = self.now_s()
        if all(v.home or (v.phase == "returning" and now > v.home_by_s) for v in self._active()):
            return True  # landed, or returning and overdue: report them as returning
        return now - self._finishing_since > LAND_WAIT_S

    # -- the end ------------------------------------------------------------------------------------------
    def _outcome(self) -> SearchOutcome:
        t = self.now_s()
        self.store.flush()
        with StoreReader(self.opt.store_path) as rd:
            slots = rd.slots()
        people = tuple(final_results(self.policy.people(t), slots, self.sc, self.frame))
        lost = tuple(v.id for v in self.vehicles.values() if v.lost)
        returning = tuple(v.id for v in self.vehicles.values() if not v.home and not v.lost and v.phase == "returning")
        other = tuple(v.id for v in self.vehicles.values() if not v.home and not v.lost and v.phase != "returning")
        text = statement_for(people, self.sc.people.required_accuracy_m, lost, other, returning)
        self._event("end", text)
        self.store.set_meta("finished", True)
        self.store.flush()
        return SearchOutcome(people, bool(people) and all(p.located for p in people), text, t, self._replans,
                             tuple(v.id for v in self.vehicles.values() if v.home), lost, returning)
