"""Before the search: reload a previous run from the store, connect every vehicle, ask for its
streams and speed, warn about its link-loss failsafe, then upload every scan (or re-adopt, after
a restart, what each vehicle has on board) and start them. Mixed into :class:`~.daemon.Daemon`.
"""

from __future__ import annotations

import asyncio
import math
import time
from pathlib import Path

from ..errors import ConfigError, LinkError, UavlocError
from ..mission import NAV_WAYPOINT, to_wire
from .missionstate import final_seq, hold_seq, same_stored_mission, scan_rest, with_hold_before_rtl
from .store import StoreReader
from .vehicle import VehicleAgent
from .vehiclelife import VehicleLife as _Vehicle
from .vehiclelife import read_facts as read_life_facts

HOLD_WALL_S = 30.0  # a finished scan holds at least this many wall seconds for the next mission
START_WAIT_S = 10.0  # wall seconds the brain waits for the scan starts before leaving them to each vehicle


class FleetPreparation:
    """Connecting, resuming and starting the fleet, for :class:`~.daemon.Daemon`."""

    async def _close_links(self) -> None:
        links = []
        for v in self.vehicles.values():
            if v.agent is not None:
                v.agent.close()
            if v.link is not None and all(v.link is not other for other in links):
                links.append(v.link)
        links += [lk for lk in self._rssi_links if all(lk is not other for other in links)]
        for link in links:
            await link.close()

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
            # sorties (issue 38): each vehicle's sortie, packs and whether it flew on the pack it has
            # (service/swaps.py PackSwaps._save_sorties), applied once the sorties are planned again
            self._stored_sorties = {int(k): dict(v) for k, v in (meta.get("sorties") or {}).items()}
            if meta.get("scenario") != self.sc.name:
                raise UavlocError(f"the store {self.opt.store_path} holds the search '{meta.get('scenario')}', "
                                  f"not '{self.sc.name}'; use another --store or --fresh")
            self.epoch_unix_s = float(meta["epoch_unix_s"])
            self._clock_anchors = [tuple(a) for a in meta.get("clock_anchors") or []]  # the clock map so far
            slots = rd.slots()
            missions = rd.latest_missions()
            self._seq_before_crash = rd.last_mission_seq()
        for vid, (plans, uploads, skipped) in (meta.get("counts") or {}).items():
            v = self.vehicles.get(int(vid))
            if v is not None:  # the counts go on from the last run's
                v.plans, v.uploads, v.skipped = int(plans), int(uploads), int(skipped)
        self.policy.ingest(slots)
        from ..search.coverage import add_stored  # noqa: PLC0415

        add_stored(self.coverage, self.opt.store_path)  # what was flown before the restart stays searched
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
                                   on_position=self._on_position, on_status_text=self._on_text,
                                   on_mission_seq=self._on_mission_seq, wall=self.wall)
            await v.link.wait_heartbeat(v.id, timeout_s=self.opt.connect_timeout_s)
            v.phase = "connected"

        results = await asyncio.gather(*(connect(v) for v in self.vehicles.values()), return_exceptions=True)
        bad = [(v, r) for v, r in zip(self.vehicles.values(), results) if isinstance(r, BaseException)]
        for _, r in bad:
            if not isinstance(r, Exception):
                await self._close_links()
                raise r
        fatal = [r for _, r in bad if not isinstance(r, LinkError)]
        names = ", ".join(f"{v.id} ({v.connection})" for v, _ in bad)
        if fatal or len(bad) == len(self.vehicles):
            await self._close_links()
            if fatal:
                raise fatal[0]
            raise LinkError(f"no heartbeat within {self.opt.connect_timeout_s:g} s from vehicle(s) {names}; "
                            "check that they are powered and the connection strings in [link] are right",
                            operation="connect")
        for v in self.vehicles.values():
            if v.phase == "connected":
                self._event("connect", f"vehicle {v.id} connected on {v.connection}", v.id)
        for v, _ in bad:
            # The others search without it; if it is heard later it joins for the looks.
            v.phase, v.lost, v.scan_done, v.home = "not connected", True, True, True
            if v.agent is None:
                v.unusable = "its link could not be opened"
            self._event("lost", f"vehicle {v.id}: no heartbeat within {self.opt.connect_timeout_s:g} s on "
                        f"{v.connection}; searching without it (it joins for the looks if heard later)", v.id)
        await self._open_rssi_links()
        await self._setup_vehicles([v for v in self.vehicles.values() if v.agent is not None and not v.lost])
        # wait for a clock (SYSTEM_TIME, asked for above) so slot times have an epoch
        deadline = self.wall() + self.opt.connect_timeout_s
        while self._epoch() is None and self.wall() < deadline:
            await asyncio.sleep(0.05)
        if self.epoch_unix_s is None:
            # degrade, do not stop: slot times then come from the ground's clock
            self._ground_clock = True
            self.epoch_unix_s = float(math.floor(time.time()))
            self.store.set_meta("epoch_unix_s", self.epoch_unix_s)
            self._event("warning", f"no vehicle sent SYSTEM_TIME within {self.opt.connect_timeout_s:g} s (asked "
                        "with SET_MESSAGE_INTERVAL); using the ground station's clock for mission time, which "
                        "is wrong under a simulator speed-up")
        await self._check_failsafes()

    async def _check_failsafes(self) -> None:
        """Warn about every vehicle a lost ground station would leave hovering (service/failsafe.py)."""
        from .failsafe import read_gcs_loss_warning  # noqa: PLC0415

        heard = [v for v in self.vehicles.values() if not v.lost and v.link is not None]
        warnings = await asyncio.gather(*(read_gcs_loss_warning(v.link, v.id, self.sc.fleet.autopilot)
                                          for v in heard), return_exceptions=True)
        for v, w in zip(heard, warnings):
            if isinstance(w, LinkError):
                w = f"vehicle {v.id}: could not read its link-loss failsafe ({w})"
            elif isinstance(w, BaseException):
                raise w
            if w:
                self._event("failsafe", w, v.id)

    async def _open_rssi_links(self) -> None:
        """RSSI beside the autopilot: one link per distinct [link] rssi_connections entry."""
        from ..link.connection import open_link  # noqa: PLC0415

        opened: dict[str, object] = {}
        for vid, conn in self.opt.rssi_connections:
            v = self.vehicles.get(vid)
            if not conn or v is None or v.agent is None:
                continue
            if conn not in opened:
                opened[conn] = await open_link(conn, source_system=self.opt.source_system,
                                               signing_key=self.opt.signing_key)
                self._rssi_links.append(opened[conn])
            v.agent.attach_rssi(opened[conn])
            self._event("connect", f"vehicle {vid}: RSSI also taken from {conn} (beside the autopilot)", vid)

    async def _setup_vehicles(self, vehicles: list) -> None:
        """Ask each vehicle for the streams the search reads; plan with the speed it will fly."""
        from .setup import fleet_speed, request_streams  # noqa: PLC0415

        refused = await asyncio.gather(*(request_streams(v.link, v.id, v.agent.flavour) for v in vehicles))
        for v, names in zip(vehicles, refused):
            if names:
                self._event("warning", f"vehicle {v.id} did not accept a stream of {', '.join(names)}; "
                            "the search uses what it sends anyway", v.id)
        speed = await fleet_speed([(v.id, v.link, v.agent.flavour) for v in vehicles], self.sc.fleet.speed_m_s,
                                  consent=self.opt.set_speed_params)
        for note in speed.notes:
            self._event("speed", note)
        self._return_speed_m_s = speed.return_m_s
        if speed.mission_m_s < self.sc.fleet.speed_m_s:
            if getattr(self, "_scan_pod", None) is not None:
                # the POD scan was chosen among speeds these vehicles do not fly: choose again
                # among those they do (a slower flight would hear more, but take longer and
                # spend energy the plan did not count)
                from ..search.pod_plan import scan_for, scan_pod_plan  # noqa: PLC0415

                was = self._scan_pod.chosen.speed_m_s
                # seconds of CPU: off the event loop, which keeps reading the vehicles meanwhile
                self._scan_pod = await asyncio.to_thread(scan_pod_plan, self._given_sc, speed.mission_m_s)
                flown, self._scan_plan = scan_for(self._given_sc, speed.mission_m_s)  # the same, cached
                self._event("speed", f"the scan planned for POD {self._scan_pod.target:g} at {was:g} m/s is planned "
                            f"again at {flown.fleet.speed_m_s:g} m/s, the fastest all vehicles fly")
                self.sc = self.sc.replace(fleet={"speed_m_s": flown.fleet.speed_m_s})
            else:
                self.sc = self.sc.replace(fleet={"speed_m_s": speed.mission_m_s})
            if hasattr(self.policy, "speed_m_s"):
                self.policy.scenario, self.policy.speed_m_s = self.sc, self.sc.fleet.speed_m_s

    async def _resume_landed_scan(self, v: _Vehicle, items: list, f) -> bool:
        """After a restart: ``v`` has its scan on board but is on the ground, disarmed (it landed
        by itself while no daemon listened: a failsafe, the scan's own RTL). The scan is flown on
        only where it was not: from the leg it was on when the last telemetry was stored (what it
        flew since then sent RSSI nobody heard). True when a start must follow."""
        then = self._seq_before_crash.get(v.id)
        hold = hold_seq(items) or final_seq(items)
        waypoints = [it.seq for it in items if it.command == NAV_WAYPOINT and it.seq > 0]
        if then is not None and waypoints and then >= hold:  # it had flown its whole scan
            self._adopt(v, "scan", items)
            v.scan_done, v.home, v.phase = True, True, "landed"
            self._event("resume", f"vehicle {v.id} is on the ground, disarmed, its scan flown (item {then} of "
                        f"{hold} reached): home", v.id)
            return False
        back = waypoints[0] if then is None or not waypoints else max(waypoints[0], min(then - 1, waypoints[-1]))
        v.phase = "uploading scan"
        if not waypoints or back <= waypoints[0]:
            self._adopt(v, "scan", items)
            self._event("resume", f"vehicle {v.id} is on the ground, disarmed, its scan not begun "
                        f"(item {then}): resuming it from its start", v.id)
            return True
        rest = scan_rest(items, back)
        left = sum(1 for it in rest if it.command == NAV_WAYPOINT and it.seq > 0)
        self._event("resume", f"vehicle {v.id} is on the ground, disarmed, its scan flown to item {then} of {hold}: "
                    f"resuming its scan from item {back} ({left} of {len(waypoints)} waypoints left)", v.id)
        await self._upload(v, "scan", rest, first_seq=None)
        return True

    async def _prepare_all(self, resumed: dict) -> None:
        """Upload every scan (or re-adopt the missions found after a restart), then start."""
        from ..scan import plan_scan, scan_missions  # noqa: PLC0415

        # The scan ends holding at its last waypoint, then RTL: the adaptive phase starts from
        # there, as the experiments model it, and the next mission is uploaded while the vehicle
        # holds; a vehicle the daemon no longer talks to comes home by itself after the hold.
        # The hold lasts until the longest scan is over, plus scan_hold_s.
        # the scan planned for search.pod_target (Daemon: search.pod_plan.scan_for), else [scan]'s at
        # the speed the vehicles fly (_setup_vehicles may have lowered it)
        pp = getattr(self, "_scan_pod", None)
        plan = self._scan_plan if pp is not None else plan_scan(self.sc)
        if pp is not None:
            c = pp.chosen
            self._event("plan", f"scan planned for POD {pp.target:g}: {pp.lanes_text()} at {c.speed_m_s:g} m/s, "
                        f"{c.passes} pass{'es' if c.passes > 1 else ''}, POD {pp.grid.overall(1):.2f} for one heard burst "
                        f"and {pp.grid.overall(2):.2f} for two" + ("" if pp.met else " (best the energy allows)"))
        from .. import geofence  # noqa: PLC0415

        self._event("plan", geofence.describe(self.sc, plan))  # the fence the looks and passes stay inside
        longest = max((p.duration_s for p in plan.vehicles), default=0.0)
        # at least HOLD_WALL_S of the daemon's own time, whatever the clock rate (a simulator speed-up)
        hold_s = max(self.opt.scan_hold_s, HOLD_WALL_S * self._rate.rate)
        from ..terrain_missions import terrain_safe  # noqa: PLC0415 -- over the ground of terrain.dem (none: as is)

        restored: dict[int, int] = {}  # sorties after a restart: vehicle -> the sortie it flies
        if self.sc.fleet.batteries <= 1:
            scans = [terrain_safe(with_hold_before_rtl(m, longest - p.duration_s + hold_s), self.sc,
                                  name=f"uav{p.index + 1}")
                     for m, p in zip(scan_missions(self.sc, plan), plan.vehicles)]
            wires = {vid: to_wire(m, self.sc.fleet.autopilot) for vid, m in zip(sorted(self.vehicles), scans)}
        else:  # flown in sorties, a swap between two (service/swaps.py)
            sorties = self._sortie_wires(plan, hold_s)
            wires = {vid: per[0] for vid, per in sorties.items()}
            for v in self.vehicles.values():
                v.sorties, v.sortie = list(sorties.get(v.id, [None])[1:]), 1
                v.packs_left = self.sc.fleet.batteries - 1
            restored = self._restore_sorties(sorties)  # a restart: where each one was
            for vid, k in restored.items():
                wires[vid] = sorties[vid][k - 1]
        to_start = []

        async def prepare(v: _Vehicle) -> None:
            if v.lost:  # never connected
                return
            previous = resumed.get(v.id)
            if previous is not None:
                on_board = await v.agent.download()
                purpose, items = previous
                if same_stored_mission(on_board, items, v.agent.flavour):
                    f = read_life_facts(v.agent)  # read now, after the download's awaits
                    if purpose == "scan" and f.landed and v.id in restored:
                        how = await self._resume_landed_sortie(v, items)
                        if how == "start":
                            to_start.append(v)
                        if how is not None:
                            return
                    if purpose == "scan" and f.landed:
                        if await self._resume_landed_scan(v, items, f):
                            to_start.append(v)
                        return
                    self._adopt(v, purpose, items)
                    v.scan_done = purpose != "scan"
                    if f.landed:
                        v.home, v.phase = True, "landed"
                        self._event("resume", f"vehicle {v.id} is on the ground, disarmed, with its {purpose} "
                                    f"mission on board (item {f.mission_seq}): home", v.id)
                        return
                    self._event("resume", f"vehicle {v.id} still flies its {purpose} mission "
                                f"(item {f.mission_seq})", v.id)
                    if purpose == "scan":
                        await self._rewind_scan(v, items)
                    return
                self._event("resume", f"vehicle {v.id}: mission on board differs from the stored one", v.id)
                if purpose != "scan" or v.agent.tel.armed:
                    await self._upload(v, purpose, items, first_seq=None)
                    return
            items = wires.get(v.id)
            if items is None:  # more vehicles than scan parts: it helps with the looks later
                v.phase = "idle"
                v.purpose, v.mission, v.end_seq = "home", [], 0
                v.scan_done = True
                v.home = True
                return
            v.phase = "uploading scan"
            await self._upload(v, "scan", items, first_seq=None)
            to_start.append(v)

        await self._each(prepare, list(self.vehicles.values()))
        to_start = [v for v in to_start if not v.unusable]
        if self.opt.start == "operator":
            for v in to_start:
                v.phase = "waiting for operator"
            self._event("operator", "scan missions uploaded; start each vehicle's mission from your "
                        "ground station (arm + AUTO); the search follows")
            return
        await self._jobs([(v, self._start(v)) for v in to_start], START_WAIT_S)
