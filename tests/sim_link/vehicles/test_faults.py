"""Fault injection: lossy/duplicating/reordering pipes, link drops and reboots."""

from __future__ import annotations

import asyncio
import time

import numpy as np
import pytest

from uavloc_gcs.dialect import mavlink as mav
from uavloc_gcs.mission import flight_mission, to_wire
from uavloc_gcs.scenario import load_scenario
from sim_link.vehicles.faults import FaultConfig, FaultyPipe, LinkFaults
from sim_link.vehicles.fleet import FakeFleet

from .mavclient import MavClient

SMALL = load_scenario("examples/small.toml")


def test_pipe_rates_and_determinism():
    cfg = FaultConfig(loss=0.2, duplicate=0.1, reorder=0.1, latency_s=0.01, reorder_delay_s=0.05)
    runs = []
    for _ in range(2):
        pipe = FaultyPipe(cfg, np.random.default_rng(42))
        runs.append([pipe.deliveries(0.0) for _ in range(20000)])
    assert runs[0] == runs[1]
    copies = np.array([len(d) for d in runs[0]])
    n = len(copies)
    assert (copies == 0).mean() == pytest.approx(0.2, abs=0.015)
    assert (copies == 2).mean() == pytest.approx(0.8 * 0.1, abs=0.01)
    delays = np.concatenate([d for d in runs[0] if d])
    assert delays.min() == pytest.approx(0.01)
    assert (delays > 0.05).mean() == pytest.approx(0.1, abs=0.01)  # reordered: held back 50 ms more
    assert pipe.counters.sent == n and pipe.counters.lost == (copies == 0).sum()


def test_pipe_down_and_validation():
    pipe = FaultyPipe(FaultConfig(), np.random.default_rng(0))
    pipe.down_until_wall_s = 10.0
    assert pipe.deliveries(9.9) == [] and pipe.deliveries(10.0) == [0.0]
    assert pipe.counters.blocked == 1
    with pytest.raises(ValueError, match="loss"):
        FaultConfig(loss=1.5)
    assert LinkFaults.of(FaultConfig(loss=0.1)).to_gcs.loss == 0.1
    assert LinkFaults.of(None).to_vehicle.is_clean


def test_downlink_loss_thins_telemetry_and_uplink_loss_drops_commands():
    async def main():
        faults = LinkFaults(to_vehicle=FaultConfig(loss=1.0), to_gcs=FaultConfig(loss=0.5))
        sc = SMALL.replace(fleet={"vehicles": 1})
        async with FakeFleet(sc, speedup=20, seed=1, base_port=0, faults=faults) as fleet:
            c = await MavClient.connect(fleet.endpoints[0][1])
            await asyncio.sleep(0.5)
            assert c.log == []  # the vehicle never heard our heartbeat, so it does not talk to us
            fleet.set_faults(LinkFaults(to_gcs=FaultConfig(loss=0.5)), 1)  # uplink clean again
            c.send(c.codec.heartbeat_encode(6, 8, 0, 0, 0))
            await asyncio.sleep(1.0)
            gpi = [m for m in c.log if m.get_type() == "GLOBAL_POSITION_INT"]
            assert 0.3 * 100 < len(gpi) < 0.7 * 100  # 5 Hz x 20 sim s, half lost
            c.close()
    asyncio.run(asyncio.wait_for(main(), 20))


def test_drop_link_silences_both_ways_while_the_vehicle_flies_on():
    async def main():
        sc = SMALL.replace(fleet={"vehicles": 1, "autopilot": "ardupilot"})
        async with FakeFleet(sc, speedup=20, seed=1, base_port=0) as fleet:
            c = await MavClient.connect(fleet.endpoints[0][1])
            await c.recv("HEARTBEAT")
            assert (await c.command(1, mav.MAV_CMD_DO_SET_MODE, 1, 4)).result == 0
            assert (await c.command(1, mav.MAV_CMD_COMPONENT_ARM_DISARM, 1)).result == 0
            assert (await c.command(1, mav.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 40)).result == 0
            z0 = fleet.vehicle(1).position_xyz_m[2]
            fleet.drop_link(1, 10.0)  # 10 s of mission time = 0.5 s at 20x
            t_drop = time.monotonic()
            _, d0 = fleet.link_counters(1)
            sent0, blocked0 = d0.sent, d0.blocked
            c.drain()
            c.send(mav.MAVLink_command_long_message(1, 1, mav.MAV_CMD_NAV_LAND, 0, 0, 0, 0, 0, 0, 0, 0))
            await asyncio.sleep(0.35)
            _, d1 = fleet.link_counters(1)
            if time.monotonic() - t_drop < 0.45:  # still inside the drop (a loaded machine may oversleep)
                # nothing the vehicle sent since came through (counted at the fault, not at the client:
                # on a loaded machine datagrams sent before the drop reached the client's queue after
                # its drain, three STATUSTEXTs in one CI-like run)
                assert d1.sent - sent0 > 0 and d1.sent - sent0 == d1.blocked - blocked0
            assert fleet.vehicle(1).position_xyz_m[2] > z0 and fleet.vehicle(1).mode == "GUIDED"
            await c.recv("HEARTBEAT", timeout=2.0)  # and then it is back
            up, down = fleet.link_counters(1)
            assert up.blocked >= 1 and down.blocked > 10
            c.close()
    asyncio.run(asyncio.wait_for(main(), 20))


def _items(sc, ap):
    pts = sc.frame.to_wgs84_latlon(np.array([[50.0, 50.0], [150.0, 50.0]]))
    return to_wire(flight_mission(pts, alt_m=30, speed_m_s=10, autopilot=ap, home_latlon_deg=sc.launch_latlon_deg))


@pytest.mark.parametrize("autopilot,keep,expect_kept", [
    ("ardupilot", None, True), ("px4", None, False), ("px4", True, True), ("ardupilot", False, False),
])
def test_reboot_keeps_or_loses_the_mission(autopilot, keep, expect_kept):
    async def main():
        sc = SMALL.replace(fleet={"vehicles": 1, "autopilot": autopilot})
        async with FakeFleet(sc, speedup=20, seed=1, base_port=0) as fleet:
            v = fleet.vehicle(1)
            v.mission.stores[0] = _items(sc, autopilot)
            c = await MavClient.connect(fleet.endpoints[0][1])
            assert (await c.command(1, mav.MAV_CMD_COMPONENT_ARM_DISARM, 1)).result == 0
            await asyncio.sleep(0.3)
            c.drain()
            boot_before = (await c.recv("SYSTEM_TIME")).time_boot_ms
            assert boot_before > 3000
            fleet.reboot(1, keep_mission=keep)
            await asyncio.sleep(0.02)
            c.drain()
            await asyncio.sleep(0.05)  # 1 s of mission time: still rebooting (2 s)
            assert not [m for m in c._pending if m.get_type() == "HEARTBEAT"]
            st = await c.recv("SYSTEM_TIME", timeout=2.0)
            assert st.time_boot_ms < boot_before
            assert not v.armed and v.landed
            assert (len(v.mission_items) > 0) == expect_kept
            c.close()
    asyncio.run(asyncio.wait_for(main(), 20))


def test_reboot_command():
    async def main():
        async with FakeFleet(SMALL, speedup=20, seed=1, base_port=0) as fleet:
            c = await MavClient.connect(fleet.endpoints[0][1])
            await c.recv("HEARTBEAT")
            ack = await c.command(1, mav.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, 1)
            assert ack.result == mav.MAV_RESULT_ACCEPTED
            await asyncio.sleep(0.02)
            c.drain()
            await asyncio.sleep(0.04)
            assert c._pending == []
            c.close()
    asyncio.run(asyncio.wait_for(main(), 20))
