"""Test-side helpers for flying a SITL vehicle through uavloc's link layer: a live view of its
telemetry and waits that judge by state (with generous wall-clock deadlines)."""

from __future__ import annotations

import asyncio
import math
import time

from uavloc_gcs.link import flavour_for

ARMED = 128
LANDED_STATE_ON_GROUND = 1  # MAV_LANDED_STATE_ON_GROUND


def distance_m(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    k = 111_320.0
    return math.hypot((lat2 - lat1) * k, (lon2 - lon1) * k * math.cos(math.radians(lat1)))


class Watch:
    """The latest HEARTBEAT, GLOBAL_POSITION_INT, MISSION_CURRENT, HOME_POSITION, SYSTEM_TIME and
    all STATUSTEXTs and MISSION_ITEM_REACHED of one vehicle, kept from the link's receive path."""

    def __init__(self, link, system: int):
        self.link, self.system = link, system
        self.last: dict[str, object] = {}
        self.counts: dict[str, int] = {}
        self.texts: list[str] = []
        self.reached: list[int] = []
        self.seqs: list[int] = []
        self.new_mission_seen = True  # see mark_upload
        self._sub = link.subscribe(None, source_system=system, callback=self._on)

    def _on(self, msg) -> None:
        kind = msg.get_type()
        if kind == "HEARTBEAT" and msg.autopilot == 8:
            return
        self.last[kind] = msg
        self.counts[kind] = self.counts.get(kind, 0) + 1
        if kind == "STATUSTEXT":
            self.texts.append(str(msg.text).rstrip("\x00"))
        elif kind == "MISSION_ITEM_REACHED":
            self.reached.append(msg.seq)
        elif kind == "MISSION_CURRENT":
            if not self.new_mission_seen:
                self.new_mission_seen = describes_a_new_mission(msg)
            if not self.seqs or self.seqs[-1] != msg.seq:
                self.seqs.append(msg.seq)

    def mark_upload(self) -> None:
        """From now on, :attr:`mission_seq` is None until a MISSION_CURRENT describes a mission
        started since (:func:`describes_a_new_mission`)."""
        self.new_mission_seen = False

    def close(self) -> None:
        self._sub.close()

    # -- state ----------------------------------------------------------------------------
    @property
    def flavour(self):
        return flavour_for(self.last["HEARTBEAT"].autopilot)

    @property
    def armed(self) -> bool:
        hb = self.last.get("HEARTBEAT")
        return bool(hb and hb.base_mode & ARMED)

    @property
    def mode(self) -> str:
        hb = self.last["HEARTBEAT"]
        return self.flavour.mode_name(hb.custom_mode, hb.type)

    @property
    def rel_alt_m(self) -> float:
        pos = self.last.get("GLOBAL_POSITION_INT")
        return pos.relative_alt / 1000.0 if pos else math.nan

    @property
    def landed(self) -> bool:
        """Disarmed on the ground: by the vehicle's own landed state (EXTENDED_SYS_STATE) where it
        sends one, else by its relative altitude. Measured on PX4 SIH (full run, 2026-11-25):
        "Landing detected", "Disarmed by landing", and GLOBAL_POSITION_INT still 1.8 m above home."""
        if self.armed:
            return False
        ext = self.last.get("EXTENDED_SYS_STATE")
        if ext is not None and ext.landed_state == LANDED_STATE_ON_GROUND:
            return True
        return self.rel_alt_m < 1.0

    @property
    def latlon(self) -> tuple[float, float]:
        pos = self.last["GLOBAL_POSITION_INT"]
        return pos.lat / 1e7, pos.lon / 1e7

    @property
    def mission_seq(self) -> int | None:
        cur = self.last.get("MISSION_CURRENT")
        return cur.seq if cur and self.new_mission_seen else None

    @property
    def mission_state(self) -> int | None:
        cur = self.last.get("MISSION_CURRENT")
        return getattr(cur, "mission_state", None) if cur else None

    async def until(self, what: str, check, timeout_s: float, poll_s: float = 0.2):
        """Wait until ``check()`` is truthy; AssertionError naming ``what`` and the state after
        ``timeout_s`` wall seconds."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            value = check()
            if value:
                return value
            await asyncio.sleep(poll_s)
        raise AssertionError(f"vehicle {self.system}: no {what} within {timeout_s:g} s "
                             f"(mode {self.mode if 'HEARTBEAT' in self.last else '?'}, armed {self.armed}, "
                             f"alt {self.rel_alt_m:.1f} m, mission seq {self.mission_seq}, state "
                             f"{self.mission_state}, seqs {self.seqs[-12:]}, texts {self.texts[-6:]})")



def describes_a_new_mission(msg) -> bool:
    """Whether a MISSION_CURRENT received after an upload describes the new mission: the daemon's
    rule (uavloc_gcs.service.vehicle.VehicleAgent._new_mission_started) without its clock. A PX4
    that has flown a mission keeps reporting that mission's last item and state COMPLETE until the
    next mission starts; taken as news, sortie 1's RTL item 8 ended sortie 2 (RTL item 6) the
    moment it was started (CI, 2026-11-29: the vehicle took off and came straight home). A vehicle
    that reports no states (UNKNOWN) is taken at its word."""
    from uavloc_gcs.dialect import mavlink  # noqa: PLC0415

    return getattr(msg, "mission_state", mavlink.MISSION_STATE_UNKNOWN) in (
        mavlink.MISSION_STATE_UNKNOWN, mavlink.MISSION_STATE_NOT_STARTED, mavlink.MISSION_STATE_ACTIVE,
        mavlink.MISSION_STATE_PAUSED)


def seq_or_before(watch: "Watch") -> int:
    """The item the vehicle reports for the new mission, -1 before it reports one (on the ground
    before the start; a track's rows are then never taken for any item of it)."""
    seq = watch.mission_seq
    return -1 if seq is None else int(seq)


MISSION_STREAMS = {"GLOBAL_POSITION_INT": 10.0, "MISSION_CURRENT": 4.0, "SYSTEM_TIME": 1.0, "EXTENDED_SYS_STATE": 1.0}


async def fly_to_its_return(link, system: int, flavour, wire, on_position, *, what: str, timeout_s: float) -> float:
    """Fly ``wire`` from the ground on vehicle ``system``: ask for MISSION_STREAMS, upload and
    verify, start, call ``on_position(msg, watch)`` for every GLOBAL_POSITION_INT, wait until the
    mission reaches its RTL item or the vehicle returns (``what`` names that moment in a timeout),
    then bring it home and wait for the landing. Returns the wall seconds from start to RTL."""
    from uavloc_gcs.link import request_streams, return_home, start_mission_from, upload_mission  # noqa: PLC0415
    from uavloc_gcs.mission import NAV_RETURN_TO_LAUNCH  # noqa: PLC0415

    watch = Watch(link, system)
    try:
        await request_streams(link, system, flavour, MISSION_STREAMS)
        # the autopilot's own HEARTBEAT too: its mode and armed state are read below (PX4's position
        # streams can come before its 1 Hz heartbeat reaches a new subscriber: KeyError 'HEARTBEAT')
        await watch.until("position", lambda: all(k in watch.last for k in ("GLOBAL_POSITION_INT", "MISSION_CURRENT",
                                                                               "HEARTBEAT")), 30)
        sub = link.subscribe("GLOBAL_POSITION_INT", source_system=system, callback=lambda m: on_position(m, watch))
        try:
            watch.mark_upload()
            await upload_mission(link, system, 1, wire, verify=True, autopilot=flavour)
            await start_mission_from(link, system, 1, flavour, flavour.first_mission_seq, armed=watch.armed,
                                     mode=watch.mode)
            rtl = next(it.seq for it in wire if it.command == NAV_RETURN_TO_LAUNCH)
            t0 = time.monotonic()
            await watch.until(what, lambda: (watch.mission_seq or 0) >= rtl or watch.mode in ("RTL", "AUTO.RTL"),
                              timeout_s, poll_s=0.5)
            flown_wall = time.monotonic() - t0
            await return_home(link, system, 1)
            await watch.until("landing", lambda: watch.landed, 200)
        finally:
            sub.close()
    finally:
        watch.close()
    return flown_wall
