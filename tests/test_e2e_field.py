"""End to end in the field world: the daemon flies fake vehicles whose simulated phones send probe
bursts under changing random addresses, heard above a receiver threshold, reported with the new RSSI
message (address, fingerprint, channel). What the search claims must be true, whatever it manages."""

import csv
import math

import numpy as np
import pytest

from tests.e2e_helpers import FIELD, small_scenario
from uavloc_gcs.cli._fleet import start_fleet_process
from uavloc_gcs.service.daemon import DaemonOptions
from uavloc_gcs.service.run import run_search
from uavloc_gcs.service.store import StoreReader

pytestmark = pytest.mark.slow  # a whole search or demo: `pytest -m 'not slow and not sitl'` leaves it out

TRUTH_MARGIN = 1.5  # as tests/test_e2e_daemon.py: a calibrated radius is this far off once in a thousand


def _search(sc, tmp_path):
    """The daemon's whole search of ``sc`` on the fake fleet (in a child process)."""
    fleet = start_fleet_process(sc, speedup=sc.simulation.speedup, seed=sc.simulation.seed, base_port=0)
    try:
        opts = DaemonOptions(store_path=tmp_path / "search.sqlite", tlog_dir=tmp_path, resume=False)
        conns = [(i + 1, c) for i, (_n, c) in enumerate(fleet.endpoints)]
        return run_search(sc, conns, opts, tmp_path)
    finally:
        fleet.stop()


def test_a_field_search_claims_only_what_is_true(tmp_path):
    from sim_link.world import World

    sc = small_scenario("ardupilot", seed=5, extra=FIELD)
    sc = sc.replace(simulation={"people": 4, "motion": "static"})
    result = _search(sc, tmp_path)
    out = result.outcome
    assert sorted(out.vehicles_home + out.vehicles_returning) == [1, 2], out.statement
    with StoreReader(tmp_path / "search.sqlite") as rd:
        slots = rd.slots()
    assert len(slots) > 0, "some burst was heard"
    # the sensor's view reached the store: random (locally administered) addresses and fingerprints
    assert np.all(slots.fingerprint != 0)
    assert np.mean((slots.address >> 41) & 1) > 0.5
    assert len(np.unique(slots.address)) > len(out.people), "addresses were linked into fewer people"
    assert "No phone was heard" not in out.statement
    world = World(sc, seed=sc.simulation.seed)
    for p in out.people:
        i = int(world.person_of([p.emitter_id])[0])
        assert i >= 0, f"{p.emitter_id:x} is no simulated phone's address"
        if p.located:  # a claim a team acts on: the true position is within reach of it
            truth = world.positions(p.t_ref_s)[i]
            err = math.hypot(p.east_m - truth[0], p.north_m - truth[1])
            assert err <= TRUTH_MARGIN * sc.people.required_accuracy_m, (p, err)
    rows = list(csv.DictReader((tmp_path / "people.csv").open()))
    heard = [r for r in rows if r["state"] != "never heard"]
    assert heard and all(r["addresses"] for r in heard)
    assert all(r["link"] in ("sure", "uncertain") for r in heard)


def test_a_search_with_a_pod_target_flies_the_scan_planned_for_it(tmp_path):
    """search.pod_target: the daemon uploads and flies the POD scan (its lanes and passes, at the
    speed chosen for it), says so, and the claims that follow are the coverage of what was flown."""
    import sqlite3

    from uavloc_gcs.mission import NAV_WAYPOINT
    from uavloc_gcs.service.store import wire_items_from_json
    from uavloc_gcs.search.pod_plan import scan_for, scan_pod_plan

    sc = small_scenario("ardupilot", seed=5, extra=FIELD + "\n[search]\npod_target = 0.9\n")
    sc = sc.replace(simulation={"people": 2, "motion": "static"})
    flown, plan = scan_for(sc)
    pp = scan_pod_plan(sc)
    assert pp.chosen.passes >= 2 and flown.fleet.speed_m_s < sc.fleet.speed_m_s
    result = _search(sc, tmp_path)
    out = result.outcome
    assert sorted(out.vehicles_home + out.vehicles_returning) == [1, 2], out.statement
    with StoreReader(tmp_path / "search.sqlite") as rd:
        said = [e.text for e in rd.events("plan") if "scan planned for POD 0.9" in e.text]
    assert said and f"{pp.chosen.passes} passes" in said[0]
    conn = sqlite3.connect(tmp_path / "search.sqlite")
    scans = {v: wire_items_from_json(j) for v, j in
             conn.execute("SELECT vehicle, items_json FROM missions WHERE purpose = 'scan' ORDER BY rowid")}
    conn.close()
    for vs in plan.vehicles:
        items = scans[vs.index + 1]
        speeds = [it.param2 for it in items if it.command == 178]
        assert speeds and speeds[0] == pytest.approx(flown.fleet.speed_m_s)
        # every waypoint of the planned passes is on board (plus the hold at the end)
        assert sum(it.command == NAV_WAYPOINT for it in items) >= len(vs.waypoints_xy_m)
    cov = out.coverage
    assert cov is not None and not cov.nothing_flown
    assert "Achieved probability of detection" in out.statement


BLE_FIELD = """
[channel]
path_loss_exponent = 2.0
reference_power_dbm = -40.05
receiver_sensitivity_dbm = -90.0
environment = "urban"
[emission]
model = "probe-bursts"
findmy_share = 1.0
[search]
look_height_m = 30.0
max_orbit_looks = 1
time_limit_s = 1500.0
"""


def test_a_search_with_beacons_reports_them_as_ble_and_claims_only_what_is_true(tmp_path):
    """Issue 39 through the daemon: phones that send Find My beacons, fake vehicles whose sensor
    reads them as a BLE sniffer would; the beacons reach the store as BLE, the people heard only
    by them are reported with their radio, and every located claim is within reach of the truth."""
    from sim_link.world import World
    from uavloc_gcs.radios import is_ble

    sc = small_scenario("ardupilot", seed=5, extra=BLE_FIELD)
    sc = sc.replace(simulation={"people": 2, "motion": "static"})
    result = _search(sc, tmp_path)
    out = result.outcome
    assert sorted(out.vehicles_home + out.vehicles_returning) == [1, 2], out.statement
    with StoreReader(tmp_path / "search.sqlite") as rd:
        slots = rd.slots()
    ble = is_ble(slots)
    assert ble.any(), "no beacon reached the store as BLE"
    assert set(np.unique(slots.channel[ble])) <= {37, 38, 39}
    world = World(sc, seed=sc.simulation.seed)
    assert np.all(world.person_of(np.unique(slots.address[ble])) >= 0)
    rows = list(csv.DictReader((tmp_path / "people.csv").open()))
    radios = {r["radio"] for r in rows if r["state"] != "never heard"}
    assert "ble" in radios, rows
    assert "heard by Bluetooth LE beacons alone" in out.statement
    assert "heard by Bluetooth LE beacons alone" in (tmp_path / "results.txt").read_text()
    for p in out.people:
        if p.located:
            i = int(world.person_of([p.emitter_id])[0])
            truth = world.positions(p.t_ref_s)[i]
            err = math.hypot(p.east_m - truth[0], p.north_m - truth[1])
            assert err <= TRUTH_MARGIN * sc.people.required_accuracy_m, (p, err)
