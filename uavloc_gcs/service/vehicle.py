"""One vehicle as the daemon sees it: its link, its telemetry, its RSSI, and the few actions
the search needs (upload, download, start, switch mission, return home).

Telemetry is kept from the raw messages (HEARTBEAT, GLOBAL_POSITION_INT, SYS_STATUS,
MISSION_CURRENT, SYSTEM_TIME, EXTENDED_SYS_STATE) in the link's receive path; RSSI batches are
decoded into :class:`SlotBatch` on the mission clock and handed to ``on_slots``. The protocol exchanges
themselves (mission transfer, commands with COMMAND_ACK) are the link layer's.
"""

from __future__ import annotations

import logging
import math
import time
from collections import deque
from dataclasses import dataclass
from typing import Callable, Sequence

from ..dialect import RSSI_MESSAGE_TYPES, mavlink
from ..dialect.rssi import decode_rssi_batch, message_time_s
from ..link import (disarm, download_mission, flavour_named, return_home, start_mission_from, switch_mission,
                    upload_mission)
from ..geo import LocalFrame
from ..mission import WireItem
from ..observations import SlotBatch

log = logging.getLogger(__name__)

MAV_MODE_FLAG_SAFETY_ARMED = 128
# below this relative altitude (and disarmed or not moving) a vehicle may be on the ground: what a
# start decides by (a mission without a take-off is never started there), never a claim that it landed
LANDED_ALT_M = 1.5
MISSION_MODES = ("AUTO", "AUTO.MISSION")  # ArduPilot, PX4


@dataclass
class Telemetry:
    """The latest telemetry of one vehicle. ``wall_s`` is the daemon's clock at the last message."""

    lat_deg: float = math.nan
    lon_deg: float = math.nan
    rel_alt_m: float = math.nan
    ground_speed_m_s: float = math.nan
    battery_pct: float | None = None
    autopilot: int = 0
    mode: str = "?"
    armed: bool = False
    mission_seq: int | None = None
    mission_total: int | None = None
    mission_state: int | None = None
    unix_s: float | None = None  # the vehicle's clock (SYSTEM_TIME), simulated time under speed-up
    unix_wall_s: float | None = None  # daemon wall clock when unix_s arrived
    mission_ours: bool = True  # MISSION_CURRENT describes the mission we uploaded last (see VehicleAgent)
    landed_state: int | None = None  # EXTENDED_SYS_STATE's MAV_LANDED_STATE, where the autopilot sends it
    heartbeats: int = 0  # the autopilot's own HEARTBEATs heard (armed is known only after the first)
    # Ready to arm, as each autopilot reports it (None: not reported): SYS_STATUS's pre-arm check
    # health bit (MAV_SYS_STATUS_PREARM_CHECK, ArduPilot and PX4), GPS_RAW_INT's fix type,
    # ESTIMATOR_STATUS's absolute horizontal position flag (PX4), ArduPilot's "EKF3 IMU0 is using GPS"
    prearm_ok: bool | None = None
    gps_fix_type: int | None = None
    estimator_pos_ok: bool | None = None
    using_gps_said: bool = False
    wall_s: float = -math.inf
    messages: int = 0


BOOT_CLOCK_SLACK_MS = 1000  # a boot clock this far behind the newest one seen is a reboot, not reordering


class VehicleAgent:
    """Telemetry and RSSI of one MAVLink system on one link, with the search's actions."""

    def __init__(self, vehicle: int, link, frame: LocalFrame, *, autopilot: str,
                 epoch_unix_s: Callable[[], float | None],
                 on_slots: Callable[[SlotBatch], None] | None = None,
                 on_position: Callable[[int, Telemetry], None] | None = None,
                 on_status_text: Callable[[int, str], None] | None = None,
                 on_mission_seq: Callable[[int, Telemetry], None] | None = None,
                 wall: Callable[[], float] = time.monotonic):
        self.vehicle = vehicle
        self.link = link
        self.frame = frame
        self.autopilot = autopilot
        self.flavour = flavour_named(autopilot)
        self.tel = Telemetry()
        self._epoch = epoch_unix_s
        self._on_slots = on_slots
        self._on_position = on_position
        self._on_status_text = on_status_text
        self._on_mission_seq = on_mission_seq
        self._wall = wall
        self._pending_rssi: list = []  # raw messages that arrived before the epoch was known
        self.rssi_messages = 0
        # Mission time up to which this vehicle's receiver has reported everything it heard (the
        # RSSI messages' times), and how many keepalives it sent: a receiver that sends them says
        # "heard nothing" as such (dialect.rssi.KEEPALIVE_S), one that does not only by silence.
        self.heard_until_s = -math.inf
        self.keepalives = 0
        self.upload_opaque_id = 0  # the plan id of our last upload's MISSION_ACK (0: not given)
        self._acked_wall_s: float | None = None  # when our last upload was acknowledged
        self._time_anchor: tuple[float, int] | None = None  # (unix s, time_boot_ms) of the first SYSTEM_TIME
        self._last_boot_ms: int | None = None  # the newest boot clock seen: a reboot restarts it
        self._anchor_provisional = False  # the anchor carried over a reboot, until the next SYSTEM_TIME
        self.texts: deque[tuple[float, str]] = deque(maxlen=20)  # (daemon wall s, STATUSTEXT), newest last
        self.airborne_wall_s = -math.inf  # when it was last seen armed and off the ground (daemon wall s)
        # after a swap (sorties): not ready to arm while it reports less remaining than a fresh pack
        self.pack_floor_pct: float | None = None
        self._sub = link.subscribe(None, source_system=vehicle, callback=self._on_message)
        self._rssi_subs: list = []

    def close(self) -> None:
        self._sub.close()
        for sub in self._rssi_subs:
            sub.close()

    def attach_rssi(self, link) -> None:
        """Also take this vehicle's RSSI from ``link``, a connection beside the autopilot (a router
        on the companion, a second radio; ``[link] rssi_connections``)."""
        self._rssi_subs.append(link.subscribe(RSSI_MESSAGE_TYPES, source_system=self.vehicle,
                                              callback=self._on_rssi_beside))

    def _on_rssi_beside(self, msg) -> None:
        self.rssi_messages += 1
        self._rssi(msg)

    # -- receive path ---------------------------------------------------------------------------
    def _on_message(self, msg) -> None:
        t = self.tel
        t.wall_s = self._wall()
        t.messages += 1
        kind = msg.get_type()
        if kind in RSSI_MESSAGE_TYPES:  # UAVLOC_RSSI_BATCH2, or the old UAVLOC_RSSI_BATCH
            self.rssi_messages += 1
            self._rssi(msg)
        elif kind == "GLOBAL_POSITION_INT":
            self._clock(int(msg.time_boot_ms))
            t.lat_deg, t.lon_deg = msg.lat / 1e7, msg.lon / 1e7
            t.rel_alt_m = msg.relative_alt / 1000.0
            t.ground_speed_m_s = math.hypot(msg.vx, msg.vy) / 100.0
            if t.armed and not self.on_ground():
                self.airborne_wall_s = t.wall_s
            if self._on_position is not None:
                self._on_position(self.vehicle, t)
        elif kind == "HEARTBEAT":
            if msg.autopilot == 8:  # MAV_AUTOPILOT_INVALID: a GCS or companion, not the autopilot
                return
            t.autopilot = msg.autopilot
            t.heartbeats += 1
            t.armed = bool(msg.base_mode & MAV_MODE_FLAG_SAFETY_ARMED)
            t.mode = self.flavour.mode_name(msg.custom_mode, msg.type)
        elif kind == "EXTENDED_SYS_STATE":
            if msg.landed_state != mavlink.MAV_LANDED_STATE_UNDEFINED:
                t.landed_state = int(msg.landed_state)
        elif kind == "SYS_STATUS":
            if msg.battery_remaining >= 0:
                t.battery_pct = float(msg.battery_remaining)
            bit = mavlink.MAV_SYS_STATUS_PREARM_CHECK
            if msg.onboard_control_sensors_present & bit and msg.onboard_control_sensors_enabled & bit:
                t.prearm_ok = bool(msg.onboard_control_sensors_health & bit)
        elif kind == "GPS_RAW_INT":
            t.gps_fix_type = int(msg.fix_type)
        elif kind == "ESTIMATOR_STATUS":
            t.estimator_pos_ok = bool(msg.flags & mavlink.ESTIMATOR_POS_HORIZ_ABS)
        elif kind == "MISSION_CURRENT":
            seq, before = int(msg.seq), t.mission_seq
            t.mission_seq = seq
            total = getattr(msg, "total", 0)
            t.mission_total = int(total) if total not in (0, 65535) else None
            t.mission_state = getattr(msg, "mission_state", None)
            if not t.mission_ours:
                t.mission_ours = self._new_mission_started(t.mission_state, t.wall_s)
            if seq != before and self._on_mission_seq is not None:
                self._on_mission_seq(self.vehicle, t)
        elif kind == "SYSTEM_TIME":
            if msg.time_unix_usec > 0:
                self._rebooted(int(msg.time_boot_ms))
                if self._time_anchor is None or self._anchor_provisional:  # the first, or the first since a reboot
                    self._time_anchor = (msg.time_unix_usec / 1e6, int(msg.time_boot_ms))
                    self._anchor_provisional = False
                self._clock(int(msg.time_boot_ms))
        elif kind == "STATUSTEXT":
            text = str(msg.text).rstrip("\x00")
            self.texts.append((t.wall_s, text))
            if "is using gps" in text.lower():  # ArduPilot's EKF: "EKF3 IMU0 is using GPS"
                t.using_gps_said = True
            if self._on_status_text is not None:
                self._on_status_text(self.vehicle, text)

    def _rssi(self, msg) -> None:
        epoch = self._epoch()
        if epoch is None:
            self._pending_rssi.append(msg)
            return
        if self._pending_rssi:
            pending, self._pending_rssi = self._pending_rssi, []
            for m in pending:
                self._deliver(m, epoch)
        self._deliver(msg, epoch)

    def _deliver(self, msg, epoch: float) -> None:
        batch = decode_rssi_batch(msg, self.frame, vehicle=self.vehicle, epoch_unix_s=epoch)
        if len(batch) and self._on_slots is not None:
            self._on_slots(batch)
        # after the slots: whoever reads both sees every slot before heard_until_s
        if int(msg.count) == 0:
            self.keepalives += 1
        self.heard_until_s = max(self.heard_until_s, message_time_s(msg, epoch_unix_s=epoch))

    def _clock(self, time_boot_ms: int) -> None:
        """The vehicle's clock: UNIX time anchored once at its first SYSTEM_TIME, then advanced by
        its boot clock. PX4 SIH under a speed-up sends time_unix_usec at the host's (wall) rate but
        time_boot_ms at the simulation's: re-reading the UNIX time would slow the mission clock
        down by the speed-up (measured 10.2 s of UNIX time for 49 s of boot time at 5x)."""
        self._rebooted(time_boot_ms)
        if self._time_anchor is None:
            return
        unix0, boot0 = self._time_anchor
        self.tel.unix_s = unix0 + (time_boot_ms - boot0) / 1000.0
        self.tel.unix_wall_s = self.tel.wall_s

    def _rebooted(self, time_boot_ms: int) -> None:
        """A boot clock that went back (a reboot: a battery swap powers the autopilot off) moves the
        anchor: the clock goes on from its last reading with the new boot clock until the vehicle's
        next SYSTEM_TIME anchors it again. Kept, the old anchor dated every position after a swap
        back by the first sortie's boot time (the fake PX4's mission clock went from 192 s back to
        26 s), and on PX4, which sends SYSTEM_TIME only when asked, for the rest of the search."""
        last = self._last_boot_ms
        if last is not None and time_boot_ms + BOOT_CLOCK_SLACK_MS < last and self._time_anchor is not None:
            # go on from the last reading (the reboot's own seconds are not known: at most a few
            # seconds early) until the vehicle's next SYSTEM_TIME anchors it again
            self._time_anchor = (self.tel.unix_s if self.tel.unix_s is not None else self._time_anchor[0],
                                 time_boot_ms)
            self._anchor_provisional = True
        self._last_boot_ms = time_boot_ms

    def _new_mission_started(self, state: int | None, wall_s: float) -> bool:
        """Whether a MISSION_CURRENT received after our upload was acknowledged describes our mission.

        A PX4 that has flown a mission since boot keeps reporting mission_state COMPLETE (and that
        mission's item) until the next mission starts, also after a new upload; taken at face value
        that ended a scan the moment it began. This dialect's MISSION_CURRENT carries no mission id
        to compare with the ACK's opaque id, so the judgment is "a new mission started": a state
        other than COMPLETE (not started, active, paused) reported after the ACK; from a vehicle
        that does not report states (UNKNOWN), any report a second after the ACK.
        """
        if self._acked_wall_s is None or wall_s < self._acked_wall_s:
            return False
        if state in (None, mavlink.MISSION_STATE_UNKNOWN):
            return wall_s >= self._acked_wall_s + 1.0
        return state in (mavlink.MISSION_STATE_NOT_STARTED, mavlink.MISSION_STATE_ACTIVE,
                         mavlink.MISSION_STATE_PAUSED)

    # -- state ------------------------------------------------------------------------------------
    def silent_for_s(self) -> float:
        return self._wall() - self.tel.wall_s

    def position_xy_m(self) -> tuple[float, float] | None:
        if not math.isfinite(self.tel.lat_deg):
            return None
        e, n = self.frame.to_local(self.tel.lat_deg, self.tel.lon_deg)
        return float(e), float(n)

    def landed(self) -> bool:
        """On the ground and disarmed, as the vehicle says it: disarmed in its HEARTBEAT and, where
        the autopilot sends EXTENDED_SYS_STATE, landed state ON_GROUND. The only ground for saying
        "landed" or "home" (issue 42): never a height-and-speed guess. Measured on SITL
        (``python -m tests.sitl.landing_measure``): ArduCopter is armed in LANDING below 1.5 m,
        sinking at 0.5 m/s, for 5 s before it touches down and disarms; PX4 SIH's height on the
        ground wanders by +-1 m while it is still armed, for about 10 s."""
        t = self.tel
        if t.heartbeats == 0 or t.armed:
            return False
        return t.landed_state is None or t.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND

    def on_ground(self) -> bool:
        """Whether the vehicle may be on the ground: what a start decides by (a mission is started
        there only with a take-off), never a claim that it landed (:meth:`landed`)."""
        # Disarmed and on the ground by the autopilot's own word, whatever the altitude says: PX4
        # SITL measured landed, disarmed and "on ground" at 2.2 m relative altitude (its height
        # estimate drifted in flight), which the altitude rule alone took for still airborne.
        if not self.tel.armed and self.tel.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND:
            return True
        alt = self.tel.rel_alt_m
        return math.isfinite(alt) and alt < LANDED_ALT_M and (not self.tel.armed or self.tel.ground_speed_m_s < 0.5)

    def not_ready(self) -> str | None:
        """Why the vehicle is not ready to arm, as it reports it now, or None (ready, or it reports
        nothing that says otherwise: its own arming checks still apply)."""
        t = self.tel
        why = []
        if t.prearm_ok is False:
            said = next((text for _w, text in reversed(self.texts) if text.lower().startswith(("prearm", "preflight"))),
                        None)
            why.append("its pre-arm checks fail" + (f" (\"{said}\")" if said else ""))
        if t.estimator_pos_ok is False:
            why.append("its estimator has no absolute position yet")
        if t.gps_fix_type is not None and t.gps_fix_type < 3 and not t.using_gps_said:
            why.append(f"no 3D GPS fix (GPS_RAW_INT fix type {t.gps_fix_type})")
        if self.pack_floor_pct is not None and t.battery_pct is not None and t.battery_pct < self.pack_floor_pct:
            why.append(f"its pack is not fresh ({t.battery_pct:.0f} % remaining; a fresh one reports "
                       f"{self.pack_floor_pct:g} % or more)")
        return "; ".join(why) or None

    # -- actions (the link layer's exchanges) -------------------------------------------------------
    @property
    def in_mission_mode(self) -> bool:
        return self.tel.mode in MISSION_MODES

    async def upload(self, items: Sequence[WireItem]) -> None:
        """Upload and verify by reading back (MissionTransferError names vehicle, item, result)."""
        result = await upload_mission(self.link, self.vehicle, 1, list(items), verify=True, autopilot=self.autopilot)
        # from now on the mission state reported is stale until the vehicle shows it started ours
        self.upload_opaque_id = getattr(result, "opaque_id", 0) or 0
        self._acked_wall_s = self._wall()
        self.tel.mission_ours = False
        return result

    async def download(self) -> list[WireItem]:
        return list(await download_mission(self.link, self.vehicle, 1))

    async def start(self, first_seq: int | None = None, *, before_start: Callable[[], None] | None = None) -> None:
        """Arm on the ground (waiting until the vehicle is ready; the error names its own reason)
        and fly the uploaded mission from ``first_seq`` (default: its first item, the takeoff).
        The per-autopilot sequence is the link layer's (link/mission_control.py); ``before_start()``
        is called right before arming and before every MISSION_START, and may raise."""
        first = self.flavour.first_mission_seq if first_seq is None else max(first_seq, self.flavour.first_mission_seq)
        await start_mission_from(self.link, self.vehicle, 1, self.flavour, first, armed=self.tel.armed,
                                 mode=self.tel.mode, before_start=before_start)

    async def switch_to(self, first_seq: int, *, before_start: Callable[[], None] | None = None,
                        on_ground: bool | None = None) -> None:
        """Fly the just-uploaded mission from item ``first_seq``: started (armed, taking off) when
        the vehicle is on the ground and disarmed now, switched to in flight otherwise.
        ``on_ground`` is ignored (kept for old callers): whether it is on the ground is read here,
        when the switch begins, never taken from before an upload (issue 26)."""
        if self.on_ground() and not self.tel.armed:
            await self.start(first_seq, before_start=before_start)
            return
        await switch_mission(self.link, self.vehicle, 1, self.flavour, first_seq, in_mission_mode=self.in_mission_mode,
                             mission_state=self.tel.mission_state, before_start=before_start)

    async def disarm(self) -> None:
        """Disarm (not forced: an autopilot refuses it in the air)."""
        await disarm(self.link, self.vehicle, 1)

    async def return_home(self) -> None:
        await return_home(self.link, self.vehicle, 1)
