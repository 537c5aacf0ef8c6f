"""The paper scenario's scan mission flown over UDP at 100x: every waypoint in order, no stop,
and the RSSI the ground station decodes agrees with the channel model."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

from uavloc_gcs.dialect import mavlink as mav
from uavloc_gcs.dialect.rssi import decode_rssi_batches
from uavloc_gcs.mission import to_wire
from uavloc_gcs.scan import plan_scan, scan_missions
from uavloc_gcs.scenario import load_scenario
from sim_link.vehicles.fleet import FakeFleet

from .mavclient import MavClient

PAPER = load_scenario("examples/paper.toml")


def test_paper_scan_over_udp():
    sc = PAPER
    wire = to_wire(scan_missions(sc, plan_scan(sc))[1], "ardupilot")  # uav2's lanes

    async def main():
        async with FakeFleet(sc, speedup=100, seed=5, base_port=0) as fleet:
            c = await MavClient.connect(fleet.endpoints[1][1])
            await c.recv("HEARTBEAT")
            assert (await c.upload(2, wire)).type == mav.MAV_MISSION_ACCEPTED
            assert (await c.command(2, mav.MAV_CMD_COMPONENT_ARM_DISARM, 1)).result == 0
            assert (await c.command(2, mav.MAV_CMD_MISSION_START)).result == 0
            while True:
                m = await c.recv("MISSION_CURRENT", timeout=10)
                if m.mission_state == mav.MISSION_STATE_COMPLETE:
                    break
            await asyncio.sleep(0.05)
            c.close()
            return fleet.world, fleet.epoch_unix_s, c.log

    world, epoch, log = asyncio.run(asyncio.wait_for(main(), 60))
    reached = [(k, m.seq) for k, m in enumerate(log) if m.get_type() == "MISSION_ITEM_REACHED"]
    nav = [w.seq for w in wire if w.command in (16, 20, 22) and w.seq >= 1]
    assert [s for _, s in reached] == nav
    # ground speed from GLOBAL_POSITION_INT between the first and the second-to-last waypoint
    wp = [k for k, s in reached if wire[s].command == 16]
    gpi = [m for m in log[wp[0]:wp[-2]] if m.get_type() == "GLOBAL_POSITION_INT"]
    boot0 = gpi[0].time_boot_ms
    speed = np.array([np.hypot(m.vx, m.vy) / 100 for m in gpi if m.time_boot_ms - boot0 > 6000])
    assert len(speed) > 100
    assert speed.min() > 8.0 and np.median(speed) == pytest.approx(sc.fleet.speed_m_s, rel=0.02)  # never stops
    # RSSI as received: from (2, 191), consistent with the channel at the true distances
    rssi = [m for m in log if m.get_type() == "UAVLOC_RSSI_BATCH"]
    assert {(m.get_srcSystem(), m.get_srcComponent()) for m in rssi} == {(2, 191)}
    slots = decode_rssi_batches(rssi, sc.frame, epoch_unix_s=epoch)
    assert len(slots) > 500 and set(slots.vehicle.tolist()) == {2}
    idx = np.array([world.index_of(e) for e in slots.emitter_id])
    xy = world.positions(slots.t_s)[np.arange(len(slots)), idx]
    d = np.sqrt(np.sum((xy - slots.xyz_m[:, :2]) ** 2, axis=1) + slots.xyz_m[:, 2] ** 2)
    assert d.max() <= sc.fleet.comm_range_m + 0.5
    resid = slots.rssi_dbm - world.channel.median_rssi_dbm(d)
    se = sc.channel.shadowing_sigma_db / np.sqrt(sc.channel.samples_per_slot)
    assert abs(resid.mean()) < 4 * se / np.sqrt(len(resid)) + 0.02
    assert resid.std() == pytest.approx(se, rel=0.1)
