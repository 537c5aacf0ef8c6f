"""The fleet over real UDP on loopback, with pymavlink as a plain ground station."""

from __future__ import annotations

import asyncio
import time

import numpy as np
import pytest

from uavloc_gcs.dialect import mavlink as mav
from uavloc_gcs.dialect.rssi import decode_rssi_batch
from uavloc_gcs.mission import flight_mission, to_wire
from uavloc_gcs.scenario import load_scenario
from sim_link.vehicles.fleet import FakeFleet

from .mavclient import MavClient

SMALL = load_scenario("examples/small.toml")


def run(coro):
    return asyncio.run(asyncio.wait_for(coro, 30))


def test_fixed_ports_ids_and_streams():
    async def main():
        sc = SMALL.replace(fleet={"vehicles": 3})
        async with FakeFleet(sc, speedup=20, seed=1, base_port=24100, epoch_unix_s=1.8e9) as fleet:
            assert [e for e, _ in fleet.endpoints] == ["uav1", "uav2", "uav3"]
            assert [c for _, c in fleet.endpoints] == [f"udpout:127.0.0.1:{24100 + i}" for i in (1, 2, 3)]
            c = await MavClient.connect(fleet.endpoints[1][1])
            hb = await c.recv("HEARTBEAT", where=lambda m: m.get_srcComponent() == 1)
            assert (hb.get_srcSystem(), hb.type, hb.autopilot) == (2, mav.MAV_TYPE_QUADROTOR, mav.MAV_AUTOPILOT_PX4)
            st = await c.recv("SYSTEM_TIME")
            # SYSTEM_TIME is the simulated UNIX time: epoch + mission time
            assert st.time_unix_usec / 1e6 - 1.8e9 == pytest.approx(fleet.now_s(), abs=0.5)
            await asyncio.sleep(1.0)
            counts = {}
            for m in c.log:
                counts[m.get_type()] = counts.get(m.get_type(), 0) + 1
            sim_s = 1.0 * fleet.speedup
            assert counts["GLOBAL_POSITION_INT"] == pytest.approx(5 * sim_s, rel=0.3)
            assert counts["SYS_STATUS"] == pytest.approx(sim_s, rel=0.3)
            assert all(m.get_srcSystem() == 2 for m in c.log)
            c.close()
    run(main())


def _items(sc, autopilot):
    pts = sc.frame.to_wgs84_latlon(np.array([[50.0, 50.0], [200.0, 50.0], [200.0, 150.0], [50.0, 150.0]]))
    plan = flight_mission(pts, alt_m=40, speed_m_s=15, autopilot=autopilot, home_latlon_deg=sc.launch_latlon_deg)
    return to_wire(plan)


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_pymavlink_client_uploads_and_flies_a_mission(autopilot):
    async def main():
        sc = SMALL.replace(fleet={"vehicles": 1, "autopilot": autopilot})
        async with FakeFleet(sc, speedup=50, seed=3, base_port=0) as fleet:
            c = await MavClient.connect(fleet.endpoints[0][1])
            await c.recv("HEARTBEAT")
            items = _items(sc, autopilot)
            req = "MISSION_REQUEST" if autopilot == "ardupilot" else "MISSION_REQUEST_INT"
            ack = await c.upload(1, items)
            assert ack.type == mav.MAV_MISSION_ACCEPTED
            assert {m.get_type() for m in c.log if m.get_type().startswith("MISSION_REQUEST")} == {req}
            assert (await c.command(1, mav.MAV_CMD_COMPONENT_ARM_DISARM, 1)).result == mav.MAV_RESULT_ACCEPTED
            start = await c.command(1, mav.MAV_CMD_MISSION_START)
            while autopilot == "px4" and start.result == mav.MAV_RESULT_DENIED:
                # PX4 checks a new mission for a moment and denies a start meanwhile ("Mission
                # start denied! No valid mission"; flavour.mission_valid_after_upload_s): retry
                await asyncio.sleep(0.02)
                start = await c.command(1, mav.MAV_CMD_MISSION_START)
            assert start.result == mav.MAV_RESULT_ACCEPTED
            reached = []
            while True:
                m = await c.recv(("MISSION_ITEM_REACHED", "MISSION_CURRENT"), timeout=10)
                if m.get_type() == "MISSION_ITEM_REACHED":
                    reached.append(m.seq)
                elif m.mission_state == mav.MISSION_STATE_COMPLETE:
                    break
            first = 1 if autopilot == "ardupilot" else 0
            assert reached == [w.seq for w in items if w.command in (16, 20, 22) and w.seq >= first]
            v = fleet.vehicle(1)
            if autopilot == "px4":  # PX4 ends the mission at its RTL item and returns in AUTO.RTL
                assert v.mode == "RTL" and not v.landed
            # (PX4 disarms 2.5 s after it landed; on a busy machine the fleet's clock runs behind the
            # wall: wait for the disarm in simulated time, however long that takes in wall time)
            for _ in range(600):
                if v.landed and not v.armed:
                    break
                await asyncio.sleep(0.05)
            if autopilot == "px4":
                assert v.mode == "RTL"
            assert v.landed and not v.armed
            rssi_sources = {(m.get_srcSystem(), m.get_srcComponent()) for m in c.log
                            if m.get_type() == "UAVLOC_RSSI_BATCH"}
            assert rssi_sources <= {(1, 191)}
            c.close()
    run(main())


def test_signing_drops_and_counts_unsigned_and_wrongly_signed():
    key = bytes(range(32))

    async def main():
        async with FakeFleet(SMALL, speedup=20, seed=1, base_port=0, signing_key=key) as fleet:
            ep = fleet.endpoints[0][1]
            good = await MavClient.connect(ep, key=key)
            hb = await good.recv("HEARTBEAT")
            assert hb.get_signed()
            ack = await good.command(1, mav.MAV_CMD_COMPONENT_ARM_DISARM, 1)
            assert ack.result == mav.MAV_RESULT_ACCEPTED and ack.get_signed()
            plain = await MavClient.connect(ep, sysid=254)
            wrong = await MavClient.connect(ep, sysid=253, key=bytes(32))
            for c in (plain, wrong):
                c.send(mav.MAVLink_command_long_message(1, 1, mav.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, 0, 0, 0, 0, 0, 0))
            await asyncio.sleep(0.5)
            assert fleet.vehicle(1).armed  # neither disarm got through
            assert fleet.stats(1).rejected_signature >= 4  # 2 heartbeats + 2 commands
            assert plain.log == [] and wrong.log == []  # and they get no telemetry
            for c in (good, plain, wrong):
                c.close()
    run(main())


def test_start_in_thread_for_sync_callers_and_state():
    import socket

    fleet = FakeFleet(SMALL, speedup=20, seed=1, base_port=0).start_in_thread()
    try:
        host, port = fleet.endpoints[0][1].split(":")[1:]
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.settimeout(2.0)
        codec = mav.MAVLink(None, 255, 190)
        s.sendto(codec.heartbeat_encode(6, 8, 0, 0, 0).pack(codec), (host, int(port)))
        data, _ = s.recvfrom(4096)
        assert codec.parse_buffer(data)[0].get_srcSystem() == 1
        v = fleet.vehicle(1)
        assert v.mode == "LOITER" and not v.armed and v.mission_items == [] and v.energy_used_j == 0.0
        t0 = fleet.now_s()
        time.sleep(0.2)
        assert fleet.now_s() - t0 == pytest.approx(0.2 * 20, rel=0.3)
        s.close()
    finally:
        fleet.stop()


def test_rssi_decodes_to_the_vehicle_track():
    async def main():
        sc = load_scenario("examples/paper.toml").replace(fleet={"vehicles": 1})
        async with FakeFleet(sc, speedup=50, seed=2, base_port=0) as fleet:
            c = await MavClient.connect(fleet.endpoints[0][1])
            await c.recv("HEARTBEAT")
            await c.take_off()
            lat, lon = sc.frame.to_wgs84(500.0, 300.0)  # then over the area (GUIDED goto)
            c.send(mav.MAVLink_set_position_target_global_int_message(
                0, 1, 1, 6, 0b110111111000, int(lat * 1e7), int(lon * 1e7), 100.0, 0, 0, 0, 0, 0, 0, 0, 0))
            msgs = []
            while len(msgs) < 20:
                msgs.append(await c.recv("UAVLOC_RSSI_BATCH", timeout=10, where=lambda m: m.count > 0))
            slots = [decode_rssi_batch(m, sc.frame, epoch_unix_s=fleet.epoch_unix_s) for m in msgs]
            assert all(len(s) and s.vehicle[0] == 1 for s in slots)
            t = np.concatenate([s.t_s for s in slots])
            assert np.all(np.diff(t) >= 0) and t[-1] <= fleet.now_s()
            c.close()
    run(main())


def test_streams_to_a_configured_gcs_address_without_being_asked():
    import socket

    async def main():
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.bind(("127.0.0.1", 0))
        sock.settimeout(3.0)
        try:
            sc = SMALL.replace(fleet={"vehicles": 1})
            async with FakeFleet(sc, speedup=20, seed=1, base_port=0, gcs_address=sock.getsockname()):
                data = await asyncio.get_running_loop().run_in_executor(None, lambda: sock.recvfrom(4096)[0])
                assert mav.MAVLink(None).parse_buffer(data)[0].get_srcSystem() == 1
        finally:
            sock.close()
    run(main())
