"""A minimal ground station for tests: pymavlink as a plain codec over an asyncio UDP socket."""

from __future__ import annotations

import asyncio
import time

from uavloc_gcs.dialect import mavlink as mav


class MavClient(asyncio.DatagramProtocol):
    """Connects like ``udpout:HOST:PORT``; keeps every decoded message in ``log``."""

    def __init__(self, sysid: int = 255, compid: int = 190, key: bytes | None = None):
        self.codec = mav.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.rx = mav.MAVLink(None)
        self.rx.robust_parsing = True
        if key is not None:
            ts = int((time.time() - 1420070400) * 1e5)
            for c in (self.codec, self.rx):
                c.signing.secret_key = key
                c.signing.timestamp = ts
            self.codec.signing.sign_outgoing = True
            self.rx.signing.allow_unsigned_callback = lambda _m, _i: False
        self.log: list = []
        self._pending: list = []
        self._new = asyncio.Event()
        self.transport = None
        self.addr = None

    @classmethod
    async def connect(cls, endpoint: str, **kw) -> "MavClient":
        host, port = endpoint.split(":")[-2:]
        self = cls(**kw)
        self.addr = (host, int(port))
        await asyncio.get_running_loop().create_datagram_endpoint(lambda: self, remote_addr=self.addr)
        self.send(self.codec.heartbeat_encode(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0))
        return self

    def connection_made(self, transport) -> None:
        self.transport = transport
        sock = transport.get_extra_info("socket")
        if sock is not None:  # sped-up telemetry arrives in bursts; the kernel caps this at rmem_max
            import socket

            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)

    def datagram_received(self, data: bytes, addr) -> None:
        for m in self.rx.parse_buffer(data) or []:
            if m.get_type() == "BAD_DATA":
                continue
            m._recv_wall_s = time.monotonic()
            self.log.append(m)
            self._pending.append(m)
        self._new.set()

    def error_received(self, exc) -> None:  # pragma: no cover - loopback ICMP noise
        pass

    def send(self, msg) -> None:
        buf = msg.pack(self.codec)
        self.codec.seq = (self.codec.seq + 1) % 256
        self.transport.sendto(buf)

    def drain(self) -> None:
        self._pending.clear()

    async def recv(self, types, *, timeout: float = 3.0, where=None):
        """The next pending message of one of ``types`` (str or tuple) matching ``where``."""
        types = (types,) if isinstance(types, str) else tuple(types)
        deadline = time.monotonic() + timeout
        while True:
            while self._pending:
                m = self._pending.pop(0)
                if m.get_type() in types and (where is None or where(m)):
                    return m
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError(f"no {types} within {timeout} s")
            self._new.clear()
            try:
                await asyncio.wait_for(self._new.wait(), left)
            except asyncio.TimeoutError:
                pass

    async def command(self, target: int, command: int, *params: float, timeout: float = 3.0):
        p = list(params) + [0.0] * (7 - len(params))
        self.drain()
        self.send(mav.MAVLink_command_long_message(target, 1, command, 0, *p))
        return await self.recv("COMMAND_ACK", timeout=timeout, where=lambda m: m.command == command)

    async def take_off(self, target: int = 1, alt_m: float = 100.0) -> None:
        """GUIDED (ArduPilot custom mode 4), arm and take off to ``alt_m``; each must be accepted."""
        for cmd, params in ((mav.MAV_CMD_DO_SET_MODE, (1, 4)), (mav.MAV_CMD_COMPONENT_ARM_DISARM, (1,)),
                            (mav.MAV_CMD_NAV_TAKEOFF, (0, 0, 0, 0, 0, 0, alt_m))):
            ack = await self.command(target, cmd, *params)
            assert ack.result == 0, f"command {cmd} refused (result {ack.result})"

    async def upload(self, target: int, items, *, timeout: float = 3.0):
        """A plain mission upload (answers MISSION_REQUEST and MISSION_REQUEST_INT with
        MISSION_ITEM_INT); returns the final MISSION_ACK."""
        self.drain()
        self.send(mav.MAVLink_mission_count_message(target, 1, len(items), 0))
        while True:
            m = await self.recv(("MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK"), timeout=timeout)
            if m.get_type() == "MISSION_ACK":
                return m
            w = items[m.seq]
            self.send(mav.MAVLink_mission_item_int_message(
                target, 1, w.seq, w.frame, w.command, w.current, w.autocontinue,
                w.param1, w.param2, w.param3, w.param4, w.x, w.y, w.z, 0))

    def close(self) -> None:
        if self.transport is not None:
            self.transport.close()
