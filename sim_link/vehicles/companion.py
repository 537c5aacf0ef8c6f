"""Companion-computer emulator: RSSI of simulated people, heard along a REAL autopilot's flight.

Attach it to ArduPilot or PX4 SITL (``tcp:127.0.0.1:5760``, ``udpin:0.0.0.0:14540``, ...). It
follows the autopilot's GLOBAL_POSITION_INT, asks :class:`sim_link.world.World` what a receiver at
that position hears in each time slot (the same world model the fake vehicles use), and sends
UAVLOC_RSSI_BATCH2 from component 191 of the autopilot's system, with a 1 Hz HEARTBEAT
(MAV_TYPE_ONBOARD_CONTROLLER). Each entry carries what the world says a sensor heard in the slot:
the source address, the content fingerprint, the channel, the frame count and the mean RSSI (the
paper's continuous world gives address = emitter id, fingerprint 0 and channel 0, sent as they are).

Two paths to the ground (docs/guide/daemon.md, "The RSSI path"):

- through the autopilot (default): the batches go to ``autopilot_url`` and the autopilot routes
  them to the ground station as a real companion's. ArduPilot forwards a message id it does not
  know only with ``MAVn_OPTIONS`` bit 3 (value 8) set on the companion's serial port; PX4 drops
  message ids its dialect does not know, so on PX4 this path delivers nothing;
- beside the autopilot (``rssi_url``): the batches (and the heartbeat) go to their own
  connection, as a router on the companion (mavlink-router) or a second radio would carry them,
  and the daemon listens there (``[link] rssi_connections``). Positions and time are still read
  from the autopilot at ``autopilot_url``.

Time: the autopilot's first SYSTEM_TIME pairs UNIX time with its boot clock; each position is
stamped ``unix = time_unix_usec + (gpi.time_boot_ms - system_time.time_boot_ms)`` from that one
anchor, so a sped-up SITL stays consistent (PX4 SIH sends time_unix_usec at the host's rate but its
boot clock at the simulation's: re-anchoring on every SYSTEM_TIME would squeeze the track in time). Mission time ``t = unix - epoch_unix_s`` (default: the first UNIX time seen).
Slot positions are interpolated between consecutive position reports; after a gap longer than
``max_gap_s`` the slot grid restarts at the new report instead of inventing a track.
"""

from __future__ import annotations

import asyncio
import logging
import math
import time
from dataclasses import dataclass

import numpy as np

from uavloc_gcs.dialect import mavlink as mav
from uavloc_gcs.dialect.rssi import BATCH2, COMPANION_COMPONENT_ID, RssiBatcher
from uavloc_gcs.scenario import Scenario

from .connection import ByteLink, open_link, parse_url

log = logging.getLogger(__name__)

HEARTBEAT_S = 1.0
MAX_GAP_S = 1.0
AIRBORNE_M = 0.5  # below this height the vehicle is on the ground: nothing is reported


@dataclass
class CompanionStats:
    positions: int = 0
    slots: int = 0
    messages: int = 0
    bytes_sent: int = 0


class CompanionEmulator:
    def __init__(self, scenario: Scenario, autopilot_url: str, *, world=None, seed: int | None = None,
                 epoch_unix_s: float | None = None, signing_key: bytes | None = None, max_gap_s: float = MAX_GAP_S,
                 rssi_url: str | None = None, via_sense: bool = False):
        if world is None:
            from ..world import World

            world = World(scenario, seed=scenario.simulation.seed if seed is None else seed)
        self.scenario = scenario
        self.world = world
        self.url = autopilot_url
        self.rssi_url = rssi_url
        self.via_sense = via_sense  # send what the real sensor makes of the world's frames (sensor_feed)
        self._rssi_link: ByteLink | None = None
        self.epoch_unix_s = epoch_unix_s
        self.max_gap_s = max_gap_s
        self.signing_key = signing_key
        self.sysid: int | None = None
        self.stats = CompanionStats()
        self._rx = mav.MAVLink(None)
        self._rx.robust_parsing = True
        self._tx: mav.MAVLink | None = None
        self._time_ref: tuple[int, int] | None = None  # (time_unix_usec, time_boot_ms)
        self._last: tuple[float, np.ndarray] | None = None  # (t, xyz) of the previous position
        self._next_slot_s: float | None = None
        self._batcher: RssiBatcher | None = None
        self._link: ByteLink | None = None

    # ---------------------------------------------------------------- running
    async def run(self, stop: asyncio.Event | None = None) -> None:
        """Connect and work until ``stop`` is set (or the TCP link closes)."""
        stop = stop or asyncio.Event()
        self._link = await open_link(self.url, self._on_bytes)
        log.info("companion emulator attached to %s", self.url)
        if self.rssi_url is not None:
            try:
                self._rssi_link = await open_link(self.rssi_url, lambda data: None)
            except BaseException:
                self._link.close()
                raise
            log.info("companion emulator sends RSSI beside the autopilot, to %s", self.rssi_url)
        try:
            # over udpout the autopilot only learns our address from a datagram: announce
            # ourselves at once (as system 1 until its HEARTBEAT tells us its id)
            announce = parse_url(self.url)[0] == "udpout"
            while not stop.is_set() and not self._link.closed.is_set():
                if self.sysid is not None or announce:
                    self._send_heartbeat()
                try:
                    await asyncio.wait_for(stop.wait(), HEARTBEAT_S)
                except asyncio.TimeoutError:
                    pass
        finally:
            self._link.close()
            if self._rssi_link is not None:
                self._rssi_link.close()

    def _codec(self, sysid: int) -> mav.MAVLink:
        if self._tx is None or self._tx.srcSystem != sysid:
            self._tx = mav.MAVLink(None, srcSystem=sysid, srcComponent=COMPANION_COMPONENT_ID)
            if self.signing_key is not None:
                self._tx.signing.secret_key = self.signing_key
                self._tx.signing.sign_outgoing = True
                self._tx.signing.timestamp = int((time.time() - 1420070400) * 1e5)
        return self._tx

    def _send(self, msg, *, rssi: bool = False) -> None:
        """To the autopilot; with ``rssi`` and a separate RSSI connection, to that one instead."""
        codec = self._codec(self.sysid or 1)
        buf = msg.pack(codec)
        codec.seq = (codec.seq + 1) % 256
        self.stats.bytes_sent += len(buf)
        (self._rssi_link if rssi and self._rssi_link is not None else self._link).send(buf)

    def _send_heartbeat(self) -> None:
        hb = mav.MAVLink_heartbeat_message(mav.MAV_TYPE_ONBOARD_CONTROLLER, mav.MAV_AUTOPILOT_INVALID,
                                           0, 0, mav.MAV_STATE_ACTIVE, 3)
        self._send(hb)
        if self._rssi_link is not None and self.sysid is not None:
            self._send(hb, rssi=True)  # the ground sees the companion on its own path too

    # ---------------------------------------------------------------- receiving
    def _on_bytes(self, data: bytes) -> None:
        for msg in self._rx.parse_buffer(data) or []:
            kind = msg.get_type()
            if kind == "BAD_DATA" or msg.get_srcComponent() != 1:
                continue  # only the autopilot's own messages
            if self.sysid is None and kind == "HEARTBEAT" and msg.type != mav.MAV_TYPE_GCS:
                self.sysid = msg.get_srcSystem()
                log.info("companion emulator: autopilot is system %d", self.sysid)
                self._send_heartbeat()
            if msg.get_srcSystem() != self.sysid:
                continue
            if kind == "SYSTEM_TIME" and msg.time_unix_usec > 0:
                if self._time_ref is None or msg.time_boot_ms < self._time_ref[1]:  # anchor once (see below)
                    self._time_ref = (int(msg.time_unix_usec), int(msg.time_boot_ms))
            elif kind == "GLOBAL_POSITION_INT":
                self._on_position(msg)

    def _unix_s(self, time_boot_ms: int) -> float:
        if self._time_ref is None:
            return time.time()
        unix_us, boot_ms = self._time_ref
        return (unix_us + (time_boot_ms - boot_ms) * 1000) / 1e6

    def _on_position(self, msg) -> None:
        unix = self._unix_s(int(msg.time_boot_ms))
        if self.epoch_unix_s is None:
            self.epoch_unix_s = unix
        t = unix - self.epoch_unix_s
        e, n = self.scenario.frame.to_local(msg.lat / 1e7, msg.lon / 1e7)
        xyz = np.array([float(e), float(n), msg.relative_alt / 1000.0])
        self.stats.positions += 1
        if self._batcher is None:
            self._batcher = RssiBatcher(self.scenario.frame, self.epoch_unix_s, self.scenario.channel.slot_s,
                                        message=BATCH2)
        last, self._last = self._last, (t, xyz)
        slot = self.scenario.channel.slot_s
        if last is None or t - last[0] > self.max_gap_s or t <= last[0]:
            self._next_slot_s = math.ceil(t / slot - 1e-9) * slot
            return
        t0, p0 = last
        k0 = max(self._next_slot_s, math.ceil(t0 / slot - 1e-9) * slot)
        ts = np.arange(round(k0 / slot), math.floor(t / slot + 1e-9) + 1) * slot
        ts = ts[(ts >= k0 - 1e-9) & (ts <= t + 1e-9)]
        if len(ts) == 0:
            return
        self._next_slot_s = ts[-1] + slot
        w = ((ts - t0) / (t - t0))[:, None]
        track = p0[None, :] * (1 - w) + xyz[None, :] * w
        airborne = track[:, 2] >= AIRBORNE_M
        ts, track = ts[airborne], track[airborne]
        if len(ts) == 0:
            return
        heard = self.world.hear_track(self.sysid, ts, track)
        if self.via_sense:
            from .sensor_feed import through_sensor

            heard = through_sensor(heard, slot, self.epoch_unix_s)
        self.stats.slots += len(heard)
        for m in self._batcher.add(heard) + self._batcher.flush(now_s=t):
            self.stats.messages += 1
            self._send(m, rssi=True)
