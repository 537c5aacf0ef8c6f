"""The companion emulator, attached to a fake vehicle standing in for an autopilot (UDP) and to a
scripted autopilot on TCP (as ArduPilot SITL's tcp:127.0.0.1:5760)."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

from uavloc_gcs.dialect import mavlink as mav
from uavloc_gcs.dialect.rssi import decode_rssi_batches
from uavloc_gcs.errors import ConfigError
from uavloc_gcs.observations import SlotBatch
from uavloc_gcs.scenario import load_scenario
from sim_link.vehicles.companion import CompanionEmulator
from sim_link.vehicles.connection import parse_url
from sim_link.vehicles.fleet import FakeFleet
from sim_link.world import World

from .mavclient import MavClient

SC = load_scenario("examples/paper.toml").replace(fleet={"vehicles": 1})


def test_companion_on_a_fake_autopilot_reaches_the_ground_station():
    world = World.with_people(SC, [[0.0, 60.0], [30.0, -40.0], [900.0, 500.0]], seed=3)

    async def main():
        async with FakeFleet(SC, speedup=20, seed=1, base_port=0, world=world, onboard_rssi=False,
                             route=True) as fleet:
            url = fleet.endpoints[0][1]
            comp = CompanionEmulator(SC, url, world=world, epoch_unix_s=fleet.epoch_unix_s)
            stop = asyncio.Event()
            task = asyncio.create_task(comp.run(stop))
            gcs = await MavClient.connect(url)
            await gcs.recv("HEARTBEAT")
            await gcs.take_off()
            await asyncio.sleep(1.2)  # 24 s of mission time: the climb to 100 m
            stop.set()
            await task
            msgs = [m for m in gcs.log if m.get_type() == "UAVLOC_RSSI_BATCH2"]
            assert msgs and {(m.get_srcSystem(), m.get_srcComponent()) for m in msgs} == {(1, 191)}
            assert comp.sysid == 1 and comp.stats.messages >= len(msgs) > 20
            slots = decode_rssi_batches(msgs, SC.frame, epoch_unix_s=fleet.epoch_unix_s)
            # the vehicle climbed straight up over the launch point
            assert np.abs(slots.xyz_m[:, :2]).max() < 1.0
            assert slots.xyz_m[:, 2].min() >= 0.5 and slots.xyz_m[:, 2].max() <= 100.5
            assert set(slots.emitter_id.tolist()) == set(world.emitter_ids[:2].tolist())  # not the far one
            # the paper's world gives no sensor columns: address = emitter id, the rest unknown
            assert np.array_equal(slots.address, slots.emitter_id)
            assert not slots.fingerprint.any() and not slots.channel.any()
            assert slots.t_s.max() <= fleet.now_s()
            # consistent with the channel model at the true distances
            xy = world.positions(slots.t_s)[np.arange(len(slots)), [world.index_of(e) for e in slots.emitter_id]]
            d = np.sqrt(np.sum((xy - slots.xyz_m[:, :2]) ** 2, axis=1) + slots.xyz_m[:, 2] ** 2)
            resid = slots.rssi_dbm - world.channel.median_rssi_dbm(d)
            se = SC.channel.shadowing_sigma_db / np.sqrt(SC.channel.samples_per_slot)
            assert abs(resid.mean()) < 5 * se / np.sqrt(len(resid)) + 0.05
            assert resid.std() == pytest.approx(se, rel=0.15)
            gcs.close()
    asyncio.run(asyncio.wait_for(main(), 30))


def test_companion_over_tcp_uses_the_autopilot_clock_and_track():
    world = World.with_people(SC, [[200.0, 80.0]], seed=2)
    epoch_us = 1_800_000_000_000_000
    received: list = []

    async def autopilot(reader, writer):
        ap = mav.MAVLink(None, srcSystem=7, srcComponent=1)
        rx = mav.MAVLink(None)
        rx.robust_parsing = True

        async def read():
            while data := await reader.read(4096):
                received.extend(m for m in rx.parse_buffer(data) or [] if m.get_type() != "BAD_DATA")

        reader_task = asyncio.create_task(read())
        writer.write(ap.heartbeat_encode(mav.MAV_TYPE_QUADROTOR, mav.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 4).pack(ap))
        writer.write(ap.system_time_encode(epoch_us + 10_000_000, 5000).pack(ap))  # unix = epoch + 10 s at boot 5 s
        for k in range(60):  # 12 s along y = 80 m at 20 m/s, 100 m up, reported at 5 Hz
            boot_ms = 5000 + 200 * k
            e = 20.0 * k * 0.2
            lat, lon = SC.frame.to_wgs84(e, 80.0)
            writer.write(ap.global_position_int_encode(boot_ms, int(round(lat * 1e7)), int(round(lon * 1e7)),
                                                       100000, 100000, 0, 2000, 0, 9000).pack(ap))
            await writer.drain()
            await asyncio.sleep(0.002)
        await asyncio.sleep(0.2)
        writer.close()
        reader_task.cancel()

    async def main():
        server = await asyncio.start_server(autopilot, "127.0.0.1", 0)
        port = server.sockets[0].getsockname()[1]
        comp = CompanionEmulator(SC, f"tcp:127.0.0.1:{port}", world=world, epoch_unix_s=epoch_us / 1e6)
        await asyncio.wait_for(comp.run(), 10)  # ends when the autopilot closes the link
        server.close()
        return comp

    comp = asyncio.run(main())
    msgs = [m for m in received if m.get_type() == "UAVLOC_RSSI_BATCH2"]
    assert {(m.get_srcSystem(), m.get_srcComponent()) for m in received} == {(7, 191)}
    assert any(m.get_type() == "HEARTBEAT" and m.type == mav.MAV_TYPE_ONBOARD_CONTROLLER for m in received)
    slots = decode_rssi_batches(msgs, SC.frame, epoch_unix_s=epoch_us / 1e6)
    assert len(slots) > 100 and comp.stats.positions == 60
    # mission time = SYSTEM_TIME mapping: t = 10 s + (boot - 5 s); track e = 20 m/s * (t - 10 s)
    assert slots.t_s.min() >= 10.0 - 1e-6 and slots.t_s.max() <= 10.0 + 11.8 + 1e-6
    np.testing.assert_allclose(slots.xyz_m[:, 0], 20.0 * (slots.t_s - 10.0), atol=0.05)
    np.testing.assert_allclose(slots.xyz_m[:, 1:], np.tile([80.0, 100.0], (len(slots), 1)), atol=0.05)
    np.testing.assert_allclose(np.diff(np.unique(slots.t_s)), SC.channel.slot_s, atol=1e-3)


class _SensorWorld:
    """The world as a Wi-Fi sensor hears it: every heard slot under a 48-bit address (high and
    locally administered bits set) changing every 2 s, a 32-bit fingerprint per person, a channel."""

    def __init__(self, world):
        self.world = world
        self.sent: list[SlotBatch] = []

    def hear_track(self, vehicle, t_s, xyz_m) -> SlotBatch:
        b = self.world.hear_track(vehicle, t_s, xyz_m)
        person = np.array([self.world.index_of(e) for e in b.emitter_id], dtype=np.int64)
        address = 0xDA0000000000 + (person << 20) + np.floor(b.t_s / 2.0).astype(np.int64)
        out = SlotBatch.from_columns(b.t_s, b.vehicle, b.xyz_m, address, b.rssi_dbm, b.n_samples, address=address,
                                     fingerprint=0xFEDC0000 + person, channel=np.array([1, 6, 11])[person % 3])
        self.sent.append(out)
        return out


def test_companion_sends_the_address_fingerprint_and_channel_the_world_gives():
    world = World.with_people(SC, [[200.0, 80.0], [260.0, 60.0]], seed=2)
    sensor = _SensorWorld(world)
    epoch_us = 1_800_000_000_000_000
    received: list = []

    async def autopilot(reader, writer):
        ap = mav.MAVLink(None, srcSystem=7, srcComponent=1)
        rx = mav.MAVLink(None)
        rx.robust_parsing = True

        async def read():
            while data := await reader.read(4096):
                received.extend(m for m in rx.parse_buffer(data) or [] if m.get_type() != "BAD_DATA")

        reader_task = asyncio.create_task(read())
        writer.write(ap.heartbeat_encode(mav.MAV_TYPE_QUADROTOR, mav.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 4).pack(ap))
        writer.write(ap.system_time_encode(epoch_us, 0).pack(ap))
        for k in range(40):  # 8 s along y = 80 m at 20 m/s, 100 m up, at 5 Hz
            lat, lon = SC.frame.to_wgs84(20.0 * k * 0.2 + 100.0, 80.0)
            writer.write(ap.global_position_int_encode(200 * k, int(round(lat * 1e7)), int(round(lon * 1e7)),
                                                       100000, 100000, 0, 2000, 0, 9000).pack(ap))
            await writer.drain()
            await asyncio.sleep(0.002)
        await asyncio.sleep(0.2)
        writer.close()
        reader_task.cancel()

    async def main():
        server = await asyncio.start_server(autopilot, "127.0.0.1", 0)
        port = server.sockets[0].getsockname()[1]
        comp = CompanionEmulator(SC, f"tcp:127.0.0.1:{port}", world=sensor, epoch_unix_s=epoch_us / 1e6)
        await asyncio.wait_for(comp.run(), 10)
        server.close()

    asyncio.run(main())
    msgs = [m for m in received if m.get_type() == "UAVLOC_RSSI_BATCH2"]
    assert msgs and not [m for m in received if m.get_type() == "UAVLOC_RSSI_BATCH"]
    got = decode_rssi_batches(msgs, SC.frame, epoch_unix_s=epoch_us / 1e6).sorted_by_time()
    sent = SlotBatch.concat(sensor.sent).sorted_by_time()
    assert len(sent) - 12 < len(got) <= len(sent) and len(got) > 100  # the last batch may be unsent at the end
    sent = sent.take(np.arange(len(got)))
    for col in ("address", "fingerprint", "channel", "n_samples"):
        np.testing.assert_array_equal(getattr(got, col), getattr(sent, col), err_msg=col)
    assert np.array_equal(got.emitter_id, got.address) and (got.address >> 40).min() == 0xDA
    assert len(np.unique(got.address)) >= 6  # the addresses changed along the pass
    np.testing.assert_allclose(got.rssi_dbm, sent.rssi_dbm, atol=0.005)


def test_connection_strings():
    assert parse_url("tcp:127.0.0.1:5760") == ("tcp", "127.0.0.1", 5760)
    assert parse_url("udp:localhost:14550") == ("udpout", "localhost", 14550)
    with pytest.raises(ConfigError, match="tcp:HOST:PORT"):
        parse_url("serial:/dev/ttyUSB0")


def test_cli_companion_against_a_fake_autopilot():
    import signal
    import subprocess
    import sys
    import time

    port_base = 24400
    sc = load_scenario("examples/paper.toml").replace(fleet={"vehicles": 1})
    # what `uavloc sim --no-rssi` runs: fake autopilots that route, without onboard RSSI
    fleet = FakeFleet(sc, speedup=20, seed=1, base_port=port_base, onboard_rssi=False, route=True).start_in_thread()
    proc = subprocess.Popen([sys.executable, "-m", "uavloc_gcs", "sim", "--companion", "--autopilot",
                             f"udpout:127.0.0.1:{port_base + 1}", "examples/paper.toml", "--seed", "1"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert "companion emulator on udpout:127.0.0.1:24401" in proc.stdout.readline()

        async def main():
            c = await MavClient.connect(f"udpout:127.0.0.1:{port_base + 1}")
            await c.recv("HEARTBEAT")
            await c.take_off()
            lat, lon = sc.frame.to_wgs84(560.0, 320.0)  # the middle of the area: people around
            c.send(mav.MAVLink_set_position_target_global_int_message(
                0, 1, 1, 6, 0b110111111000, int(lat * 1e7), int(lon * 1e7), 100.0, 0, 0, 0, 0, 0, 0, 0, 0))
            m = await c.recv("UAVLOC_RSSI_BATCH2", timeout=15, where=lambda m: m.count > 0)  # not a keepalive
            c.close()
            return m

        m = asyncio.run(main())
        assert (m.get_srcSystem(), m.get_srcComponent()) == (1, 191) and m.count >= 1
        assert abs(m.time_usec / 1e6 - (fleet.epoch_unix_s + fleet.now_s())) < 5.0
        t0 = time.time()
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()  # never leave it holding the ports for the rest of the suite
            proc.communicate()
            raise
        finally:
            fleet.stop()
    assert proc.returncode == 0 and time.time() - t0 < 10


def test_companion_sends_rssi_beside_the_autopilot_when_given_its_own_connection():
    """The path PX4 allows (it drops unknown message ids): RSSI on a connection of its own, as a
    router on the companion would carry it; nothing of it goes through the autopilot."""
    world = World.with_people(SC, [[0.0, 60.0], [30.0, -40.0]], seed=3)

    class _Sink(asyncio.DatagramProtocol):
        def __init__(self):
            self.rx, self.msgs = mav.MAVLink(None), []
            self.rx.robust_parsing = True

        def datagram_received(self, data, addr):
            self.msgs += [m for m in self.rx.parse_buffer(data) or [] if m.get_type() != "BAD_DATA"]

    async def main():
        loop = asyncio.get_running_loop()
        transport, sink = await loop.create_datagram_endpoint(_Sink, local_addr=("127.0.0.1", 0))
        port = transport.get_extra_info("sockname")[1]
        async with FakeFleet(SC, speedup=20, seed=1, base_port=0, world=world, onboard_rssi=False,
                             route=True) as fleet:
            url = fleet.endpoints[0][1]
            comp = CompanionEmulator(SC, url, world=world, epoch_unix_s=fleet.epoch_unix_s,
                                     rssi_url=f"udpout:127.0.0.1:{port}")
            stop = asyncio.Event()
            task = asyncio.create_task(comp.run(stop))
            gcs = await MavClient.connect(url)
            await gcs.recv("HEARTBEAT")
            await gcs.take_off()
            await asyncio.sleep(1.2)
            stop.set()
            await task
            gcs.close()
        transport.close()
        beside = [m for m in sink.msgs if m.get_type() == "UAVLOC_RSSI_BATCH2"]
        through = [m for m in gcs.log if m.get_type() == "UAVLOC_RSSI_BATCH2"]
        assert len(beside) > 20 and not through
        assert {(m.get_srcSystem(), m.get_srcComponent()) for m in beside} == {(1, 191)}
        assert any(m.get_type() == "HEARTBEAT" for m in sink.msgs)
        slots = decode_rssi_batches(beside, SC.frame, epoch_unix_s=fleet.epoch_unix_s)
        assert set(slots.emitter_id.tolist()) == set(world.emitter_ids.tolist())
    asyncio.run(asyncio.wait_for(main(), 30))
