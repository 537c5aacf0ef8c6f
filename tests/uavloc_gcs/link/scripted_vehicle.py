"""A small scripted vehicle for link tests: the vehicle side of the mission and command protocols
over UDP on loopback, ArduPilot-style or PX4-style, with injected loss, duplication and
reordering. It uses pymavlink only as a codec, like the code under test, but shares none of it.

ArduPilot style (MissionItemProtocol.cpp): requests items with MISSION_REQUEST, re-requests every
1 s, NACKs an out-of-order item with INVALID_SEQUENCE and carries on, gives up after 8 s, reports
its own home as seq 0. PX4 style (mavlink_mission.cpp): MISSION_REQUEST_INT, re-requests every
0.25 s, ignores out-of-order items, re-ACKs a duplicate last item, gives up after 5 s.
"""

from __future__ import annotations

import asyncio
import random
import time
from dataclasses import dataclass, field

from uavloc_gcs.dialect import mavlink
from uavloc_gcs.mission import WireItem

M = mavlink


@dataclass
class Faults:
    loss: float = 0.0  # probability each packet (either direction) is dropped
    duplicate: float = 0.0  # probability an outgoing packet is sent twice
    reorder: float = 0.0  # probability an outgoing packet is held back behind the next one
    seed: int = 0


@dataclass
class Style:
    name: str
    autopilot: int
    request_type: str
    rerequest_s: float
    give_up_s: float
    home_at_seq0: bool


ARDUPILOT = Style("ardupilot", M.MAV_AUTOPILOT_ARDUPILOTMEGA, "MISSION_REQUEST", 1.0, 8.0, True)
PX4 = Style("px4", M.MAV_AUTOPILOT_PX4, "MISSION_REQUEST_INT", 0.25, 5.0, False)
HOME = (473977420, 85455940, 488.0)  # degE7, degE7, m AMSL


@dataclass
class VehicleState:
    custom_mode: int = 0
    armed: bool = False
    current_seq: int = 0
    mission: list[WireItem] = field(default_factory=list)
    uploads_completed: int = 0


class ScriptedVehicle(asyncio.DatagramProtocol):
    """Listens on 127.0.0.1:<port>; the GCS connects with ``udpout:127.0.0.1:<port>``."""

    def __init__(self, style: Style = PX4, *, system_id: int = 1, component_id: int = 1,
                 faults: Faults | None = None, signing_key: bytes | None = None,
                 telemetry_interval_s: float = 0.2, command_results: dict[int, int] | None = None,
                 reject_item: tuple[int, int] | None = None,
                 command_texts: dict[int, list[tuple[float, int, str]]] | None = None):
        self.style = style
        self.faults = faults or Faults()
        self.rng = random.Random(self.faults.seed)
        self.mav = M.MAVLink(None, system_id, component_id)
        self.mav.robust_parsing = True
        if signing_key is not None:
            self.mav.signing.secret_key = signing_key
            self.mav.signing.sign_outgoing = True
            self.mav.signing.timestamp = int((time.time() - 1420070400) * 1e5)
        self.state = VehicleState()
        self.telemetry_interval_s = telemetry_interval_s
        self.command_results = command_results or {}
        self.reject_item = reject_item  # (seq, MAV_MISSION_RESULT) to refuse during upload
        # command -> STATUSTEXTs (delay after the ACK in s, severity, text) sent after each ACK of it
        self.command_texts = command_texts or {}
        self._text_id = 0
        self.silent = False  # simulate a link drop: neither send nor receive
        self.received: list = []  # every accepted message, for assertions
        self.gcs_addr = None
        self.port = 0
        self._udp = None
        self._held: bytes | None = None
        self._tasks: list[asyncio.Task] = []
        self._rx_expected = 0
        self._rx_count = 0
        self._rx_items: list[WireItem] = []
        self._receiving = False
        self._rx_task: asyncio.Task | None = None
        self._uploader = (255, 190)
        self._sending = False
        self._tx_expected = 0

    # -- lifecycle ------------------------------------------------------------------------

    async def start(self) -> "ScriptedVehicle":
        loop = asyncio.get_running_loop()
        self._udp, _ = await loop.create_datagram_endpoint(lambda: self, local_addr=("127.0.0.1", 0))
        self.port = self._udp.get_extra_info("sockname")[1]
        self._tasks.append(asyncio.create_task(self._telemetry()))
        return self

    @property
    def connection(self) -> str:
        return f"udpout:127.0.0.1:{self.port}"

    async def stop(self) -> None:
        for t in self._tasks + ([self._rx_task] if self._rx_task else []):
            t.cancel()
        await asyncio.gather(*self._tasks, return_exceptions=True)
        if self._udp is not None:
            self._udp.close()

    async def __aenter__(self):
        return await self.start()

    async def __aexit__(self, *exc):
        await self.stop()

    # -- faulty wire ----------------------------------------------------------------------

    def send(self, msg) -> None:
        buf = msg.pack(self.mav)
        self.mav.seq = (self.mav.seq + 1) % 256
        if self.gcs_addr is None or self.silent or self.rng.random() < self.faults.loss:
            return
        copies = 2 if self.rng.random() < self.faults.duplicate else 1
        if self._held is None and self.rng.random() < self.faults.reorder:
            self._held = buf
            return
        for _ in range(copies):
            self._udp.sendto(buf, self.gcs_addr)
        if self._held is not None:
            self._udp.sendto(self._held, self.gcs_addr)
            self._held = None

    def datagram_received(self, data: bytes, addr) -> None:
        if self.silent or self.rng.random() < self.faults.loss:
            return
        self.gcs_addr = addr
        for msg in self.mav.parse_buffer(data) or ():
            if isinstance(msg, M.MAVLink_bad_data):
                continue
            self.received.append(msg)
            handler = getattr(self, "_on_" + msg.get_type().lower(), None)
            if handler is not None:
                handler(msg)

    # -- telemetry ------------------------------------------------------------------------

    async def _telemetry(self) -> None:
        while True:
            s = self.state
            base = M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (M.MAV_MODE_FLAG_SAFETY_ARMED if s.armed else 0)
            self.send(self.mav.heartbeat_encode(M.MAV_TYPE_QUADROTOR, self.style.autopilot, base, s.custom_mode,
                                                M.MAV_STATE_ACTIVE))
            self.send(self.mav.global_position_int_encode(1000, HOME[0], HOME[1], 50_000, 12_000, 0, 0, 0, 9000))
            self.send(self.mav.sys_status_encode(0, 0, 0, 0, 15800, 100, 87, 0, 0, 0, 0, 0, 0))
            self.send(self.mav.mission_current_encode(s.current_seq, len(s.mission), 2, 0))
            await asyncio.sleep(self.telemetry_interval_s)

    # -- mission upload (vehicle side) -----------------------------------------------------

    def _ack(self, msg, result: int) -> None:
        self.send(self.mav.mission_ack_encode(msg.get_srcSystem(), msg.get_srcComponent(), result, 0))

    def _request(self, seq: int) -> None:
        ts, tc = self._uploader
        if self.style.request_type == "MISSION_REQUEST":
            self.send(self.mav.mission_request_encode(ts, tc, seq, 0))
        else:
            self.send(self.mav.mission_request_int_encode(ts, tc, seq, 0))

    def _on_mission_count(self, msg) -> None:
        if self._receiving and self.style is PX4 and self._rx_expected > 0:
            self._ack(msg, M.MAV_MISSION_ERROR)  # "WPM: REJ. CMD: Busy"; the transfer goes on
            return
        if msg.count == 0:
            self.state.mission = []
            self._ack(msg, M.MAV_MISSION_ACCEPTED)
            return
        self._receiving = True
        self._uploader = (msg.get_srcSystem(), msg.get_srcComponent())
        self._rx_count, self._rx_expected, self._rx_items = msg.count, 0, []
        if self.style is ARDUPILOT:
            self.state.mission = self.state.mission[:msg.count]  # AP truncates at once: not atomic
        self._request(0)
        if self._rx_task:
            self._rx_task.cancel()
        self._rx_task = asyncio.create_task(self._rerequest_loop(msg))

    async def _rerequest_loop(self, count_msg) -> None:
        idle_s = 0.0
        last = -1
        while self._receiving:
            await asyncio.sleep(self.style.rerequest_s)
            if not self._receiving:
                return
            idle_s = idle_s + self.style.rerequest_s if self._rx_expected == last else 0.0
            last = self._rx_expected
            if idle_s >= self.style.give_up_s:
                self._receiving = False
                self._ack(count_msg, M.MAV_MISSION_OPERATION_CANCELLED)
                return
            self._request(self._rx_expected)

    def _on_mission_item_int(self, msg) -> None:
        if not self._receiving:
            if self.style is PX4 and msg.seq == self._rx_count - 1 and self.state.uploads_completed:
                self._ack(msg, M.MAV_MISSION_ACCEPTED)  # lost-final-ACK case
            return
        if msg.seq != self._rx_expected:
            if self.style is ARDUPILOT:
                self._ack(msg, M.MAV_MISSION_INVALID_SEQUENCE)
            return
        if self.reject_item and msg.seq == self.reject_item[0]:
            self._receiving = False
            self._ack(msg, self.reject_item[1])
            return
        self._rx_items.append(WireItem(msg.seq, msg.frame, msg.command, msg.current, msg.autocontinue, msg.param1,
                                       msg.param2, msg.param3, msg.param4, msg.x, msg.y, msg.z, msg.mission_type))
        self._rx_expected += 1
        if self._rx_expected == self._rx_count:
            self._receiving = False
            self.state.mission = self._rx_items
            self.state.uploads_completed += 1
            self._ack(msg, M.MAV_MISSION_ACCEPTED)
        else:
            self._request(self._rx_expected)

    # -- mission download / clear ---------------------------------------------------------

    def _on_mission_request_list(self, msg) -> None:
        self._tx_expected = 0
        self._sending = True
        self.send(self.mav.mission_count_encode(msg.get_srcSystem(), msg.get_srcComponent(), len(self.state.mission),
                                                0))

    def _on_mission_request_int(self, msg) -> None:
        if not 0 <= msg.seq < len(self.state.mission):
            self._ack(msg, M.MAV_MISSION_INVALID_SEQUENCE)
            return
        if self.style is PX4:  # only the expected item or a repeat of the previous one, else abort
            if not self._sending or msg.seq not in (self._tx_expected, self._tx_expected - 1):
                self._sending = False
                self._ack(msg, M.MAV_MISSION_ERROR)
                return
            self._tx_expected = max(self._tx_expected, msg.seq + 1)
        w = self.state.mission[msg.seq]
        x, y, z, frame = w.x, w.y, w.z, w.frame
        if self.style.home_at_seq0 and msg.seq == 0:
            (x, y, z), frame = HOME, 0
        self.send(self.mav.mission_item_int_encode(msg.get_srcSystem(), msg.get_srcComponent(), w.seq, frame,
                                                   w.command, w.current, w.autocontinue, w.param1, w.param2,
                                                   w.param3, w.param4, x, y, z, w.mission_type))

    _on_mission_request = _on_mission_request_int

    def _on_mission_clear_all(self, msg) -> None:
        self.state.mission = []
        self._ack(msg, M.MAV_MISSION_ACCEPTED)

    # -- commands -------------------------------------------------------------------------

    def _on_command_long(self, msg) -> None:
        result = self.command_results.get(msg.command, M.MAV_RESULT_ACCEPTED)
        if result == M.MAV_RESULT_ACCEPTED:
            if msg.command == M.MAV_CMD_DO_SET_MODE:
                self.state.custom_mode = int(msg.param2) if self.style is ARDUPILOT else (
                    int(msg.param2) << 16 | int(msg.param3) << 24)
            elif msg.command == M.MAV_CMD_COMPONENT_ARM_DISARM:
                self.state.armed = msg.param1 == 1
            elif msg.command == M.MAV_CMD_DO_SET_MISSION_CURRENT:
                self.state.current_seq = int(msg.param1)
        self.send(self.mav.command_ack_encode(msg.command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()))
        loop = asyncio.get_running_loop()
        for delay_s, severity, text in self.command_texts.get(msg.command, []):
            loop.call_later(delay_s, self.say, severity, text)

    def say(self, severity: int, text: str) -> None:
        """A STATUSTEXT, in 50-byte chunks sharing an id when longer (as PX4 and ArduPilot do)."""
        raw = text.encode()
        if len(raw) <= 50:
            self.send(self.mav.statustext_encode(severity, raw))
            return
        self._text_id = self._text_id % 65535 + 1
        for n, i in enumerate(range(0, len(raw), 50)):
            self.send(self.mav.statustext_encode(severity, raw[i:i + 50], self._text_id, n))

    def _on_mission_set_current(self, msg) -> None:
        self.state.current_seq = msg.seq
        self.send(self.mav.mission_current_encode(msg.seq, len(self.state.mission), 2, 0))
