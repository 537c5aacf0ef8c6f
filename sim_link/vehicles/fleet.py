"""Several fake vehicles in one process, each on its own UDP port, speaking MAVLink 2.

Vehicle i (1-based) is MAVLink system i, autopilot component 1 (its RSSI comes from component 191,
as a companion computer routed through the autopilot would send it). It binds
``host:(base_port + i)`` (``base_port=0``: an ephemeral port each) and talks to every address it
has heard from in the last ``peer_timeout_s`` seconds, plus ``gcs_address`` if given. A ground
station connects like to ArduPilot SITL: ``udpout:127.0.0.1:14561`` and sends a HEARTBEAT first.

Usage::

    async with FakeFleet(load_scenario("examples/paper.toml"), speedup=20, seed=1) as fleet:
        print(fleet.endpoints)          # [("uav1", "udpout:127.0.0.1:14561"), ...]

    fleet = FakeFleet(scenario); fleet.start_in_thread(); ...; fleet.stop()   # from sync code
"""

from __future__ import annotations

import asyncio
import logging
import threading
import time
from dataclasses import dataclass, field

import numpy as np

from pymavlink.dialects.v20 import common as _common

from uavloc_gcs.dialect import mavlink as mav
from uavloc_gcs.dialect.signing import verify_signature_first
from uavloc_gcs.errors import LinkError
from uavloc_gcs.scenario import Scenario

from .clock import SimClock
from .faults import FaultConfig, FaultyPipe, LinkFaults
from .flavour import FLAVOURS
from .mission_server import Peer, Reply
from .vehicle import FakeVehicle, VehicleConfig

log = logging.getLogger(__name__)
COMMON_MESSAGE_IDS = frozenset(_common.mavlink_map)  # what a PX4 built on common.xml knows

TICK_WALL_S = 0.01
# At most this much real time's worth of simulation per step of the fleet. On a busy machine a step
# can take seconds of wall time; the next one then had to simulate a minute of flight at 20x, and
# every vehicle fell silent for seconds at a time (the ground marked all four lost within 3 s, issue
# 42). Instead the clock falls back (SimClock.slip): the mission runs slower than asked, the
# telemetry keeps coming, and the fleet says so (SLIP_REPORT_S).
MAX_STEP_WALL_S = 0.1
SLIP_REPORT_S = 30.0  # wall seconds between two warnings that the fleet runs behind its speed-up
PEER_TIMEOUT_S = 30.0
REBOOT_SILENCE_S = 2.0  # simulated seconds a rebooting vehicle is silent
TEAM_SWAP_BELOW = 0.5  # the team swaps a pack at most this charged (the daemon's SWAP_BELOW_PCT)


class BindError(LinkError, OSError):
    """A vehicle's UDP port could not be bound: a LinkError, and an OSError for callers catching those."""

    __str__ = BaseException.__str__  # the sentence, not OSError's "[Errno 98] ..."


@dataclass
class LinkStats:
    rx_packets: int = 0
    rx_bytes: int = 0
    tx_packets: int = 0
    tx_bytes: int = 0
    rejected_signature: int = 0  # unsigned or wrongly signed datagrams dropped (signing on)
    bad_packets: int = 0
    tx_bytes_by_type: dict = field(default_factory=dict)


class _PeerCodecs:
    """One MAVLink codec per peer for parsing, and one per (peer, our component) for sending."""

    def __init__(self, sysid: int, key: bytes | None, link_id: int):
        self.rx = mav.MAVLink(None)
        self.rx.robust_parsing = True  # bad CRC / bad signature -> BAD_DATA, not an exception
        self.tx = {c: mav.MAVLink(None, srcSystem=sysid, srcComponent=c) for c in (1, 191)}
        self.last_heard_wall_s = -float("inf")  # set by the first valid message
        if key is not None:
            ts = int((time.time() - 1420070400) * 1e5)
            self.rx.signing.secret_key = key
            verify_signature_first(self.rx)
            self.rx.signing.timestamp = ts
            # as ArduPilot: only RADIO_STATUS may come unsigned (SiK radios cannot sign)
            self.rx.signing.allow_unsigned_callback = lambda _mav, msg_id: msg_id == mav.MAVLINK_MSG_ID_RADIO_STATUS
            for codec in self.tx.values():
                codec.signing.secret_key = key
                codec.signing.sign_outgoing = True
                codec.signing.link_id = link_id
                codec.signing.timestamp = ts


class _VehicleEndpoint(asyncio.DatagramProtocol):
    """The UDP socket of one vehicle, its peers, codecs and fault pipes."""

    def __init__(self, fleet: "FakeFleet", vehicle: FakeVehicle, faults: LinkFaults, rng: np.random.Generator):
        self.fleet = fleet
        self.vehicle = vehicle
        self.up = FaultyPipe(faults.to_vehicle, rng)
        self.down = FaultyPipe(faults.to_gcs, rng)
        self.peers: dict = {}
        self.stats = LinkStats()
        self.transport: asyncio.DatagramTransport | None = None
        self.offline_until_s = -1.0  # mission time until which the vehicle is rebooting

    def connection_made(self, transport) -> None:
        self.transport = transport

    @property
    def address(self) -> tuple[str, int]:
        if self.transport is None:  # not started: the fixed port is known, an ephemeral one is not
            if self.fleet.base_port == 0:
                raise RuntimeError("FakeFleet with base_port=0: endpoints are known only after start()")
            return self.fleet.host, self.fleet.base_port + self.vehicle.sysid
        return self.transport.get_extra_info("sockname")[:2]

    def _codecs(self, addr) -> _PeerCodecs:
        pc = self.peers.get(addr)
        if pc is None:
            pc = _PeerCodecs(self.vehicle.sysid, self.fleet.signing_key, len(self.peers) % 256)
            self.peers[addr] = pc
        return pc

    def datagram_received(self, data: bytes, addr) -> None:
        loop = self.fleet.loop
        for delay in self.up.deliveries(time.monotonic()):
            if delay <= 0:
                self._receive(data, addr)
            else:
                loop.call_later(delay, self._receive, data, addr)

    def _receive(self, data: bytes, addr) -> None:
        if self.fleet.clock.now_s() < self.offline_until_s:
            return
        self.stats.rx_packets += 1
        self.stats.rx_bytes += len(data)
        pc = self._codecs(addr)
        msgs = pc.rx.parse_buffer(data) or []
        wall = time.monotonic()
        replies: list[Reply] = []
        for msg in msgs:
            if msg.get_type() == "BAD_DATA":
                if "signature" in str(getattr(msg, "reason", "")):
                    self.stats.rejected_signature += 1
                else:
                    self.stats.bad_packets += 1
                continue
            pc.last_heard_wall_s = wall
            if self.fleet.route and getattr(msg, "target_system", 0) != self.vehicle.sysid and self._forwards(msg):
                self._forward(data, addr)
            peer = Peer(addr, msg.get_srcSystem(), msg.get_srcComponent())
            try:
                replies += self.vehicle.handle(msg, peer, wall)
            except Exception:  # a malformed message must not take the vehicle down
                self.stats.bad_packets += 1
                log.exception("uav%d: error handling %s", self.vehicle.sysid, msg.get_type())
        self.send(replies)

    def _forwards(self, msg) -> bool:
        v = self.vehicle
        return (not v.cfg.realistic_forwarding or v.flavour.forwards_unknown_ids
                or msg.get_msgId() in COMMON_MESSAGE_IDS)

    def _forward(self, data: bytes, from_addr) -> None:
        for addr in self._active_addresses():
            if addr != from_addr:
                self._sendto(data, addr)

    def _active_addresses(self) -> list:
        now = time.monotonic()
        out = [a for a, pc in self.peers.items() if now - pc.last_heard_wall_s <= self.fleet.peer_timeout_s]
        gcs = self.fleet.gcs_address
        if gcs is not None and gcs not in out:
            out.append(gcs)
        return out

    def send(self, replies: list[Reply]) -> None:
        if not replies or self.transport is None or self.fleet.clock.now_s() < self.offline_until_s:
            return
        everyone = self._active_addresses()
        for r in replies:
            for addr in ([r.to.address] if r.to is not None else everyone):
                pc = self._codecs(addr)
                codec = pc.tx[r.component]
                buf = r.msg.pack(codec)
                codec.seq = (codec.seq + 1) % 256
                name = r.msg.get_type()
                self.stats.tx_bytes_by_type[name] = self.stats.tx_bytes_by_type.get(name, 0) + len(buf)
                self._sendto(buf, addr)

    def _sendto(self, buf: bytes, addr) -> None:
        self.stats.tx_packets += 1
        self.stats.tx_bytes += len(buf)
        for delay in self.down.deliveries(time.monotonic()):
            if delay <= 0:
                self.transport.sendto(buf, addr)
            else:
                self.fleet.loop.call_later(delay, self._late_send, buf, addr)

    def _late_send(self, buf: bytes, addr) -> None:
        if self.transport is not None and not self.transport.is_closing():
            self.transport.sendto(buf, addr)


class FakeFleet:
    """``scenario.fleet.vehicles`` fake vehicles sharing one clock and one simulated world."""

    def __init__(
        self,
        scenario: Scenario,
        *,
        speedup: float | None = None,
        seed: int | None = None,
        base_port: int = 14560,
        host: str = "127.0.0.1",
        faults: FaultConfig | LinkFaults | None = None,
        signing_key: bytes | None = None,
        world=None,
        gcs_address: tuple[str, int] | None = None,
        epoch_unix_s: float | None = None,
        onboard_rssi: bool = True,
        companion_heartbeat: bool = False,
        route: bool = False,
        peer_timeout_s: float = PEER_TIMEOUT_S,
        vehicle_options: dict | None = None,
        team_swaps: bool = False,
    ):
        if signing_key is not None and len(signing_key) != 32:
            raise ValueError(f"signing_key must be 32 bytes, got {len(signing_key)}")
        self.scenario = scenario
        self.seed = int(scenario.simulation.seed if seed is None else seed)
        speedup = float(scenario.simulation.speedup if speedup is None else speedup)
        self.clock = SimClock(speedup, float(int(time.time())) if epoch_unix_s is None else float(epoch_unix_s))
        self.base_port, self.host = int(base_port), host
        self.signing_key = signing_key
        self.gcs_address = gcs_address
        self.route = route
        self.peer_timeout_s = peer_timeout_s
        if world is None:
            from ..world import World

            world = World(scenario, seed=self.seed)
        self.world = world
        self.faults = LinkFaults.of(faults)
        flavour = FLAVOURS[scenario.fleet.autopilot]
        f = scenario.fleet
        self.vehicles = [
            FakeVehicle(VehicleConfig(
                sysid=i, flavour=flavour, frame=scenario.frame, cruise_speed_m_s=f.speed_m_s,
                max_accel_m_s2=f.max_acceleration_m_s2, energy_budget_j=f.energy_budget_j,
                power=scenario.power_model, slot_s=scenario.channel.slot_s,
                epoch_unix_s=self.clock.epoch_unix_s, rssi=onboard_rssi,
                companion_heartbeat=companion_heartbeat,
                # over terrain the launch point's AMSL altitude is the DEM's, as absolute missions assume
                **{**({"home_alt_amsl_m": scenario.dem.height_at(0.0, 0.0)} if scenario.dem is not None else {}),
                   **(vehicle_options or {})}), world)
            for i in range(1, f.vehicles + 1)
        ]
        seeds = np.random.SeedSequence(self.seed, spawn_key=(7,)).spawn(len(self.vehicles))
        self._endpoints = [
            _VehicleEndpoint(self, v, self.faults, np.random.default_rng(s)) for v, s in zip(self.vehicles, seeds)
        ]
        for ep in self._endpoints:
            ep.vehicle.on_reboot_request = (lambda e=ep: self.loop.call_soon(self._reboot_now, e, None))
        # the team on the ground (issue 38): a vehicle landed and disarmed on a pack at most
        # TEAM_SWAP_BELOW charged gets a fresh one fleet.battery_swap_s later, while it has spares
        self.team_swaps = team_swaps
        self.spare_packs = [f.batteries - 1] * len(self.vehicles)
        self._down_since_s: list[float | None] = [None] * len(self.vehicles)
        self.loop: asyncio.AbstractEventLoop | None = None
        self._task: asyncio.Task | None = None
        self._thread: threading.Thread | None = None
        self._stop_event: asyncio.Event | None = None
        self.slipped_s = 0.0  # mission time the clock fell back because the simulation ran late

    # ---------------------------------------------------------------- public state
    @property
    def speedup(self) -> float:
        return self.clock.speedup

    @property
    def epoch_unix_s(self) -> float:
        return self.clock.epoch_unix_s

    @property
    def endpoints(self) -> list[tuple[str, str]]:
        """(vehicle id, connection string a ground station uses), e.g. ("uav1", "udpout:127.0.0.1:14561")."""
        return [(f"uav{ep.vehicle.sysid}", f"udpout:{ep.address[0]}:{ep.address[1]}") for ep in self._endpoints]

    def vehicle(self, i: int) -> FakeVehicle:
        """Vehicle ``i`` (1-based, = MAVLink system id)."""
        return self.vehicles[i - 1]

    def stats(self, i: int) -> LinkStats:
        return self._endpoints[i - 1].stats

    def link_counters(self, i: int):
        """(uplink, downlink) fault counters of vehicle ``i``."""
        ep = self._endpoints[i - 1]
        return ep.up.counters, ep.down.counters

    def now_s(self) -> float:
        return self.clock.now_s()

    # ---------------------------------------------------------------- faults
    def drop_link(self, i: int, seconds: float, *, wall_clock: bool = False) -> None:
        """Drop every datagram to and from vehicle ``i`` for ``seconds`` of mission time
        (of real time with ``wall_clock=True``). The vehicle keeps flying."""
        wall = seconds if wall_clock else self.clock.sim_to_wall_s(seconds)
        ep = self._endpoints[i - 1]
        until = time.monotonic() + wall
        ep.up.down_until_wall_s = ep.down.down_until_wall_s = until

    def set_faults(self, faults: FaultConfig | LinkFaults | None, i: int | None = None) -> None:
        """Change the link faults of vehicle ``i`` (all vehicles if None) from now on."""
        lf = LinkFaults.of(faults)
        for ep in self._endpoints if i is None else [self._endpoints[i - 1]]:
            ep.up.cfg, ep.down.cfg = lf.to_vehicle, lf.to_gcs

    def reboot(self, i: int, *, keep_mission: bool | None = None, silence_s: float = REBOOT_SILENCE_S) -> None:
        """Power-cycle vehicle ``i``: silent for ``silence_s`` of mission time, then on the ground,
        disarmed; the mission is kept on ArduPilot-like and lost on PX4-like vehicles unless
        ``keep_mission`` says otherwise."""
        ep = self._endpoints[i - 1]
        if self.loop is not None and self.loop.is_running():
            self.loop.call_soon_threadsafe(self._reboot_now, ep, keep_mission, silence_s)
        else:
            self._reboot_now(ep, keep_mission, silence_s)

    def swap_pack(self, i: int, *, reboot: bool = True, silence_s: float = REBOOT_SILENCE_S) -> None:
        """The team gives vehicle ``i`` a fresh pack (issue 38; it must be on the ground, disarmed).
        On a multirotor the pack powers the autopilot too, so the swap is a reboot (``reboot``):
        silent for ``silence_s``, then a fresh start whose ArduPilot monitor counts from 100 %.
        Without the reboot ArduPilot still reports the old pack's remaining until told otherwise
        (MAV_CMD_BATTERY_RESET), PX4 the new pack's (it reads the voltage)."""
        ep = self._endpoints[i - 1]
        if ep.vehicle.armed or not ep.vehicle.landed:
            raise RuntimeError(f"uav{i} is {'armed' if ep.vehicle.armed else 'in the air'}: a pack is swapped on the ground")

        def now() -> None:
            ep.vehicle.swap_pack()
            if reboot:
                self._reboot_now(ep, None, silence_s)
        if self.loop is not None and self.loop.is_running():
            self.loop.call_soon_threadsafe(now)
        else:
            now()

    def _reboot_now(self, ep: _VehicleEndpoint, keep_mission: bool | None,
                    silence_s: float = REBOOT_SILENCE_S) -> None:
        ep.vehicle.reboot(keep_mission)
        ep.offline_until_s = self.clock.now_s() + silence_s
        for pc in ep.peers.values():  # a rebooted autopilot starts new sequence numbers
            for codec in pc.tx.values():
                codec.seq = 0

    # ---------------------------------------------------------------- running
    async def start(self) -> "FakeFleet":
        self.loop = asyncio.get_running_loop()
        for ep in self._endpoints:
            port = 0 if self.base_port == 0 else self.base_port + ep.vehicle.sysid
            try:
                await self.loop.create_datagram_endpoint(lambda e=ep: e, local_addr=(self.host, port))
            except OSError as exc:
                await self.aclose()
                err = BindError(f"cannot bind UDP {self.host}:{port} ({exc.strerror or exc}); is another "
                                "simulator running? choose another --base-port",
                                vehicle=f"uav{ep.vehicle.sysid}", operation="bind")
                err.errno, err.strerror = exc.errno, exc.strerror
                raise err from None
        self.clock.start()
        self._stop_event = asyncio.Event()
        self._task = asyncio.create_task(self._run(), name="fake-fleet")
        log.info("fake fleet up: %s", self.endpoints)
        return self

    async def aclose(self) -> None:
        if self._task is not None:
            self._task.cancel()
            try:
                await self._task
            except asyncio.CancelledError:
                pass
            self._task = None
        for ep in self._endpoints:
            if ep.transport is not None:
                ep.transport.close()

    async def __aenter__(self) -> "FakeFleet":
        return await self.start()

    async def __aexit__(self, *exc) -> None:
        await self.aclose()

    async def _run(self) -> None:
        t_done = self.clock.now_s()
        report_wall, report_t, slipped = time.monotonic(), t_done, 0.0
        while True:
            wall = time.monotonic()
            asked = self.clock.now_s()
            t = min(asked, t_done + MAX_STEP_WALL_S * self.clock.speedup)
            if t < asked:
                self.clock.slip(asked - t)
                slipped += asked - t
            if slipped > 0 and wall - report_wall >= SLIP_REPORT_S:
                log.warning("the fake fleet is behind real time (a busy machine): its clock ran at %.1fx instead "
                            "of %gx over the last %.0f s", (t - report_t) / (wall - report_wall), self.clock.speedup,
                            wall - report_wall)
                report_wall, report_t, slipped = wall, t, 0.0
            elif slipped == 0 and wall - report_wall >= SLIP_REPORT_S:
                report_wall, report_t = wall, t
            self.slipped_s += max(asked - t, 0.0)
            t_done = t
            if self.team_swaps:
                self._team(t)
            for ep in self._endpoints:
                try:
                    out = ep.vehicle.advance(t) + ep.vehicle.tick_protocols(wall)
                except Exception:  # keep the other vehicles (and this one's link) alive; say why
                    log.exception("uav%d: simulation step failed", ep.vehicle.sysid)
                    out = []
                ep.send(out)
                await asyncio.sleep(0)  # let receivers on this loop drain their sockets between bursts
                stale = [a for a, pc in ep.peers.items() if wall - pc.last_heard_wall_s > 10 * self.peer_timeout_s]
                for a in stale:
                    del ep.peers[a]
            await asyncio.sleep(TICK_WALL_S)

    def _team(self, t_s: float) -> None:
        """The team's swaps (``team_swaps``), on the fleet's clock."""
        for k, ep in enumerate(self._endpoints):
            v = ep.vehicle
            used = v.landed and not v.armed and v.battery.charge <= TEAM_SWAP_BELOW and t_s >= ep.offline_until_s
            if not used or self.spare_packs[k] <= 0:
                self._down_since_s[k] = None
                continue
            if self._down_since_s[k] is None:
                self._down_since_s[k] = t_s
            elif t_s - self._down_since_s[k] >= self.scenario.fleet.battery_swap_s:
                self.spare_packs[k] -= 1
                self._down_since_s[k] = None
                v.swap_pack()
                self._reboot_now(ep, None)

    def start_in_thread(self, timeout_s: float = 5.0) -> "FakeFleet":
        """Run the fleet on its own event loop in a daemon thread (for synchronous callers)."""
        ready = threading.Event()
        errors: list[BaseException] = []

        async def main() -> None:
            try:
                await self.start()
            except BaseException as exc:  # reported to the caller below
                errors.append(exc)
                ready.set()
                return
            ready.set()
            await self._stop_event.wait()
            await self.aclose()

        self._thread = threading.Thread(target=lambda: asyncio.run(main()), name="fake-fleet", daemon=True)
        self._thread.start()
        if not ready.wait(timeout_s):
            raise RuntimeError("fake fleet did not start")
        if errors:
            raise errors[0]
        return self

    def stop(self, timeout_s: float = 5.0) -> None:
        """Stop a fleet started with :meth:`start_in_thread`."""
        if self._thread is None:
            return
        self.loop.call_soon_threadsafe(self._stop_event.set)
        self._thread.join(timeout_s)
        self._thread = None
