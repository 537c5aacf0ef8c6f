"""A UDP man-in-the-middle between the daemon and one fake vehicle, for per-vehicle faults.

The daemon connects to the proxy (``udpout:127.0.0.1:<port>``) instead of the vehicle. Every
MAVLink message is parsed (pymavlink as a codec only) and forwarded unchanged unless a rule says
otherwise:

* ``drop_acks_for``: COMMAND_ACKs of these commands never reach the daemon (the vehicle did the
  command; the acknowledgement is lost), plus ``drop_ack_p`` of all other COMMAND_ACKs;
* ``nack_every``: every n-th command (COMMAND_LONG/INT) is not passed on; the proxy answers it
  with COMMAND_ACK TEMPORARILY_REJECTED as the vehicle (a busy autopilot's NACK);
* ``reject_uploads``: every MISSION_COUNT is answered MISSION_ACK DENIED and not passed on (a
  vehicle that refuses every mission).

Runs its own event loop in a thread so it works next to ``run_search``'s ``asyncio.run``.
"""

from __future__ import annotations

import asyncio
import random
import threading
from dataclasses import dataclass, field

from uavloc_gcs.dialect import mavlink as M


@dataclass
class Rules:
    drop_acks_for: frozenset = frozenset()
    drop_ack_p: float = 0.0
    nack_every: int = 0
    reject_uploads: bool = False
    seed: int = 0
    counts: dict = field(default_factory=dict)  # what the proxy did, for assertions


class _Side(asyncio.DatagramProtocol):
    def __init__(self, on_data):
        self.on_data = on_data
        self.transport = None

    def connection_made(self, transport):
        self.transport = transport

    def datagram_received(self, data, addr):
        self.on_data(data, addr)


class FaultyProxy:
    def __init__(self, vehicle_port: int, sysid: int, rules: Rules):
        self.vehicle_addr = ("127.0.0.1", vehicle_port)
        self.sysid = sysid
        self.rules = rules
        self.rng = random.Random(rules.seed)
        self.port = 0
        self.gcs_addr = None
        self._from_gcs = M.MAVLink(None)
        self._from_vehicle = M.MAVLink(None)
        self._from_gcs.robust_parsing = self._from_vehicle.robust_parsing = True
        self._as_vehicle = M.MAVLink(None, srcSystem=sysid, srcComponent=1)
        self._commands = 0

    @property
    def connection(self) -> str:
        return f"udpout:127.0.0.1:{self.port}"

    def _count(self, what: str) -> None:
        self.rules.counts[what] = self.rules.counts.get(what, 0) + 1

    async def start(self) -> None:
        loop = asyncio.get_running_loop()
        self._gcs, _ = await loop.create_datagram_endpoint(lambda: _Side(self._on_gcs), local_addr=("127.0.0.1", 0))
        self._veh, _ = await loop.create_datagram_endpoint(lambda: _Side(self._on_vehicle),
                                                           remote_addr=self.vehicle_addr)
        self.port = self._gcs.get_extra_info("sockname")[1]

    def close(self) -> None:
        self._gcs.close()
        self._veh.close()

    def _reply(self, msg) -> None:
        if self.gcs_addr is not None:
            buf = msg.pack(self._as_vehicle)
            self._as_vehicle.seq = (self._as_vehicle.seq + 1) % 256
            self._gcs.sendto(buf, self.gcs_addr)

    def _on_gcs(self, data: bytes, addr) -> None:
        self.gcs_addr = addr
        r = self.rules
        for msg in self._from_gcs.parse_buffer(data) or ():
            kind = msg.get_type()
            if kind == "BAD_DATA":
                continue
            if kind in ("COMMAND_LONG", "COMMAND_INT") and r.nack_every and msg.target_system == self.sysid:
                self._commands += 1
                if self._commands % r.nack_every == 0:
                    self._count("nacked")
                    self._reply(M.MAVLink_command_ack_message(msg.command, M.MAV_RESULT_TEMPORARILY_REJECTED,
                                                              target_system=msg.get_srcSystem(),
                                                              target_component=msg.get_srcComponent()))
                    continue
            if kind == "MISSION_COUNT" and r.reject_uploads and msg.target_system == self.sysid:
                self._count("rejected uploads")
                self._reply(M.MAVLink_mission_ack_message(msg.get_srcSystem(), msg.get_srcComponent(),
                                                          M.MAV_MISSION_DENIED, msg.mission_type))
                continue
            self._veh.sendto(msg.get_msgbuf())

    def _on_vehicle(self, data: bytes, addr) -> None:
        if self.gcs_addr is None:
            return
        r = self.rules
        for msg in self._from_vehicle.parse_buffer(data) or ():
            if msg.get_type() == "BAD_DATA":
                continue
            if msg.get_type() == "COMMAND_ACK" and (msg.command in r.drop_acks_for or self.rng.random() < r.drop_ack_p):
                self._count(f"dropped ack {msg.command}")
                continue
            self._gcs.sendto(msg.get_msgbuf(), self.gcs_addr)


class ProxyThread:
    """Proxies for several vehicles on one event loop in a background thread."""

    def __init__(self, specs: list[tuple[int, int, Rules]]):  # (vehicle port, sysid, rules)
        self.proxies = [FaultyProxy(port, sysid, rules) for port, sysid, rules in specs]
        self.loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self.loop.run_forever, name="faulty-proxy", daemon=True)

    def __enter__(self) -> "ProxyThread":
        self._thread.start()
        for p in self.proxies:
            asyncio.run_coroutine_threadsafe(p.start(), self.loop).result(10)
        return self

    def __exit__(self, *exc) -> None:
        for p in self.proxies:
            self.loop.call_soon_threadsafe(p.close)
        self.loop.call_soon_threadsafe(self.loop.stop)
        self._thread.join(10)
