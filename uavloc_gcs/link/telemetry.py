"""Per-vehicle state from the messages vehicles stream, and lost/found detection.

:class:`VehicleTracker` subscribes to a :class:`~uavloc_gcs.link.connection.Link` and keeps one
:class:`VehicleState` per system id from HEARTBEAT (mode, armed, autopilot), GLOBAL_POSITION_INT,
SYS_STATUS (battery), MISSION_CURRENT, MISSION_ITEM_REACHED, STATUSTEXT and SYSTEM_TIME. A vehicle
not heard from for ``lost_after_s`` is lost; it is found again with its next message. Run
:meth:`VehicleTracker.run` in a TaskGroup to get ``on_event("lost"|"found"|"new", state)``
callbacks exactly when that happens (it sleeps until the next deadline; no polling).
"""

from __future__ import annotations

import asyncio
import collections
import logging
import time
from dataclasses import dataclass, field, replace
from typing import Callable

from ..dialect import mavlink
from .autopilots import Flavour, flavour_for
from .connection import Link

log = logging.getLogger(__name__)

LOST_AFTER_S = 5.0  # 5 missed 1 Hz heartbeats (QGC marks "communication lost" after a few seconds)
STATUSTEXT_KEPT = 20
TRACKED = ("HEARTBEAT", "GLOBAL_POSITION_INT", "SYS_STATUS", "MISSION_CURRENT", "MISSION_ITEM_REACHED",
           "STATUSTEXT", "SYSTEM_TIME")


@dataclass(frozen=True)
class StatusText:
    t_s: float  # monotonic receive time
    severity: int  # MAV_SEVERITY (0 emergency .. 7 debug)
    text: str


@dataclass
class VehicleState:
    """What we know about one vehicle. Times are ``clock()`` seconds (monotonic by default)."""

    system_id: int
    flavour: Flavour | None = None
    vehicle_type: int | None = None
    mode: str = ""
    custom_mode: int = 0
    armed: bool = False
    system_status: int = 0
    lat_deg: float | None = None
    lon_deg: float | None = None
    relative_alt_m: float | None = None
    alt_amsl_m: float | None = None
    velocity_ned_m_s: tuple[float, float, float] | None = None
    heading_deg: float | None = None
    battery_pct: float | None = None  # None: not reported (SYS_STATUS battery_remaining = -1)
    battery_v: float | None = None
    mission_seq: int | None = None  # MISSION_CURRENT.seq
    mission_total: int | None = None  # MISSION_CURRENT.total (ArduPilot: excludes home)
    mission_state: int | None = None  # MISSION_STATE
    last_reached_seq: int | None = None
    unix_time_offset_s: float | None = None  # vehicle UNIX time - our wall clock
    statustexts: collections.deque = field(default_factory=lambda: collections.deque(maxlen=STATUSTEXT_KEPT))
    last_heard_s: float = 0.0
    lost: bool = False

    @property
    def autopilot(self) -> str | None:
        """'ardupilot', 'px4', 'generic' or None before the first HEARTBEAT."""
        return self.flavour.name if self.flavour else None

    def snapshot(self) -> "VehicleState":
        """An independent copy (for handing to other tasks)."""
        return replace(self, statustexts=collections.deque(self.statustexts, maxlen=STATUSTEXT_KEPT))


Event = Callable[[str, VehicleState], None]


class VehicleTracker:
    """Keeps :class:`VehicleState` per system id for the vehicles heard on ``link``."""

    def __init__(self, link: Link, *, lost_after_s: float = LOST_AFTER_S, on_event: Event | None = None,
                 clock: Callable[[], float] = time.monotonic, wall_clock: Callable[[], float] = time.time):
        self.link = link
        self.lost_after_s = lost_after_s
        self.on_event = on_event
        self._clock = clock
        self._wall = wall_clock
        self.vehicles: dict[int, VehicleState] = {}
        self._wake = asyncio.Event()
        self._sub = link.subscribe(TRACKED, callback=self._on_message)

    def close(self) -> None:
        self._sub.close()

    def __getitem__(self, system_id: int) -> VehicleState:
        return self.vehicles[system_id]

    def is_lost(self, system_id: int) -> bool:
        v = self.vehicles.get(system_id)
        return v is None or v.lost or self._clock() - v.last_heard_s > self.lost_after_s

    # -- receive path ---------------------------------------------------------------------

    def _on_message(self, msg) -> None:
        sysid = msg.get_srcSystem()
        if sysid == self.link.mav.srcSystem:
            return  # another GCS component of ours
        kind = msg.get_type()
        v = self.vehicles.get(sysid)
        event = None
        if v is None:
            if kind != "HEARTBEAT" or msg.autopilot == mavlink.MAV_AUTOPILOT_INVALID:
                return  # vehicles are created by an autopilot heartbeat
            v = self.vehicles[sysid] = VehicleState(sysid)
            event = "new"
        elif v.lost:
            v.lost = False
            log.warning("vehicle %d found again", sysid)
            event = "found"
        now = self._clock()
        v.last_heard_s = now
        getattr(self, "_" + kind.lower())(v, msg, now)
        if event is not None:
            self._emit(event, v)
            self._wake.set()  # otherwise deadlines only move later, so run() need not wake

    def _heartbeat(self, v: VehicleState, m, now: float) -> None:
        if m.autopilot == mavlink.MAV_AUTOPILOT_INVALID:
            return  # a companion computer or gimbal of that vehicle
        v.flavour = flavour_for(m.autopilot)
        v.vehicle_type = m.type
        v.custom_mode = m.custom_mode
        v.mode = v.flavour.mode_name(m.custom_mode, m.type)
        v.armed = bool(m.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
        v.system_status = m.system_status

    def _global_position_int(self, v: VehicleState, m, now: float) -> None:
        v.lat_deg, v.lon_deg = m.lat / 1e7, m.lon / 1e7
        v.relative_alt_m, v.alt_amsl_m = m.relative_alt / 1000.0, m.alt / 1000.0
        v.velocity_ned_m_s = (m.vx / 100.0, m.vy / 100.0, m.vz / 100.0)
        v.heading_deg = None if m.hdg == 65535 else m.hdg / 100.0

    def _sys_status(self, v: VehicleState, m, now: float) -> None:
        v.battery_pct = None if m.battery_remaining < 0 else float(m.battery_remaining)
        v.battery_v = None if m.voltage_battery == 65535 else m.voltage_battery / 1000.0

    def _mission_current(self, v: VehicleState, m, now: float) -> None:
        v.mission_seq = m.seq
        total = getattr(m, "total", 0)
        v.mission_total = None if total in (0, 65535) else total
        v.mission_state = getattr(m, "mission_state", 0) or None

    def _mission_item_reached(self, v: VehicleState, m, now: float) -> None:
        v.last_reached_seq = m.seq

    def _statustext(self, v: VehicleState, m, now: float) -> None:
        text = m.text.decode("utf-8", "replace") if isinstance(m.text, (bytes, bytearray)) else str(m.text)
        v.statustexts.append(StatusText(now, m.severity, text.rstrip("\x00")))
        log.info("vehicle %d says: %s", v.system_id, text)

    def _system_time(self, v: VehicleState, m, now: float) -> None:
        if m.time_unix_usec:
            v.unix_time_offset_s = m.time_unix_usec / 1e6 - self._wall()

    def _emit(self, event: str, v: VehicleState) -> None:
        if self.on_event is not None:
            try:
                self.on_event(event, v)
            except Exception:
                log.exception("vehicle tracker event handler failed")

    # -- lost detection -------------------------------------------------------------------

    async def run(self) -> None:
        """Mark vehicles lost when they fall silent; runs until cancelled."""
        while True:
            now = self._clock()
            next_deadline = None
            for v in self.vehicles.values():
                if v.lost:
                    continue
                deadline = v.last_heard_s + self.lost_after_s
                if now >= deadline:
                    v.lost = True
                    log.warning("vehicle %d lost (silent for %.1f s)", v.system_id, now - v.last_heard_s)
                    self._emit("lost", v)
                elif next_deadline is None or deadline < next_deadline:
                    next_deadline = deadline
            self._wake.clear()
            timeout = None if next_deadline is None else max(0.0, next_deadline - self._clock())
            try:
                async with asyncio.timeout(timeout):
                    await self._wake.wait()  # a new vehicle (or a found one) moves the deadline
            except TimeoutError:
                pass
