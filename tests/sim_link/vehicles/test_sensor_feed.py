"""The simulated companion's slots through the real sensor (``uavloc sim --companion --via-sense``)."""

from __future__ import annotations

import asyncio

import numpy as np

from uavloc_gcs.dialect.rssi import decode_rssi_batches
from uavloc_gcs.observations import SlotBatch
from uavloc_gcs.scenario import load_scenario
from sim_link.vehicles.companion import CompanionEmulator
from sim_link.vehicles.fleet import FakeFleet
from sim_link.vehicles.sensor_feed import frames_for, through_sensor
from sim_link.world import World

from .mavclient import MavClient

SC = load_scenario("examples/paper.toml").replace(fleet={"vehicles": 1})


def _heard(n=60, seed=0):
    rng = np.random.default_rng(seed)
    t = np.sort(rng.choice(2000, n, replace=False)) * 0.025
    addr = rng.integers(0, 2**48, n)
    return SlotBatch.from_columns(t, np.full(n, 2), rng.normal(size=(n, 3)), addr, rng.uniform(-90, -40, n),
                                  rng.integers(1, 12, n), address=addr, fingerprint=rng.choice([11, 22, 33], n),
                                  channel=rng.choice([1, 6, 11], n))


def test_slots_survive_the_sensor():
    h = _heard()
    out = through_sensor(h, 0.025, 1.75e9)
    assert len(out) == len(h)
    o = np.argsort(out.address)
    i = np.argsort(h.address)
    assert np.array_equal(out.address[o], h.address[i])
    assert np.array_equal(out.n_samples[o], h.n_samples[i]) and np.array_equal(out.channel[o], h.channel[i])
    assert np.abs(out.rssi_dbm[o] - h.rssi_dbm[i]).max() <= 0.5  # whole dBm per frame, as drivers report
    assert np.array_equal(out.xyz_m[o], h.xyz_m[i]) and np.allclose(out.t_s[o], h.t_s[i])
    # the sensor's own fingerprints, one per world fingerprint
    pairs = set(zip(h.fingerprint[i].tolist(), out.fingerprint[o].tolist()))
    assert len(pairs) == 3 and len({b for _, b in pairs}) == 3


def test_the_frames_are_a_capture_the_cli_reads(tmp_path):
    from uavloc_gcs.cli import main

    (tmp_path / "c.pcap").write_bytes(frames_for(_heard(20), 0.025, 1.75e9))
    assert main(["sense", str(tmp_path / "c.pcap"), "--out", str(tmp_path / "o")]) == 0
    rows = (tmp_path / "o" / "frames.csv").read_text().splitlines()
    assert len(rows) - 1 == int(_heard(20).n_samples.sum())


def test_companion_via_sense_on_a_fake_autopilot():
    world = World.with_people(SC, [[0.0, 60.0], [30.0, -40.0], [900.0, 500.0]], seed=3)

    async def main():
        async with FakeFleet(SC, speedup=20, seed=1, base_port=0, world=world, onboard_rssi=False,
                             route=True) as fleet:
            url = fleet.endpoints[0][1]
            comp = CompanionEmulator(SC, url, world=world, epoch_unix_s=fleet.epoch_unix_s, via_sense=True)
            stop = asyncio.Event()
            task = asyncio.create_task(comp.run(stop))
            gcs = await MavClient.connect(url)
            await gcs.recv("HEARTBEAT")
            await gcs.take_off()
            await asyncio.sleep(1.2)
            stop.set()
            await task
            msgs = [m for m in gcs.log if m.get_type() == "UAVLOC_RSSI_BATCH2"]
            assert msgs and comp.stats.slots > 0
            slots = decode_rssi_batches(msgs, SC.frame, epoch_unix_s=fleet.epoch_unix_s)
            # the near people, by their addresses; whole-dBm frames; the sensor's channel and fingerprint
            assert set(slots.address.tolist()) == set(world.emitter_ids[:2].tolist())
            assert np.all(slots.channel == 6) and np.all(slots.fingerprint > 0)
            assert np.abs(slots.xyz_m[:, :2]).max() < 1.0
            gcs.close()
    asyncio.run(asyncio.wait_for(main(), 90))


def test_fake_vehicles_onboard_rssi_via_sense():
    """The demo's path (FakeFleet with vehicle_options via_sense, the default of ``uavloc demo``): the
    onboard RSSI the fake vehicle sends is the parser's output, not the world's slots. The world's
    RSSI is continuous and its fingerprints are the world's; through the sensor every slot's mean
    is of whole-dBm frames and every fingerprint is the sensor's hash of the frames' elements."""
    from uavloc_gcs.sense.dot11 import fingerprint_elements
    from sim_link.vehicles.sensor_feed import _elements

    world = World.with_people(SC, [[0.0, 60.0], [30.0, -40.0], [900.0, 500.0]], seed=3)

    async def main():
        async with FakeFleet(SC, speedup=20, seed=1, base_port=0, world=world,
                             vehicle_options={"via_sense": True}) as fleet:
            url = fleet.endpoints[0][1]
            gcs = await MavClient.connect(url)
            await gcs.recv("HEARTBEAT")
            await gcs.take_off()
            await asyncio.sleep(1.2)
            msgs = [m for m in gcs.log if m.get_type().startswith("UAVLOC_RSSI_BATCH")]
            gcs.close()
            return msgs, fleet.epoch_unix_s

    msgs, epoch = asyncio.run(asyncio.wait_for(main(), 90))
    slots = decode_rssi_batches(msgs, SC.frame, epoch_unix_s=epoch)
    assert len(slots) > 10
    assert set(slots.address.tolist()) == set(world.emitter_ids[:2].tolist())
    sensor_fp = {fingerprint_elements(b"".join(_elements(int(f))))[0] for f in world.fingerprints[:2]}
    assert set(slots.fingerprint.tolist()) <= sensor_fp
    assert np.allclose(slots.rssi_dbm, np.round(slots.rssi_dbm), atol=0.01)


def test_beacons_go_through_the_ble_sniffer_path_and_stay_ble():
    """The world's Find My beacons reach the ground as the sensor reads them from a BLE sniffer
    (link type 256), with their radio, channel, address and whole-dBm RSSI: not as Wi-Fi probe
    requests on a 'channel 37' (which the ground would judge by the Wi-Fi link budget)."""
    from sim_link.world import World
    from uavloc_gcs.examples import scenario_path
    from uavloc_gcs.radios import is_ble
    from uavloc_gcs.scenario import load_scenario

    sc = load_scenario(scenario_path("field")).replace(emission={"findmy_share": 1.0})
    w = World(sc, seed=3, people=3, motion="static")
    p = w.positions(0.0)[0]
    t = np.arange(0.0, 120.0, sc.channel.slot_s)
    heard = w.hear_track(1, t, np.column_stack([p[0] + 20 + 0 * t, p[1] + 0 * t, 30 + 0 * t]))
    out = through_sensor(heard, sc.channel.slot_s, 1.7e9)
    b_in, b_out = is_ble(heard), is_ble(out)
    assert b_in.sum() >= 10 and b_out.sum() == b_in.sum() and (~b_out).sum() == (~b_in).sum()
    assert set(out.address[b_out]) == set(heard.address[b_in])
    assert set(out.channel[b_out]) <= {37, 38, 39}
    assert np.array_equal(np.sort(out.rssi_dbm[b_out]), np.sort(np.round(heard.rssi_dbm[b_in])))
    assert np.all(out.fingerprint[b_out] != 0)  # the Find My key, rebuilt by the sensor
