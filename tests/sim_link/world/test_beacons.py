"""Find My BLE beacons in the field world (issue 39 item 1; sim_link/world/beacons.py): a share of
the phones advertise every 2 s under an address that rotates every 15 minutes, at a BLE link budget
that is shorter than Wi-Fi's; the Wi-Fi world is drawn exactly as without them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sim_link.world import World
from uavloc_gcs.errors import ConfigError
from uavloc_gcs.observations import SlotBatch
from uavloc_gcs.radios import ble_view, is_ble, radio_of
from uavloc_gcs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]


def _field(share: float):
    return load_scenario(ROOT / "examples" / "field.toml").replace(emission={"findmy_share": share})


def _hover(world: World, xyz, seconds: float, vehicle: int = 1) -> SlotBatch:
    sc = world.scenario
    t = np.arange(0.0, seconds, sc.channel.slot_s)
    parts = [world.hear_track(vehicle, t[i:i + 2000], np.tile(xyz, (len(t[i:i + 2000]), 1)))
             for i in range(0, len(t), 2000)]
    return SlotBatch.concat(parts)


def test_a_share_of_the_phones_advertise_every_two_seconds_under_rotating_addresses():
    world = World(_field(0.5), seed=4, people=40, motion="static")
    b = world.beacons
    assert 10 <= b.sends.sum() <= 30  # about half of 40
    f = b.frames(0.0, 3600.0)
    assert set(np.unique(f.person)) == set(b.senders.tolist())
    assert set(np.unique(f.channel)) == {37, 38, 39}
    i = int(b.senders[0])
    t = f.t_s[f.person == i]
    gaps = np.diff(t)
    assert np.all(np.abs(gaps - 2.0) <= 0.0101)  # the interval and the advDelay of 0-10 ms
    addrs = f.address[f.person == i]
    changes = np.flatnonzero(np.diff(addrs) != 0)
    assert len(changes) in (3, 4)  # an hour of 15-minute keys
    assert np.allclose(np.diff(t[changes + 1]), 900.0, atol=2.1)
    assert np.all((addrs >> 46) == 0b11)  # random static addresses
    assert np.all(world.person_of(np.unique(addrs)) == i)
    # asked in pieces, the same beacons
    pieces = [b.frames(a, a + 7.3) for a in np.arange(0.0, 73.0, 7.3)]
    whole = b.frames(0.0, 73.0)
    assert np.array_equal(np.concatenate([p.t_s for p in pieces]), whole.t_s)


def test_beacons_are_heard_close_and_low_and_not_from_the_scan_height():
    world = World(_field(1.0), seed=2, people=1, motion="static")
    person = world.positions(0.0)[0]
    low = _hover(world, [person[0] + 20.0, person[1], 30.0], 300.0, vehicle=1)
    high = _hover(world, [person[0] + 20.0, person[1], 150.0], 300.0, vehicle=2)
    n_low, n_high = int(is_ble(low).sum()), int(is_ble(high).sum())
    assert n_low >= 40, n_low  # of 150 sent, most heard 36 m away (one shadowing draw: some may fade)
    assert n_high <= 5, n_high  # 150 m up, below the BLE scanner's threshold
    assert (~is_ble(high)).sum() == 0 or np.all(high.channel[~is_ble(high)] <= 14)
    # the BLE link budget is the cautious one: shorter than Wi-Fi's
    from uavloc_gcs.a2g import LOS, A2GChannel
    wifi, ble = A2GChannel.from_scenario(world.scenario), A2GChannel.from_scenario(ble_view(world.scenario))
    assert ble.state_range_m(LOS) < 0.3 * wifi.state_range_m(LOS)


def test_the_wifi_world_is_drawn_exactly_as_without_beacons():
    p0 = World(_field(0.0), seed=7, people=8, motion="static").positions(0.0)[0]
    xyz = [p0[0] + 15.0, p0[1], 40.0]
    plain = _hover(World(_field(0.0), seed=7, people=8, motion="static"), xyz, 600.0)
    both = _hover(World(_field(1.0), seed=7, people=8, motion="static"), xyz, 600.0)
    wifi = both.take(~is_ble(both))
    assert len(plain) > 0 and len(wifi) == len(plain)
    assert np.array_equal(wifi.rssi_dbm, plain.rssi_dbm) and np.array_equal(wifi.address, plain.address)
    assert is_ble(both).sum() > 0
    assert radio_of(both.take(is_ble(both))) == "ble" and radio_of(plain) == "wifi"
    assert World(_field(0.0), seed=7, people=8).beacons is None


@pytest.mark.parametrize("key, value, says", [
    ("findmy_share", 1.5, "between 0 and 1"),
    ("ble_interval_s", 0.001, "shorter than any BLE advertising interval"),
    ("ble_key_rotation_s", 1.0, "not longer than the advertising interval"),
])
def test_impossible_beacons_are_refused_naming_the_key(key, value, says):
    with pytest.raises(ConfigError, match=says) as e:
        _field(0.2).replace(emission={key: value})
    assert f"emission.{key}" in str(e.value)


def test_beacons_need_the_field_worlds_channel():
    paper = load_scenario(ROOT / "examples" / "paper.toml")
    with pytest.raises(ConfigError, match="field world") as e:
        paper.replace(emission={"findmy_share": 0.3})
    assert "emission.findmy_share" in str(e.value)


def test_the_world_and_the_sensor_mark_the_ble_radio_alike():
    from uavloc_gcs.radios import RADIO_BLE
    from uavloc_gcs.sense.frames import RADIO_BLE as SENSED_BLE

    assert RADIO_BLE == SENSED_BLE
