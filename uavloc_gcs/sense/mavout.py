"""UAVLOC_RSSI_BATCH2 to the autopilot (or beside it), time-tagged in the autopilot's clock.

The companion sends from the autopilot's system id and component 191 with a 1 Hz HEARTBEAT
(MAV_TYPE_ONBOARD_CONTROLLER, MAV_AUTOPILOT_INVALID) and a TIMESYNC request every second; it
reads the autopilot's HEARTBEAT, SYSTEM_TIME, GLOBAL_POSITION_INT and TIMESYNC replies on the
autopilot link (the same link, or ``--autopilot`` when the RSSI goes beside the autopilot). Frames
are put on the autopilot's UNIX clock (:mod:`.clock`), cut into slots on that clock, placed where
the vehicle was (interpolated between position reports) and batched by the dialect's rule
(:class:`~uavloc_gcs.dialect.rssi.RssiBatcher`: 12 entries or 200 ms). Frames heard before the
clock is known, and slots whose position never arrives within :data:`POSITION_WAIT_S`, are counted
and dropped.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, replace

import numpy as np

from ..dialect import mavlink
from ..dialect.rssi import BATCH2, COMPANION_COMPONENT_ID, RssiBatcher
from ..geo import LocalFrame
from ..observations import SlotBatch
from .aggregate import slot_entries
from .clock import AutopilotClock, TrackBuffer
from .frames import Frames

log = logging.getLogger(__name__)

SLOT_LATENCY_S = 0.05  # a slot is closed this long after its end (frames still in the kernel's buffer)
POSITION_WAIT_S = 1.0  # how long a closed slot waits for the position report after it
HEARTBEAT_S = 1.0
TIMESYNC_S = 1.0


@dataclass
class SenderStats:
    frames_in: int = 0
    frames_before_clock: int = 0
    entries_sent: int = 0
    entries_no_position: int = 0
    messages: int = 0
    bytes_sent: int = 0


class RssiSender:
    """Owns the links; call :meth:`add` with frames as they arrive and :meth:`tick` every ~50 ms."""

    def __init__(self, rssi_link, autopilot_link, *, slot_s: float, sysid: int | None = None):
        self.rssi_link = rssi_link
        self.ap_link = autopilot_link
        self.slot_s = slot_s
        self.sysid = sysid
        self.clock = AutopilotClock()
        self.track = TrackBuffer()
        self.stats = SenderStats()
        self._frame: LocalFrame | None = None
        self._batcher: RssiBatcher | None = None
        self._pending: list[Frames] = []  # frames on the autopilot's UNIX clock, slots not yet closed
        self._closed_entries = None
        self._last_hb = self._last_ts = -1e9
        self._sub = autopilot_link.subscribe(("HEARTBEAT", "SYSTEM_TIME", "GLOBAL_POSITION_INT", "TIMESYNC"),
                                             callback=self._on_message)

    @property
    def ready(self) -> bool:
        """The autopilot's clock and at least one position are known."""
        return self.clock.ready and self.track.last_t is not None

    # -- receiving ----------------------------------------------------------------------------
    def _on_message(self, msg) -> None:
        kind = msg.get_type()
        src = msg.get_srcSystem()
        if kind == "HEARTBEAT":
            if self.sysid is None and msg.autopilot != mavlink.MAV_AUTOPILOT_INVALID:
                self.sysid = src
                for link in {id(self.rssi_link): self.rssi_link, id(self.ap_link): self.ap_link}.values():
                    link.mav.srcSystem = src
                log.info("following autopilot system %d", src)
            return
        if src != self.sysid or msg.get_srcComponent() != 1:
            return
        now = time.monotonic()
        if kind == "TIMESYNC" and msg.tc1 != 0:
            self.clock.on_timesync(msg.tc1, msg.ts1, now)
        elif kind == "SYSTEM_TIME":
            self.clock.on_system_time(msg.time_unix_usec, msg.time_boot_ms, now)
        elif kind == "GLOBAL_POSITION_INT" and self.clock.anchor is not None:
            lat, lon = msg.lat / 1e7, msg.lon / 1e7
            if self._frame is None:
                self._frame = LocalFrame(lat, lon)
                self._batcher = RssiBatcher(self._frame, epoch_unix_s=0.0, slot_s=self.slot_s, message=BATCH2)
            self.track.add(float(self.clock.boot_to_unix(msg.time_boot_ms / 1e3)), lat, lon, msg.relative_alt / 1e3)

    # -- sending ------------------------------------------------------------------------------
    def _send(self, link, msg) -> None:
        link.send_nowait(msg)
        self.stats.bytes_sent += len(msg.get_msgbuf())

    def add(self, frames: Frames) -> None:
        """Frames stamped on the companion's UNIX clock (the kernel's capture time)."""
        self.stats.frames_in += len(frames)
        if not len(frames):
            return
        if not self.clock.ready:
            self.stats.frames_before_clock += len(frames)
            return
        mono = frames.t_s - (time.time() - time.monotonic())
        self._pending.append(replace(frames, t_s=np.asarray(self.clock.companion_to_unix(mono))))

    def tick(self, *, final: bool = False) -> None:
        now = time.monotonic()
        if now - self._last_hb >= HEARTBEAT_S:
            self._last_hb = now
            hb = mavlink.MAVLink_heartbeat_message(mavlink.MAV_TYPE_ONBOARD_CONTROLLER, mavlink.MAV_AUTOPILOT_INVALID,
                                                   0, 0, mavlink.MAV_STATE_ACTIVE, 3)
            self._send(self.ap_link, hb)
            if self.rssi_link is not self.ap_link:
                self._send(self.rssi_link, hb)
        if now - self._last_ts >= TIMESYNC_S and self.sysid is not None:
            self._last_ts = now
            self._send(self.ap_link, mavlink.MAVLink_timesync_message(0, int(now * 1e9)))
        if not self.clock.ready or self._batcher is None:
            return
        ap_now = float(self.clock.companion_to_unix(now))
        self._close_slots(ap_now, final)
        # a keepalive may claim only what is closed: slots still open or waiting for a position
        # are not sent yet
        complete = ap_now - SLOT_LATENCY_S - self.slot_s
        complete = min([complete] + [float(np.min(f.t_s)) for f in self._pending if len(f)])
        for msg in self._batcher.flush(now_s=ap_now, force=final, complete_until_s=complete):
            self._send(self.rssi_link, msg)
            self.stats.messages += 1
            self.stats.entries_sent += msg.count

    def _close_slots(self, ap_now: float, final: bool) -> None:
        frames = Frames.concat(self._pending) if self._pending else None
        if frames is None or not len(frames):
            return
        slot_end = (np.floor(frames.t_s / self.slot_s) + 1) * self.slot_s
        last_pos = self.track.last_t if self.track.last_t is not None else -np.inf
        ready = (slot_end + SLOT_LATENCY_S <= ap_now) & (slot_end - self.slot_s <= last_pos)
        expired = (slot_end + SLOT_LATENCY_S + POSITION_WAIT_S <= ap_now) & ~ready
        if final:
            ready |= ~expired
        done = ready | expired
        self._pending = [frames.take(~done)] if np.any(~done) else []
        if np.any(ready):
            self._emit(frames.take(ready))
        if np.any(expired):
            self.stats.entries_no_position += len(slot_entries(frames.take(expired), self.slot_s))

    def _emit(self, frames: Frames) -> None:
        e = slot_entries(frames, self.slot_s)
        ok, pos = self.track.at(e.t_s)
        self.stats.entries_no_position += int(np.sum(~ok))
        if not np.any(ok):
            return
        east, north = self._frame.to_local(pos[ok, 0], pos[ok, 1])
        xyz = np.column_stack([east, north, pos[ok, 2]])
        k = int(np.sum(ok))
        slots = SlotBatch.from_columns(e.t_s[ok], np.full(k, self.sysid), xyz, e.address[ok], e.rssi_dbm[ok],
                                       e.n_frames[ok], address=e.address[ok], fingerprint=e.fingerprint[ok],
                                       channel=e.channel[ok], radio=e.radio[ok])
        for msg in self._batcher.add(slots):
            self._send(self.rssi_link, msg)
            self.stats.messages += 1
            self.stats.entries_sent += msg.count

    def close(self) -> None:
        self._sub.close()


async def open_sender(rssi_url: str, autopilot_url: str | None, *, slot_s: float, sysid: int | None,
                      signing_key: bytes | None = None) -> RssiSender:
    from ..link.connection import open_link

    first = sysid or 1
    rssi = await open_link(rssi_url, source_system=first, source_component=COMPANION_COMPONENT_ID,
                           signing_key=signing_key, heartbeat_interval_s=None)
    ap = rssi
    if autopilot_url:
        try:
            ap = await open_link(autopilot_url, source_system=first, source_component=COMPANION_COMPONENT_ID,
                                 signing_key=signing_key, heartbeat_interval_s=None)
        except BaseException:
            await rssi.close()
            raise
    return RssiSender(rssi, ap, slot_s=slot_s, sysid=sysid)
