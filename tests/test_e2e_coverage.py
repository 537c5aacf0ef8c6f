"""End to end: one of two fake vehicles is lost mid-scan (its link cut for good). Coverage comes from
the flown telemetry, so its unflown lanes are below the POD target: the other vehicle flies them
when its energy allows; when nobody can, the results say how much was not searched and where, and
`uavloc daemon` exits 4 (issue 26 item 3). It was lost in the air, so that is said first, in every
file and on the live map, and `uavloc daemon` exits 5 (issue 42 item 2)."""

import asyncio
import csv
import json

import pytest

from tests.e2e_helpers import small_scenario
from uavloc_gcs.cli._fleet import start_fleet_process
from uavloc_gcs.cli.daemon import exit_code
from uavloc_gcs.search import coverage as coverage_mod
from uavloc_gcs.service.lost import EXIT_VEHICLE_LOST
from uavloc_gcs.service.daemon import DaemonOptions
from uavloc_gcs.service.run import run_search
from uavloc_gcs.service.store import StoreReader

pytestmark = pytest.mark.slow  # a whole search or demo: `pytest -m 'not slow and not sitl'` leaves it out


def _run(tmp_path, during):
    # a 90 m range (67 m on the ground at 60 m): vehicle 2's lanes (x = 0-267 m) are out of
    # vehicle 1's hearing (x = 267-400 m), so what vehicle 2 did not fly nobody heard
    sc = small_scenario().replace(fleet={"comm_range_m": 90.0})
    fleet = start_fleet_process(sc, speedup=sc.simulation.speedup, seed=sc.simulation.seed, base_port=0)
    try:
        opts = DaemonOptions(store_path=tmp_path / "search.sqlite", tlog_dir=tmp_path, resume=False,
                             lost_timeout_s=1.5)
        conns = [(i + 1, c) for i, (_n, c) in enumerate(fleet.endpoints)]
        daemons = []

        def on_daemon(d):
            daemons.append(d)
            during(d, fleet)

        result = run_search(sc, conns, opts, tmp_path, on_daemon=on_daemon)
    finally:
        fleet.stop()
    return sc, result, daemons[0]


def _lose_vehicle_2_mid_scan(daemon, fleet, cut: list):
    async def cut_when_scanning():
        while True:
            v2 = daemon.vehicles[2]
            if v2.phase == "scanning" and daemon.coverage.flown_s > 30.0:  # both airborne for a while
                fleet.drop_link(2, 1e6)
                cut.append(daemon.now_s())
                return
            await asyncio.sleep(0.05)

    orig = daemon._brain

    async def brain():
        task = asyncio.ensure_future(cut_when_scanning())
        try:
            await orig()
        finally:
            task.cancel()

    daemon._brain = brain


@pytest.mark.parametrize("passes", ["replanned", "nobody can"])
def test_a_vehicle_lost_mid_scan_has_its_area_flown_by_the_other_or_reported(tmp_path, monkeypatch, passes):
    if passes == "nobody can":
        monkeypatch.setattr(coverage_mod, "MAX_PASS_ROUNDS", 0)
    cut: list = []
    sc, result, daemon = _run(tmp_path, lambda d, f: _lose_vehicle_2_mid_scan(d, f, cut))
    out = result.outcome
    assert cut, "vehicle 2's link was cut"
    assert 2 in out.vehicles_lost, out.statement
    cov = out.coverage
    assert cov is not None and not cov.nothing_flown
    assert "Achieved probability of detection" in out.statement
    with StoreReader(tmp_path / "search.sqlite") as rd:
        lost_at = min(e.t_s for e in rd.events("lost") if e.vehicle == 2)
        after = [e for e in rd.events("upload") if e.vehicle == 1 and e.t_s > lost_at]
    if passes == "replanned":
        assert after, "vehicle 1 got a mission after vehicle 2 was lost"
        assert cov.unsearched_m2 == 0.0, out.statement
        assert not out.unsearched_after_loss
        assert "was not searched" not in out.statement
    else:
        assert cov.unsearched_m2 > 0.0
        assert out.unsearched_after_loss  # -> `uavloc daemon` exit code 4 (EXIT_UNSEARCHED)
        assert "was not searched: vehicle(s) 2" in out.statement and "Unsearched" in out.statement
    # lost in the air (issue 42 item 2): said first, with its last position, height and battery, and
    # the exit code of its own, whether or not its lanes were flown by the other
    assert [x.vehicle for x in out.lost_in_air] == [2], out.statement
    lh = out.lost_in_air[0]
    assert lh.airborne and lh.rel_alt_m > 20.0, lh
    first = lh.sentence()
    assert out.statement.startswith(f"Vehicle 2 was lost in the air: last heard at ") and out.statement.startswith(first)
    assert "m above home" in first and "battery" in first
    assert exit_code(out) == EXIT_VEHICLE_LOST
    assert out.statement.count("was lost in the air") == 1
    assert (tmp_path / "results.txt").read_text().startswith(first + "\n")
    assert (tmp_path / "people.csv").read_text().startswith(f"# {first}\n")
    gj_lost = json.loads((tmp_path / "people.geojson").read_text())
    assert [x["vehicle"] for x in gj_lost["vehicles_lost"]] == [2]
    assert gj_lost["features"][0]["properties"]["kind"] == "vehicle_lost"
    assert "vehicle 2 LOST IN THE AIR" in (tmp_path / "people.kml").read_text()
    notes = {s.vehicle: s.note for s in daemon.snapshot().vehicles}  # the live map's vehicle status
    assert notes[2].startswith("Vehicle 2 was lost in the air") and notes[1] == ""
    # the claims in the files
    # (its '#' lines, the lost vehicle's sentence, come first: a spreadsheet shows them on top)
    rows = list(csv.DictReader(line for line in (tmp_path / "people.csv").open() if not line.startswith("#")))
    assert rows and all("pod_here" in r for r in rows)
    heard = [r for r in rows if r["state"] != "never heard" and r["east_m"]]
    assert all(0.0 <= float(r["pod_here"]) <= 1.0 for r in heard if r["pod_here"])
    gj = json.loads((tmp_path / "people.geojson").read_text())
    cells = [f for f in gj["features"] if f["properties"]["kind"] == "pod_cell"]
    assert len(cells) == len(cov.pod1)
    assert gj["coverage"]["unsearched_m2"] == pytest.approx(cov.unsearched_m2, abs=0.1)
    assert any(c["properties"]["unsearched"] for c in cells) == (cov.unsearched_m2 > 0)
    assert "achieved POD" in (tmp_path / "people.kml").read_text()
    assert "Achieved probability of detection" in (tmp_path / "results.txt").read_text()
