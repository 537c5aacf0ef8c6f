"""A vehicle lost in the air (issue 42 item 2): its own exit code, said first, in every file and on
the live map. The daemon's side is driven by real MAVLink messages into a real VehicleAgent."""

import csv
import io
import json
import math

import numpy as np
from lxml import etree

from tests.e2e_helpers import small_scenario
from tests.uavloc_gcs.service.test_vehicle_agent import _Link
from uavloc_gcs.cli.daemon import exit_code
from uavloc_gcs.dialect import mavlink as mav
from uavloc_gcs.service.daemon import Daemon, DaemonOptions
from uavloc_gcs.service.lost import EXIT_VEHICLE_LOST, LastHeard, mark_lost, title_mark
from uavloc_gcs.service.outcome import EXIT_UNSEARCHED, SearchOutcome, statement_for
from uavloc_gcs.service.results import PersonResult, write_results
from uavloc_gcs.service.store import Store
from uavloc_gcs.service.vehicle import VehicleAgent

from .test_daemon_decisions import _Policy

LOST = LastHeard(2, True, 812.34, 1_795_000_000.0, 42.6261234, 13.2849876, 152.0, -13.0, 40.1, 63.0, "AUTO", True)


def _p(eid, located, reason=""):
    return PersonResult(eid, 42.626, 13.284, 10.0, 20.0, 0.0, 0.0, 5.0, 9.0, 10.0, located, True, reason, 50.0)


def test_the_sentence_names_the_vehicle_its_last_position_height_battery_and_time():
    s = LOST.sentence()
    assert s.startswith("Vehicle 2 was lost in the air: last heard at 2026-11-18 11:06:40 UTC (this computer's "
                        "clock; mission time 812.3 s)")
    assert "42.6261234, 13.2849876 (152 m east, 13 m south of the launch point, 153 m away)" in s
    assert "40.1 m above home" in s and "battery 63 %" in s and "armed in AUTO" in s


def test_the_statement_says_it_first_once_and_never_that_all_are_home():
    text = statement_for([_p(1, True)], 15, [2], [], lost_in_air=[LOST])
    assert "All vehicles are home" not in text and "Lost contact" not in text  # said in its own sentence
    text = statement_for([_p(1, True)], 15, [2, 3], [], lost_in_air=[LOST])
    assert "Lost contact with vehicle(s) 3." in text  # lost on the ground: the old sentence


def test_exit_codes_in_order_of_what_the_operator_must_hear_first():
    base = SearchOutcome((), True, "", 0.0, 0, (1,), ())
    assert exit_code(base) == 0
    assert exit_code(SearchOutcome((), False, "", 0.0, 0, (1,), ())) == 1
    unsearched = SearchOutcome((), True, "", 0.0, 0, (1,), (2,), unsearched_after_loss=True)
    assert exit_code(unsearched) == EXIT_UNSEARCHED == 4
    both = SearchOutcome((), True, "", 0.0, 0, (1,), (2,), unsearched_after_loss=True, lost_in_air=(LOST,))
    assert exit_code(both) == EXIT_VEHICLE_LOST == 5


def test_every_file_says_it_first(tmp_path):
    sc = small_scenario()
    frame = sc.frame
    files = write_results(tmp_path, [_p(1, True)], frame=frame, area_latlon_deg=np.array(sc.polygon_latlon_deg),
                          tracks_latlon_deg={}, required_accuracy_m=15.0, name="t" + title_mark([LOST]),
                          epoch_unix_s=1_795_000_000.0)
    mark_lost(files, [LOST])
    assert (tmp_path / "results.txt").read_text().splitlines()[0] == LOST.sentence()
    text = (tmp_path / "people.csv").read_text()
    assert text.splitlines()[0] == "# " + LOST.sentence()
    rows = list(csv.DictReader(io.StringIO("".join(line + "\n" for line in text.splitlines()
                                                    if not line.startswith("#")))))
    assert rows[0]["emitter_id"] == "1"  # the table itself is untouched
    gj = json.loads((tmp_path / "people.geojson").read_text())
    assert gj["vehicles_lost"][0]["statement"] == LOST.sentence() and gj["vehicles_lost"][0]["rel_alt_m"] == 40.1
    point = gj["features"][0]
    assert point["properties"]["kind"] == "vehicle_lost" and point["geometry"]["coordinates"] == [13.2849876, 42.6261234]
    kml = etree.fromstring((tmp_path / "people.kml").read_bytes())
    ns = {"k": "http://www.opengis.net/kml/2.2"}
    assert "VEHICLE 2 LOST IN THE AIR" in kml.find("k:Document/k:name", ns).text
    first = kml.find("k:Document/k:Placemark", ns)
    assert first.find("k:name", ns).text == "vehicle 2 LOST IN THE AIR"
    assert first.find("k:description", ns).text == LOST.sentence()


class _NobodyHeard(_Policy):
    def people(self, t_s):
        return []


def _hb(armed: bool):
    return mav.MAVLink_heartbeat_message(2, 3, 89 | (128 if armed else 0), 3, 4, 3)  # ArduCopter, AUTO


def test_a_vehicle_silent_in_the_air_is_lost_in_the_air_first_in_the_statement_and_on_the_map(tmp_path):
    """Fed real MAVLink: vehicle 2 airborne at 40 m, 63 % battery, then silent past the lost timeout;
    vehicle 1 landed and disarmed, then silent too: lost, but not in the air."""
    sc = small_scenario()
    d = Daemon(sc, [(1, "udpout:127.0.0.1:1"), (2, "udpout:127.0.0.1:2")],
               DaemonOptions(store_path=tmp_path / "s.sqlite", lost_timeout_s=5.0), policy=_NobodyHeard())
    d.store = Store(tmp_path / "s.sqlite")
    clock = [100.0]
    d.wall = lambda: clock[0]
    links = {}
    try:
        for vid in (1, 2):
            links[vid] = _Link()
            d.vehicles[vid].agent = VehicleAgent(vid, links[vid], d.frame, autopilot="ardupilot",
                                                 epoch_unix_s=lambda: 0.0, wall=lambda: clock[0])
            d.vehicles[vid]._phase = "scanning"
        lat, lon = (float(x) for x in d.frame.to_wgs84(152.0, -13.0))
        links[2].feed(_hb(True))
        links[2].feed(mav.MAVLink_global_position_int_message(1000, int(lat * 1e7), int(lon * 1e7), 0, 40100,
                                                              800, 0, 0, 0))
        links[2].feed(mav.MAVLink_sys_status_message(0, 0, 0, 0, 0, 0, 63, 0, 0, 0, 0, 0, 0))
        links[1].feed(_hb(False))
        links[1].feed(mav.MAVLink_global_position_int_message(1000, 426250000, 132830000, 0, 0, 0, 0, 0, 0))
        links[1].feed(mav.MAVLink_extended_sys_state_message(0, mav.MAV_LANDED_STATE_ON_GROUND))
        clock[0] = 106.0
        for v in d.vehicles.values():
            d._update_phase(v)
        v1, v2 = d.vehicles[1], d.vehicles[2]
        assert v1.lost and v2.lost
        assert v2.last_heard.airborne and not v1.last_heard.airborne
        assert v2.last_heard.battery_pct == 63.0 and math.isclose(v2.last_heard.rel_alt_m, 40.1)
        assert math.isclose(v2.last_heard.east_m, 152.0, abs_tol=0.5)
        snap = d.snapshot()
        notes = {s.vehicle: s.note for s in snap.vehicles}
        assert notes[2].startswith("Vehicle 2 was lost in the air") and notes[1] == ""
        d.store.flush()
        from uavloc_gcs.service.store import StoreReader

        with StoreReader(tmp_path / "s.sqlite") as rd:
            lost = {e.vehicle: e.text for e in rd.events("lost")}
        assert "LOST IN THE AIR" in lost[2] and "40.1 m above home" in lost[2] and "LOST IN THE AIR" not in lost[1]
        # the live map's feed: the alert and the vehicle's note
        from uavloc_gcs.service.web import MapFeed

        feed = MapFeed(sc, tmp_path / "s.sqlite", snapshot=d.snapshot, epoch=d.clock)
        live = feed.live()
        assert live["alert"].startswith("Vehicle 2 was lost in the air")
        assert [v["note"] != "" for v in live["vehicles"]] == [False, True]
        # the statement: the lost vehicle first
        outcome = d._outcome()
        assert outcome.statement.startswith("Vehicle 2 was lost in the air: last heard at ")
        assert outcome.lost_in_air == (v2.last_heard,) and exit_code(outcome) == EXIT_VEHICLE_LOST
        assert "Lost contact with vehicle(s) 1." in outcome.statement
        # heard again: no longer lost, nor in the air
        clock[0] = 107.0
        links[2].feed(_hb(True))
        d._update_phase(v2)
        assert not v2.lost and v2.last_heard is None
    finally:
        d.store.close()


def test_partial_results_name_each_vehicle_once(tmp_path):
    """Issue 42 item 4: a stopped search said "vehicle 1: airborne, returning home (RTL acknowledged)"
    and then "Vehicle(s) 1, 2, 3 not confirmed returning home". The statement of a stopped search
    leaves the fleet to the stop report, which says each vehicle once."""
    text = statement_for([_p(1, True)], 15, [], [1, 2, 3], fleet=False)
    assert "Vehicle" not in text and "home" not in text
