"""Each vehicle's exchanges in the search: start, switch, upload, a look's upload, send home,
disarm after a failed start, resume a scan after a restart, and what each vehicle does when the
daemon is stopped. Mixed into :class:`~.daemon.Daemon` (which owns the vehicles, the store, the
clock and the event log); the orchestration (when each is done) stays in the daemon.

Every decision here reads the vehicle's facts at the moment it acts (on the ground, armed, mode,
current item: :func:`.vehiclelife.read_facts`, :func:`.starting.read_facts`), never a value taken
before an await: a vehicle can land, be disarmed or refuse while an upload stalls (issue 26).
"""

from __future__ import annotations

import asyncio
import logging
import math

import numpy as np

from .. import geofence
from ..errors import InfeasibleError, LinkError
from ..estimation.identity import person_name
from ..heights import look_floor_m
from ..mission import NAV_WAYPOINT, flight_mission, to_wire
from ..search.orbit import look_mission, orbits_for
from ..terrain_missions import point_seqs, terrain_safe
from .lifecycle import persist
from .missionstate import final_seq, hold_seq, same_stored_mission
from .starting import (CLIMB_WAIT_S, READY_WAIT_S, REFUSAL_GRACE_S, StartFailed, UnsafeStart, read_facts, refusal_in,
                       start_guard, takeoff_seen)
from .vehicle import VehicleAgent
from .vehiclelife import HOMING_MODES
from .vehiclelife import VehicleLife as _Vehicle

log = logging.getLogger(__name__)

WAYPOINT_TOLERANCE_M = 10.0  # a replanned look this close to the uploaded one is "unchanged"
STOP_WAIT_S = 15.0  # wall seconds to send everyone home when stopped
LOOK_UPLOAD_TRIES = 2  # uploads of one look: the second with a take-off, for a vehicle that landed meanwhile


class VehicleCommands:
    """The per-vehicle exchanges of :class:`~.daemon.Daemon`."""

    async def _stopping(self) -> list[str]:
        """The daemon is being stopped: send the airborne vehicles home (``on_stop = "rtl"``) or let
        them fly on; one sentence per vehicle saying what it will do."""
        rtl = self.opt.on_stop == "rtl"

        async def one(v: _Vehicle) -> str:
            a = v.agent
            if a is None or not math.isfinite(a.tel.rel_alt_m):
                return f"vehicle {v.id}: never heard; nothing sent"
            mission = (f"its {v.purpose or 'current'} mission (item {a.tel.mission_seq} of {len(v.mission)}), "
                       "which ends in RTL")
            if v.lost:
                lh = v.last_heard or self._last_heard(v)
                if not lh.airborne:
                    return f"vehicle {v.id}: out of contact, last heard on the ground and disarmed at {lh.when()}"
                return (f"vehicle {v.id}: LOST IN THE AIR, last heard at {lh.when()}, {lh.where()}; it flies {mission}, "
                        "or its link-loss failsafe acts")
            if a.landed():
                return f"vehicle {v.id}: on the ground, disarmed"
            if a.on_ground():  # armed, low and slow: landing, or down and not yet disarmed
                return (f"vehicle {v.id}: armed {a.tel.rel_alt_m:.1f} m above home in {a.tel.mode}, not yet on the "
                        "ground and disarmed; nothing sent (it disarms by itself once down)")
            if a.tel.mode in HOMING_MODES:
                self._returning(v)
                return f"vehicle {v.id}: airborne, already returning home ({a.tel.mode})"
            if not rtl:
                return f"vehicle {v.id}: airborne, continues {mission} (on_stop = \"continue\")"
            try:
                how = await persist(a.return_home, lambda: a.tel.mode in HOMING_MODES, what="return home",
                                    vehicle=v.id, tries=2, settle_s=1.5, wall=self.wall,
                                    heard_since=lambda t: a.tel.wall_s > t)
            except LinkError as exc:
                return f"vehicle {v.id}: airborne; RTL not confirmed ({exc}); it flies {mission}"
            self._returning(v)  # what the outcome says of it, too
            seen = "acknowledged" if how == "acked" else "not acknowledged but seen in RTL"
            return f"vehicle {v.id}: airborne, returning home (RTL {seen})"

        async def bounded(v: _Vehicle) -> str:  # one vehicle's silence does not take the others' lines
            try:
                return await asyncio.wait_for(one(v), STOP_WAIT_S)
            except TimeoutError:
                return f"vehicle {v.id}: no answer within {STOP_WAIT_S:g} s; it flies its mission, which ends in RTL"

        vehicles = list(self.vehicles.values())
        lines = list(await asyncio.gather(*(bounded(v) for v in vehicles)))
        for v, line in zip(vehicles, lines):
            self._event("stop", line, v.id)
        self.store.set_meta("stopped", True)
        self.store.flush()
        return lines

    def _mark_unusable(self, v: _Vehicle, err: BaseException) -> None:
        if v.unusable:
            return
        v.unusable = str(err)
        if v.agent is not None and v.agent.landed():
            v.home = True  # it never left, or is back (on the ground and disarmed): reported as home
        v.phase = "unusable"
        where = "it flies its current mission, which ends in RTL" if v.airborne else "it stays where it is"
        self._event("unusable", f"vehicle {v.id} cannot be commanded ({err}); {where}; its people go to the others",
                    v.id)

    def _save_counts(self) -> None:
        """Each vehicle's plans, uploads and plans not uploaded, in the store as they change: a
        restarted daemon goes on counting from them (issue 26: a restart reported "0/0/0")."""
        self.store.set_meta("counts", {str(v.id): [v.plans, v.uploads, v.skipped] for v in self.vehicles.values()})

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
        try:
            await self._switch(v, back)
        except UnsafeStart as exc:  # armed, but on the ground: not sent up without a take-off
            self._event("resume", f"vehicle {v.id}: scan not re-flown ({exc})", v.id)
            return
        v.agent.tel.mission_seq = back
        v.ignore_seq_until_wall = self.wall() + 1.0
        self._event("resume", f"vehicle {v.id} re-flies its scan from item {back} (flown while the daemon was "
                    f"down, now at item {now})", v.id)

    async def _start(self, v: _Vehicle) -> None:
        """Start the scan on a vehicle on the ground; it is started once it climbs (starting.py)."""
        v.phase = "starting"
        a = v.agent
        guard = start_guard(a, v.mission, a.flavour.first_mission_seq, v.id)
        try:
            try:
                ready_by = self.wall() + READY_WAIT_S
                while True:
                    await self._until_ready(v)
                    alt0, began = self._ground_alt(a), self.wall()  # (read after the wait)
                    try:
                        await self._persist(v, "start", lambda: a.start(before_start=guard),
                                            lambda: a.tel.armed and a.in_mission_mode)
                        break
                    except UnsafeStart:
                        # a freshly booted vehicle whose first SYS_STATUS says "not ready" only after
                        # the wait above saw nothing against it: wait again, within READY_WAIT_S
                        facts = read_facts(a)
                        if facts.armed or not facts.not_ready or self.wall() >= ready_by:
                            raise
                        await asyncio.sleep(0.5)
            except (LinkError, UnsafeStart) as exc:
                await self._disarm_on_ground(v)
                if isinstance(exc, UnsafeStart):  # a failed start like any other: the vehicle is unusable
                    raise StartFailed(f"scan start failed: {exc}", vehicle=str(v.id), operation="start") from exc
                raise
            await self._confirm_takeoff(v, "scan", began, self.wall(), alt0)
        except LinkError as exc:
            v.start_failed = str(exc)
            raise
        if v.phase == "starting":  # (the monitor may have seen it fly meanwhile)
            v.phase = "scanning"
        self._event("start", f"vehicle {v.id} started its scan", v.id)

    async def _until_ready(self, v: _Vehicle) -> None:
        """Wait until ``v`` says it is ready to arm (``VehicleAgent.not_ready``, read each time);
        StartFailed with its reason after READY_WAIT_S. Nothing is sent meanwhile: it is never
        armed, nor put in a mode that needs a position, before it has one."""
        a = v.agent
        not_ready = getattr(a, "not_ready", lambda: None)
        deadline, said = self.wall() + READY_WAIT_S, False
        while not a.tel.armed and (why := not_ready()) is not None:
            if self.wall() >= deadline:
                raise StartFailed(f"not ready to arm within {READY_WAIT_S:g} s: {why}", vehicle=str(v.id),
                                  operation="start")
            if not said:
                self._event("start", f"vehicle {v.id} waits to be ready to arm: {why}", v.id)
                said = True
            await asyncio.sleep(0.1)

    @staticmethod
    def _ground_alt(a: VehicleAgent) -> float:
        alt = a.tel.rel_alt_m
        return alt if math.isfinite(alt) and a.on_ground() else 0.0

    async def _disarm_on_ground(self, v: _Vehicle) -> None:
        """After a failed start: a vehicle left armed on the ground is disarmed (best effort; the
        autopilots also disarm by themselves after a while)."""
        a = v.agent
        if a.tel.armed and a.on_ground():
            try:
                await a.disarm()
                self._event("start", f"vehicle {v.id} disarmed on the ground after its failed start", v.id)
            except LinkError as exc:
                log.info("vehicle %d: disarm after a failed start: %s", v.id, exc)

    async def _confirm_takeoff(self, v: _Vehicle, purpose: str, began_wall_s: float, since_wall_s: float,
                               ground_alt_m: float) -> None:
        """A start from the ground is a start once the vehicle leaves the ground (or was seen
        airborne since the start began at ``began_wall_s``: a start whose ACKs were lost can last
        as long as a short look, flown and landed from meanwhile). A refusal it states
        after the start was accepted (STATUSTEXT since ``since_wall_s``; refusals during the start
        exchange are the exchange's to retry; one that does not rule out a repetition only if the
        vehicle does not fly the mission anyway) or no climb within CLIMB_WAIT_S is a failed start:
        a vehicle left armed on the ground is disarmed, and StartFailed names the reason (the
        vehicle becomes unusable; its scan is not counted as flown)."""
        from ..link.mission_control import final_start_refusal  # noqa: PLC0415

        a = v.agent
        deadline = self.wall() + CLIMB_WAIT_S
        refused_wall_s = None
        while not (takeoff_seen(read_facts(a), ground_alt_m) or a.airborne_wall_s >= began_wall_s):
            refusal = refusal_in(a.texts, since_wall_s)
            now = self.wall()
            if refusal is not None and refused_wall_s is None:
                refused_wall_s = now
            # A refusal fails the start at once when no repetition changes it ("Missing Takeoff
            # Cmd"); any other only if the vehicle does not go on to fly the mission (armed, in
            # its mission mode) within REFUSAL_GRACE_S: PX4 sends a denied attempt's STATUSTEXT
            # on its own stream, after the ACK of the retry it accepted (PX4 SITL under load:
            # "Mission start denied! No valid mission" 0.25 s after the accepted MISSION_START, while
            # it took off; the daemon tried to disarm it and gave the vehicle up)
            flying_it = a.tel.armed and a.in_mission_mode
            refused = refusal is not None and (final_start_refusal(refusal) or (
                not flying_it and now - refused_wall_s >= REFUSAL_GRACE_S))
            late = now >= deadline
            if refused or late:
                why = (f"the vehicle refused it: \"{refusal}\"" if refused else
                       f"it did not leave the ground within {CLIMB_WAIT_S:g} s ({a.tel.mode}, "
                       f"{'armed' if a.tel.armed else 'disarmed'})")
                await self._disarm_on_ground(v)
                raise StartFailed(f"{purpose} start failed: {why}", vehicle=str(v.id), operation="start")
            await asyncio.sleep(0.05)

    async def _persist(self, v: _Vehicle, what: str, action, done, check=None) -> str:
        a = v.agent
        how = await persist(action, done, what=what, vehicle=v.id, check=check, wall=self.wall,
                            heard_since=lambda t: a.tel.wall_s > t,
                            on_retry=lambda text: self._event("retry", text, v.id))
        if how == "judged":
            self._event("retry", f"vehicle {v.id} {what}: not acknowledged, but the vehicle does it", v.id)
        return how

    async def _switch(self, v: _Vehicle, first_seq: int) -> None:
        """Fly the mission on board from ``first_seq``. Whether the vehicle is on the ground is read
        when each try begins and again right before each arm and MISSION_START (starting.py): a
        mission without a take-off is never started on a vehicle on the ground (UnsafeStart)."""
        a = v.agent
        guard = start_guard(a, v.mission, first_seq, v.id)
        guard()
        from_ground, alt0, began = a.on_ground(), self._ground_alt(a), self.wall()

        def flying_it() -> bool:
            seq = a.tel.mission_seq
            return a.tel.armed and a.in_mission_mode and seq is not None and first_seq <= seq <= max(first_seq, v.end_seq)

        try:
            await self._persist(v, f"switch to item {first_seq}", lambda: a.switch_to(first_seq, before_start=guard),
                                flying_it)
        except (LinkError, UnsafeStart):
            if from_ground:
                await self._disarm_on_ground(v)
            raise
        if from_ground:
            await self._confirm_takeoff(v, v.purpose or "mission", began, self.wall(), alt0)

    def _adopt(self, v: _Vehicle, purpose: str, items: list) -> None:
        v.purpose, v.mission = purpose, list(items)
        v.end_seq = final_seq(items)
        v.hold_seq = hold_seq(items) if purpose == "scan" else v.end_seq
        if v.phase != "uploading scan":  # the start follows
            v.phase = {"scan": "scanning", "look": "localizing", "home": "returning"}.get(purpose, purpose)

    async def _upload(self, v: _Vehicle, purpose: str, items: list, first_seq: int | None,
                      plan_text: str | None = None) -> None:
        """Upload ``items`` and (``first_seq``) switch the vehicle to it. The upload's event, and
        the "plan" event ``plan_text``, come as soon as the mission is on board, before the
        switch: a switch whose ACKs are lost can outlast the flight it starts (measured at 25x: a
        look flown and landed while MISSION_START was resent), and a "done" that cancels it must
        not also erase from the log that the mission was uploaded and flown."""
        a = v.agent

        async def on_board() -> bool:
            return same_stored_mission(await a.download(), items, a.flavour)

        await self._persist(v, f"{purpose} upload", lambda: a.upload(items), lambda: False, check=on_board)
        v.uploads += 1
        self._adopt(v, purpose, items)
        self.store.add_mission(self.now_s(), v.id, purpose, items)
        self._save_counts()
        if self.on_mission_acked is not None:
            self.on_mission_acked(v.id, purpose)
        self._event("upload", f"vehicle {v.id}: {purpose} mission of {len(items)} items acknowledged", v.id)
        if plan_text is not None:
            self._event("plan", plan_text, v.id)
        if first_seq is not None:
            await self._switch(v, first_seq)
            a.tel.mission_seq = first_seq
            v.ignore_seq_until_wall = self.wall() + 1.0

    def _vehicle_state(self, v: _Vehicle):
        from ..planning import VehicleState  # noqa: PLC0415

        xy = v.agent.position_xy_m() or (0.0, 0.0)
        budget = self.sc.fleet.energy_budget_j
        pct = v.agent.tel.battery_pct
        left = self.sc.usable_energy_j if pct is None else max(
            0.0, budget * pct / 100.0 - budget * self.sc.fleet.energy_reserve_fraction)
        return VehicleState(str(v.id), (float(xy[0]), float(xy[1])), (0.0, 0.0), float(left))

    def _worth_uploading(self, v: _Vehicle, pts: np.ndarray, targets: tuple):
        """Whether the new looks ``pts``/``targets`` are worth an upload to ``v`` (search/uploads.py)."""
        from ..search.uploads import DEFAULT_UPLOAD_COST_S, UPLOAD_COST_S, decide_upload  # noqa: PLC0415

        flying_look = (v.purpose == "look" and v.look_xy_m is not None and not v.home
                       and not v.phase.startswith("returning") and not v.agent.on_ground())
        old_pts, old_targets = np.zeros((0, 2)), ()
        if flying_look:
            seq = v.agent.tel.mission_seq
            passed = 0 if seq is None else (sum(k < seq for k in v.look_seqs) if v.look_seqs else
                                             int(np.clip(seq - v.look_first_seq, 0, len(v.look_xy_m))))
            old_pts, old_targets = v.look_xy_m[passed:], tuple(v.targets[passed:])
        return decide_upload(
            flying_look=flying_look, uploads_since_look=v.uploads_since_look,
            position_xy_m=v.agent.position_xy_m() or (0.0, 0.0), old_targets=old_targets, old_points_xy_m=old_pts,
            new_targets=targets, new_points_xy_m=pts, speed_m_s=self.sc.fleet.speed_m_s,
            cost_s=UPLOAD_COST_S.get(self.sc.fleet.autopilot, DEFAULT_UPLOAD_COST_S),
            move_tolerance_m=self.sc.people.required_accuracy_m, same_tolerance_m=WAYPOINT_TOLERANCE_M)

    async def _upload_look(self, v: _Vehicle, pts: np.ndarray, targets: tuple) -> None:
        """Upload the looks ``pts`` (a take-off first when the vehicle is on the ground) and fly
        them. Whether it is on the ground is read before the upload to plan, and again at the start
        (``_switch``): a vehicle that landed while a look without a take-off was uploaded gets the
        look again with one; if it still cannot be started safely it holds where it is."""
        self._report_vehicle_looks(v, self.now_s())  # the current mission's passed looks, read now
        latlon = self.frame.to_wgs84_latlon(pts)
        f = self.sc.fleet
        first = 1 if v.agent.flavour.home_at_seq0 else 0  # the takeoff (on the ground) or the speed item
        for attempt in range(LOOK_UPLOAD_TRIES):
            on_ground = v.home or v.agent.on_ground()
            plan = flight_mission(latlon.tolist(), alt_m=f.altitude_m, speed_m_s=f.speed_m_s, autopilot=f.autopilot,
                                  home_latlon_deg=self.sc.launch_latlon_deg, include_takeoff=on_ground)
            orbits = orbits_for(self.policy, v.id, targets) if self.sc.dem is None else ()
            # the scenario's fence, else the area plus area.default_geofence_m (issue 42: without a
            # fence, looks left the area by up to 111 m)
            fence = geofence.flight_fence(self.sc)
            if any(o is not None for o in orbits) or fence is not None:  # orbits (search/orbit.py), a fence
                try:
                    looks = look_mission(self.frame, pts, targets, orbits or None, alt_m=f.altitude_m,
                                         speed_m_s=f.speed_m_s, autopilot=f.autopilot,
                                         home_latlon_deg=self.sc.launch_latlon_deg,
                                         start_xy_m=v.agent.position_xy_m(), include_takeoff=on_ground, fence=fence,
                                         floor_m=look_floor_m(self.sc),
                                         # a vehicle low in a look at its own height goes on with it
                                         # (look_mission's CONTINUE_*); with no look height asked,
                                         # the missions of before
                                         start_alt_m=None if self.sc.search.look_height_m is None
                                         else v.agent.tel.rel_alt_m)
                except InfeasibleError as exc:
                    self._event("hold", f"vehicle {v.id}: look not flown: {exc}", v.id)
                    return
                plan = looks.plan
                latlon = self.frame.to_wgs84_latlon(looks.look_xy_m)  # moved inside the fence
            if self.sc.dem is not None:  # over the ground of terrain.dem, from where the vehicle is
                try:
                    plan = terrain_safe(plan, self.sc, name=f"vehicle {v.id}", start_xy_m=None if on_ground
                                        else np.asarray(v.agent.position_xy_m() or (0.0, 0.0)))
                except InfeasibleError as exc:
                    self._event("hold", f"look not flown: {exc}", v.id)
                    return
            items = to_wire(plan, f.autopilot)
            try:
                await self._upload(v, "look", items, first_seq=first,
                                   plan_text=f"vehicle {v.id} looks at {', '.join(map(person_name, targets))}")
                break
            except UnsafeStart as exc:
                if attempt + 1 < LOOK_UPLOAD_TRIES:
                    self._event("plan", f"vehicle {v.id} landed while its look was uploaded ({exc}); "
                                "uploading the look again with a take-off", v.id)
                    continue
                v.home, v.phase = True, "landed"
                self._event("hold", f"vehicle {v.id}: look not started, it stays on the ground ({exc}); "
                            "no take-off without a take-off item", v.id)
                return
        v.targets, v.look_xy_m, v.looks_reported = targets, pts, 0
        v.look_first_seq = next((it.seq for it in items if it.command == NAV_WAYPOINT and it.seq > 0), first)
        # over terrain, waypoints added between the look points: where each look point went
        v.look_seqs = point_seqs(items, latlon) if self.sc.dem is not None else ()
        if fence is not None:
            v.look_xy_m = looks.look_xy_m  # moved inside the fence
        if any(o is not None for o in orbits) or (fence is not None and self.sc.dem is None):
            # each look counted at its orbit's entry or its own item (detours around the fence between)
            v.look_xy_m, v.look_seqs = looks.look_xy_m, looks.look_seqs(v.agent.flavour.home_at_seq0)
        a = v.agent
        # Read now, not assumed: a start whose ACKs were lost lasts as long as a short look, and the
        # vehicle may have flown it and landed meanwhile (tests/test_e2e_vehicle_faults.py's store:
        # vehicle 1 on the ground, disarmed, "not home", and the search waited for a replan).
        if a.landed():
            v.home, v.phase = True, "landed"
        else:
            v.home = False

    async def _send_home(self, v: _Vehicle) -> None:
        self._report_vehicle_looks(v, self.now_s())  # its passed looks, before they are forgotten
        v.purpose, v.targets, v.look_xy_m = "home", (), None
        a = v.agent
        if a.landed():
            v.home, v.phase = True, "landed"
            return
        if a.on_ground():
            # armed, low and slow: landing, or down and not yet disarmed -- it disarms by itself, and
            # an RTL sent now could make it climb again; "home" once it reports itself disarmed
            self._returning(v)
            return
        await self._persist(v, "return home", a.return_home, lambda: a.tel.mode in HOMING_MODES or a.landed())
        self._returning(v)
        self._event("home", f"vehicle {v.id} has nothing left to look at: returning home", v.id)
