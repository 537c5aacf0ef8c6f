"""A BLE beacon identity in the search policy (issue 39 items 3-4): its own radio's estimate (one
beacon per unit, the BLE link budget), the events a listening vehicle missed counted as evidence,
its looks planned for a stream of beacons, and never one person with a Wi-Fi identity."""

from __future__ import annotations

import numpy as np
import pytest

from sim_link.world import World
from uavloc_gcs.examples import scenario_path
from uavloc_gcs.observations import SlotBatch
from uavloc_gcs.radios import BLE, WIFI, is_ble, radio_of
from uavloc_gcs.scenario import load_scenario
from uavloc_gcs.search import SearchPolicy


@pytest.fixture(scope="module")
def heard():
    sc = load_scenario(scenario_path("field")).replace(
        emission={"findmy_share": 1.0}, people={"max_speed_m_s": 0.0}, simulation={"motion": "static"},
        search={"look_height_m": 30.0})
    world = World(sc, seed=5, people=1)
    person = world.positions(0.0)[0]
    t = np.arange(0.0, 240.0, sc.channel.slot_s)
    ang = 8.0 * t / 30.0
    xyz = np.column_stack([person[0] + 30 * np.cos(ang), person[1] + 30 * np.sin(ang), np.full(len(t), 30.0)])
    slots = SlotBatch.concat([world.hear_track(1, t[i:i + 400], xyz[i:i + 400]) for i in range(0, len(t), 400)])
    return sc, world, person, t, xyz, slots


def test_a_beacon_identity_is_estimated_from_its_beacons_and_the_ones_missed(heard):
    sc, world, person, t, xyz, slots = heard
    ble = slots.take(is_ble(slots))
    assert len(np.unique(ble.address)) >= 1 and len(ble) >= 30
    policy = SearchPolicy(sc)
    policy.ingest(slots)
    policy.ingest_track(1, t, xyz)
    policy.update(float(t[-1]))
    ids = [p for p in policy._people.values() if radio_of(p.batches[0]) == BLE]
    assert ids, "no BLE identity among the people"
    p = max(ids, key=lambda q: len(q.batches[0]))
    assert all(radio_of(q.batches[0]) in (BLE, WIFI) for q in policy._people.values())
    assert not any(np.any(is_ble(q.batches[0])) and not np.all(is_ble(q.batches[0]))
                   for q in policy._people.values()), "a Wi-Fi and a BLE identity made one person"
    units = policy._bursts_of(p)
    heard_u = [u for u in units if not u.silent]
    missed = [u for u in units if u.silent]
    span = max(u.t_s for u in heard_u) - min(u.t_s for u in heard_u)
    assert len(heard_u) == len(p.batches[0])  # one beacon, one unit
    assert len(heard_u) + len(missed) == pytest.approx(span / sc.emission.ble_interval_s + 1, abs=2)
    assert policy.scenario_for(p.emitter_id).channel.receiver_sensitivity_dbm == sc.channel.ble_receiver_sensitivity_dbm
    st = {s.emitter_id: s for s in policy.people(float(t[-1]))}[p.emitter_id]
    assert st.xy_m is not None
    err = float(np.hypot(*(np.asarray(st.xy_m) - person)))
    assert err <= st.radius95_m * 1.5, (err, st.radius95_m)


def test_a_beacon_identitys_look_flies_at_the_floor_for_a_stream_of_beacons():
    """A beacon at 0 dBm is seldom heard from the survey's 100 m: a BLE identity's orbit flies at
    the look floor whatever search.look_height_m says, its dwell is the one for single frames, and
    the slots down there count as airborne."""
    from uavloc_gcs.heights import airborne_floor_m, look_floor_m
    from uavloc_gcs.radios import ble_view
    from uavloc_gcs.search import orbit

    sc = load_scenario(scenario_path("field")).replace(emission={"findmy_share": 0.22})
    assert sc.search.look_height_m is None  # Wi-Fi looks at the survey altitude
    view = ble_view(sc)
    o = orbit.plan_orbit(view, (0.0, 0.0), 20.0)
    assert o.alt_m == look_floor_m(sc) < sc.fleet.altitude_m
    assert orbit.elicited(view) and view.emission.elicitation_rate_hz == pytest.approx(0.5)
    assert airborne_floor_m(sc) <= 0.5 * look_floor_m(sc) < airborne_floor_m(sc.replace(emission={"findmy_share": 0.0}))
