"""End to end in the field world: the daemon flies fake vehicles whose simulated phones send probe
bursts under changing random addresses, heard above a receiver threshold, reported with the new RSSI
message (address, fingerprint, channel). What the search claims must be true, whatever it manages."""

import csv
import math

import numpy as np

from tests.e2e_helpers import FIELD, small_scenario
from uavloc_gcs.cli._fleet import start_fleet_process
from uavloc_gcs.service.daemon import DaemonOptions
from uavloc_gcs.service.run import run_search
from uavloc_gcs.service.store import StoreReader

TRUTH_MARGIN = 1.5  # as tests/test_e2e_daemon.py: a calibrated radius is this far off once in a thousand


def test_a_field_search_claims_only_what_is_true(tmp_path):
    from sim_link.world import World

    sc = small_scenario("ardupilot", seed=5, extra=FIELD)
    sc = sc.replace(simulation={"people": 4, "motion": "static"})
    fleet = start_fleet_process(sc, speedup=sc.simulation.speedup, seed=sc.simulation.seed, base_port=0)
    try:
        opts = DaemonOptions(store_path=tmp_path / "search.sqlite", tlog_dir=tmp_path, resume=False)
        conns = [(i + 1, c) for i, (_n, c) in enumerate(fleet.endpoints)]
        result = run_search(sc, conns, opts, tmp_path)
    finally:
        fleet.stop()
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
