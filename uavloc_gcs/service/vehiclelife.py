"""One vehicle's life in the search, as one explicit state machine.

The states (``VehicleLife.phase``) and the only moves between them (:data:`NEXT`)::

    connecting -> connected | not connected
    not connected -> idle                               (heard after all)
    connected -> uploading scan | scanning | localizing | returning | landed | hovering (scan done)
                 | waiting for operator | idle          (a fresh scan, or a mission adopted on resume)
    uploading scan -> starting | waiting for operator | scanning
    waiting for operator -> scanning                    (armed in a mission mode by the operator)
    starting -> scanning                                (left the ground: takeoff seen)
    scanning -> hovering (scan done) | returning | localizing | scanning | landed (a sortie's end)
    hovering (scan done) | idle | landed -> localizing | returning | landed
    localizing -> localizing | returning | landed
    returning -> landed | localizing | returning
    landed -> waiting for pack -> uploading scan | landed  (sorties: the team's swap, then its next sortie or looks)
    any -> unusable      (it talks but cannot be commanded, or its start failed: never "scan done")

Lost/found is orthogonal (``VehicleLife.lost``): a silent vehicle keeps its phase and is left out
of planning until it is heard again.

The facts every decision reads (:class:`Facts`, from :func:`read_facts`) are the vehicle's last
report *at the moment the decision acts*: armed, maybe on the ground (landed state or altitude: what
a start decides by), landed (on the ground and disarmed by the vehicle's own report: what "landed"
and "home" are said from, never a height-and-speed guess), mode, mission on board (ours or not
yet), current item, mission state. Nothing here keeps a fact across
an await: the monitor reads them each tick (:meth:`VehicleLife.observe`), and the exchanges
(service/commands.py, service/starting.py) read them again right before each arm, MISSION_START
and mission switch. Rules that matter (issue 26):

* the scan is "done" only once the vehicle has been seen airborne since it left the ground and
  its mission reached the scan's hold (a refused start -- "Auto: Missing Takeoff Cmd", no climb --
  is a failed start: ``start_failed`` and ``unusable``, never "finished");
* a vehicle that lands by itself mid-scan (a failsafe, a battery RTL) has NOT finished its scan:
  ``scan_done`` stays False and ``landed_mid_scan`` keeps the item it reached, so the unflown part
  can be resumed (a restart resumes it, :func:`resume_seq`);
* a mission starts on a vehicle on the ground only with a take-off from the item it starts at
  (service/starting.py).
"""

from __future__ import annotations

import asyncio
import logging
import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

log = logging.getLogger(__name__)

MISSION_STATE_COMPLETE = 5
HOMING_MODES = ("RTL", "SMART_RTL", "LAND", "AUTO.RTL", "AUTO.LAND")  # ArduPilot, PX4

NEXT: dict[str, frozenset[str]] = {
    "connecting": frozenset({"connected", "not connected"}),
    "not connected": frozenset({"idle"}),
    "connected": frozenset({"uploading scan", "scanning", "localizing", "returning", "landed",
                            "waiting for operator", "idle", "hovering (scan done)"}),
    "uploading scan": frozenset({"starting", "waiting for operator", "scanning"}),
    "waiting for operator": frozenset({"scanning"}),
    "starting": frozenset({"scanning"}),
    "scanning": frozenset({"hovering (scan done)", "returning", "scanning", "localizing", "landed"}),
    "hovering (scan done)": frozenset({"localizing", "returning", "landed"}),
    "idle": frozenset({"localizing", "returning", "landed"}),
    "localizing": frozenset({"localizing", "returning", "landed"}),
    "returning": frozenset({"landed", "localizing", "returning"}),
    "landed": frozenset({"localizing", "returning", "landed", "starting", "waiting for pack"}),
    # sorties (issue 38): home at its reserve, it waits for the team's swap, then is started again
    "waiting for pack": frozenset({"uploading scan", "landed"}),
    "unusable": frozenset(),
}
ANY_TO = frozenset({"unusable"})
STATES = frozenset(NEXT)


def allowed(old: str, new: str) -> bool:
    return new in ANY_TO or new in NEXT.get(old, frozenset())


@dataclass(frozen=True)
class Facts:
    """What a decision about one vehicle reads, as the vehicle reported it last."""

    armed: bool
    on_ground: bool
    mode: str
    in_mission_mode: bool
    mission_seq: int | None  # the current item (MISSION_CURRENT)
    mission_state: int | None
    mission_ours: bool  # MISSION_CURRENT describes the mission we uploaded last
    rel_alt_m: float
    ground_speed_m_s: float
    silent_s: float  # wall seconds since it was last heard
    # on the ground and disarmed by its own report (HEARTBEAT disarmed, EXTENDED_SYS_STATE ON_GROUND
    # where sent): the only fact "landed" and "home" are said from (VehicleAgent.landed)
    landed: bool = False

    @property
    def airborne(self) -> bool:
        return not self.on_ground and math.isfinite(self.rel_alt_m)


def read_facts(agent) -> Facts:
    """The facts now (``agent``: a :class:`~.vehicle.VehicleAgent`)."""
    t = agent.tel
    return Facts(bool(t.armed), bool(agent.on_ground()), str(t.mode), bool(agent.in_mission_mode), t.mission_seq,
                 t.mission_state, bool(t.mission_ours), float(t.rel_alt_m), float(t.ground_speed_m_s),
                 float(agent.silent_for_s()), landed=bool(agent.landed()))


@dataclass
class VehicleLife:
    """One vehicle: its link, its state (``phase``) and what the search asked of it."""

    id: int
    connection: str
    link: object = None
    agent: object = None  # a VehicleAgent once connected
    _phase: str = "connecting"
    purpose: str = ""  # "scan" | "look" | "home"
    mission: list = field(default_factory=list)  # acknowledged wire items
    end_seq: int = 0  # seq of the final RTL item of the current mission
    targets: tuple = ()
    look_xy_m: np.ndarray | None = None
    look_first_seq: int = 0  # wire seq of the first look waypoint
    look_seqs: tuple = ()  # wire seqs of the look waypoints when terrain added waypoints between them
    looks_reported: int = 0  # looks of the current mission reported flown to the policy
    lost: bool = False
    scan_done: bool = False
    home: bool = False
    ignore_seq_until_wall: float = 0.0
    home_by_s: float = math.inf  # mission time by which a returning vehicle should have landed
    plans: int = 0  # replans that changed what this vehicle should do
    uploads: int = 0  # missions uploaded to it (scan included; carried over a restart from the store)
    skipped: int = 0  # new plans not uploaded: not worth a restarted leg (search/uploads.py)
    uploads_since_look: int = 0  # look missions uploaded in flight since it last passed a look
    deferred: bool = False  # a newer plan was not uploaded (at most one upload between two looks)
    hold_seq: int = 0  # seq of the scan's closing hold (scan done once the vehicle is there)
    unusable: str = ""  # why the vehicle cannot be commanded ("" = usable)
    job: asyncio.Task | None = None  # the exchange under way with this vehicle (its own task)
    job_late: bool = False  # the brain stopped waiting for it: replan when it ends
    flew: bool = False  # seen airborne (armed, off the ground) since it was last on the ground
    odd_moves: list = field(default_factory=list)  # moves outside NEXT (logged, kept)
    start_failed: str = ""  # why its scan could not be started ("": it was, or was never tried)
    scan_reached_seq: int = 0  # the furthest scan item seen current while it flew its scan
    landed_mid_scan: bool = False  # it landed by itself before its scan's hold: the rest is unflown
    # sorties (issue 38; service/swaps.py)
    sorties: list = field(default_factory=list)  # the scan's sortie missions still to fly after the current one
    sortie: int = 1  # the sortie it flies (or last flew)
    packs_left: int = 0  # fresh packs on the ground for it
    pack_flown: bool = False  # seen airborne on the pack it has now
    waiting: str = ""  # what it waits for on the ground ("" = nothing)
    operator_fresh: bool = False  # the operator said its pack is fresh
    unflown_sorties: int = 0  # sorties of its scan left unflown when its packs were spent
    packs_flown: int = 0  # packs it has flown on (a sortie each)
    pack_counted: bool = False  # the pack it has now is counted in packs_flown
    last_heard: object = None  # service.lost.LastHeard: what it said last, while it is lost

    @property
    def phase(self) -> str:
        return self._phase

    @phase.setter
    def phase(self, new: str) -> None:
        old = self._phase
        if new != old and not allowed(old, new):
            self.odd_moves.append((old, new))
            log.warning("vehicle %d: unexpected move %s -> %s", self.id, old, new)
        self._phase = new

    @property
    def airborne(self) -> bool:
        return self.agent is not None and not self.agent.on_ground() and math.isfinite(self.agent.tel.rel_alt_m)

    def returning(self, home_by_s: float) -> None:
        self.phase = "returning"
        self.home_by_s = home_by_s

    def observe(self, f: Facts, wall_s: float, lost_timeout_s: float,
                home_by: Callable[["VehicleLife"], float]) -> list[tuple[str, str]]:
        """One step of the state machine on the facts ``f`` read now; the events to log, as
        (kind, text). ``home_by(v)``: the mission time by which ``v`` flying home should have landed."""
        events: list[tuple[str, str]] = []
        silent = f.silent_s > lost_timeout_s
        if self.phase == "waiting for pack" and not self.lost:
            return events  # on the ground for its swap, which powers it off: silence is not a loss
        if silent and not self.lost:
            self.lost = True
            events.append(("lost", f"vehicle {self.id} silent for {lost_timeout_s:g} s: marked lost; "
                                   "its people go to the others"))
        elif self.lost and not silent:
            self.lost = False
            if self.phase == "not connected":
                self.phase = "idle"
            events.append(("found", f"vehicle {self.id} is back"))
        if self.lost:
            return events
        seq = f.mission_seq
        if self.phase == "waiting for operator" and f.armed and f.in_mission_mode:
            self.phase = "scanning"
            events.append(("start", f"vehicle {self.id} started by the operator"))
        elif self.phase == "starting" and f.armed and f.in_mission_mode and not f.on_ground:
            self.phase = "scanning"  # flying its scan, while the start exchange may still be judged
        if self.purpose == "scan" and self.sorties and self.phase == "scanning":
            # A sortie with more to come ends in RTL, not a hold: landing is its end, not a scan
            # cut short (a failsafe landing mid-sortie is taken as its end too; the next sortie
            # goes on from where this one was planned to end).
            if not f.on_ground and f.armed:
                self.flew = True
            elif self.flew and f.on_ground and not f.armed:
                self.home, self.flew = True, False
                self.phase = "landed"
                events.append(("landed", f"vehicle {self.id} landed after sortie {self.sortie} of its scan"))
            return events
        fresh = wall_s >= self.ignore_seq_until_wall and f.mission_ours
        if self.phase == "scanning" and fresh and seq is not None and self.flew:
            self.scan_reached_seq = max(self.scan_reached_seq, seq)
        past_end = seq is not None and self.end_seq and seq >= self.end_seq and fresh
        if self.hold_seq:  # the scan ends with a hold, then RTL: done once it holds
            complete = fresh and seq is not None and seq >= self.hold_seq
        else:  # a scan stored by an older daemon: done once it hovers at its end
            complete = fresh and (f.mission_state == MISSION_STATE_COMPLETE or (
                past_end and f.ground_speed_m_s < 1.0 and not f.on_ground))
        if self.phase == "scanning" and complete and self.flew:  # (a stale item of a vehicle never airborne)
            self.scan_done = True
            self.phase = "hovering (scan done)"
            events.append(("scan", f"vehicle {self.id} finished its scan"))
        if self.phase == "hovering (scan done)" and self.hold_seq and past_end:
            self.returning(home_by(self))  # the hold ran out before a new mission came: it flies home
        elif self.phase == "localizing" and past_end:
            self.returning(home_by(self))
        if not f.on_ground and f.armed:
            self.flew = True
        elif self.flew and not f.armed and self.phase in ("scanning", "hovering (scan done)", "localizing"):
            # It landed by itself (its mission's RTL, a failsafe) before we saw its mission end. A
            # look's mission is done; a scan stopped before its hold is NOT: its rest is unflown.
            if self.phase == "scanning" and self.purpose == "scan":
                self.landed_mid_scan = True
                events.append(("scan", f"vehicle {self.id} landed by itself during its scan, at item "
                                       f"{self.scan_reached_seq} of {self.hold_seq or self.end_seq}; the rest "
                                       "of its scan is not flown"))
            self.scan_done = True
            self.returning(home_by(self))
        if self.phase.startswith("returning") and f.landed and not self.home:
            # on the ground and disarmed by its own word: armed and low is still landing (issue 42)
            self.home, self.flew = True, False
            self.phase = "landed"
            events.append(("landed", f"vehicle {self.id} landed (on the ground and disarmed)"))
        if self.home and not f.on_ground and f.armed:
            self.home = False  # sent out again
            if self.phase == "landed" and f.mode in HOMING_MODES:
                # Judged landed while still armed, low and slow, it is flying its return again
                # (a return restarted by the pilot, a landing aborted): it is returning, not home.
                self.returning(home_by(self))
                events.append(("home", f"vehicle {self.id} is airborne again in {f.mode}: returning home"))
        return events
