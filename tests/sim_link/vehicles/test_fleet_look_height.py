"""A look at its own height (issue 41 item 2, ``[search] look_height_m``) flown by the fake fleet over
UDP at 100x: the vehicle transits at the survey altitude, goes down at the look's entry, rings the
person at the look's height and climbs back; the RSSI slots its receiver reports carry the height
they were heard at, and their RSSI is the channel's at the true slant distance from there."""

from __future__ import annotations

import asyncio
import dataclasses

import numpy as np
import pytest

from sim_link.vehicles.fleet import FakeFleet
from uavloc_gcs.dialect import mavlink as mav
from uavloc_gcs.dialect.rssi import decode_rssi_batches
from uavloc_gcs.heights import look_floor_m
from uavloc_gcs.mission import to_wire
from uavloc_gcs.scenario import load_scenario
from uavloc_gcs.search.orbit import look_mission, plan_orbit

from .mavclient import MavClient

LOOK_M = 30.0
SC = load_scenario("examples/paper.toml").replace(search={"look_height_m": LOOK_M})


def test_a_look_is_flown_at_its_own_height_and_its_slots_carry_that_height():
    sc = SC

    async def main():
        async with FakeFleet(sc, speedup=50, seed=5, base_port=0) as fleet:
            person = fleet.world.positions(0.0)[0]
            orb = plan_orbit(sc, person, 30.0)  # the policy's look: at search.look_height_m
            assert orb.alt_m == LOOK_M
            orb = dataclasses.replace(orb, dwell_s=1.0)  # one turn
            lm = look_mission(sc.frame, [orb.entry_xy_m((0.0, 0.0))], (1,), [orb], alt_m=sc.fleet.altitude_m,
                              speed_m_s=sc.fleet.speed_m_s, autopilot="ardupilot", home_latlon_deg=sc.launch_latlon_deg,
                              start_xy_m=(0.0, 0.0), floor_m=look_floor_m(sc))
            assert lm.look_alt_m == (LOOK_M,)
            wire = to_wire(lm.plan, "ardupilot")
            c = await MavClient.connect(fleet.endpoints[0][1])
            await c.recv("HEARTBEAT")
            assert (await c.upload(1, wire, timeout=10)).type == mav.MAV_MISSION_ACCEPTED
            assert (await c.command(1, mav.MAV_CMD_COMPONENT_ARM_DISARM, 1)).result == 0
            assert (await c.command(1, mav.MAV_CMD_MISSION_START)).result == 0
            while True:
                m = await c.recv("MISSION_CURRENT", timeout=10)
                if m.mission_state == mav.MISSION_STATE_COMPLETE:
                    break
            await asyncio.sleep(0.05)
            c.close()
            return fleet.world, fleet.epoch_unix_s, c.log, orb

    world, epoch, log, orb = asyncio.run(asyncio.wait_for(main(), 150))
    centre = np.asarray(orb.centre_xy_m)
    # telemetry: up to the survey altitude, down to the look's height, and back up before the return
    alt = np.array([m.relative_alt / 1000.0 for m in log if m.get_type() == "GLOBAL_POSITION_INT"])
    top = np.flatnonzero(alt > sc.fleet.altitude_m - 1.0)
    assert len(top) and alt.max() < sc.fleet.altitude_m + 1.0  # took off to the survey altitude
    down = top[0] + np.flatnonzero(np.abs(alt[top[0]:] - LOOK_M) < 1.0)[0]  # down at the look
    up = down + np.flatnonzero(alt[down:] > sc.fleet.altitude_m - 1.0)[0]  # and back up
    look = alt[down:up]
    assert np.sum(np.abs(look - LOOK_M) < 1.0) > 0.7 * len(look) and len(look) > 50
    assert look.min() > LOOK_M - 1.0  # never below the look's height
    # the slots as the ground station decodes them: heard on the ring at the look's height
    slots = decode_rssi_batches([m for m in log if m.get_type() == "UAVLOC_RSSI_BATCH"], sc.frame,
                                epoch_unix_s=epoch)
    z = slots.xyz_m[:, 2]
    low = np.abs(z - LOOK_M) < 1.0
    rho = np.hypot(*(slots.xyz_m[:, :2] - centre).T)
    on_ring = np.abs(rho - orb.radius_m) < 5.0
    assert np.sum(low & on_ring) > 100
    assert np.sum(low & ~on_ring) < 0.1 * np.sum(low)  # low only at the look (its entry's descent and climb)
    assert np.sum(np.abs(z - sc.fleet.altitude_m) < 1.0) > 100  # and the transit's at 100 m
    # their RSSI is the channel's at the slant distance from that height
    idx = np.array([world.index_of(e) for e in slots.emitter_id])
    xy = world.positions(slots.t_s)[np.arange(len(slots)), idx]
    d = np.sqrt(np.sum((xy - slots.xyz_m[:, :2]) ** 2, axis=1) + z ** 2)
    resid = (slots.rssi_dbm - world.channel.median_rssi_dbm(d))[low & on_ring]
    se = sc.channel.shadowing_sigma_db / np.sqrt(sc.channel.samples_per_slot)
    assert abs(resid.mean()) < 4 * se / np.sqrt(len(resid)) + 0.02
    # at 100 m over the same points the slots would read about 10 n log10(d100 / d30) dB louder than heard
    d100 = np.sqrt(np.sum((xy - slots.xyz_m[:, :2]) ** 2, axis=1) + sc.fleet.altitude_m ** 2)
    wrong = (slots.rssi_dbm - world.channel.median_rssi_dbm(d100))[low & on_ring]
    assert wrong.mean() > 2.0 + abs(resid.mean())
