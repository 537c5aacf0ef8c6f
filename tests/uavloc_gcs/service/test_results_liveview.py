"""Result files (CSV, GeoJSON, KML, PNG, table) and the live view in both output modes."""

import csv
import io
import json
import math

import numpy as np
from lxml import etree

from uavloc_gcs.geo import LocalFrame
from uavloc_gcs.service.liveview import LiveView, PersonStatusView, StatusSnapshot, VehicleStatus
from uavloc_gcs.service.results import (PersonResult, people_csv, people_geojson, people_kml,
                                        results_table, write_results)

FRAME = LocalFrame(42.625, 13.283)


def _person(eid, e, n, r, located=True, reason=""):
    lat, lon = FRAME.to_wgs84(e, n)
    return PersonResult(eid, float(lat), float(lon), e, n, 0.5, -0.2, r, 2 * r, 60.0, located, True, reason, 58.5)


PEOPLE = [_person(2, 100.0, 50.0, 8.0), _person(1, 300.0, 200.0, 30.0, False, "heard from one leg only"),
          PersonResult(3, math.nan, math.nan, math.nan, math.nan, math.nan, math.nan, math.nan, math.nan,
                       math.nan, False, False, "never heard")]


def test_csv_is_sorted_and_complete():
    rows = list(csv.DictReader(io.StringIO(people_csv(PEOPLE))))
    assert [r["emitter_id"] for r in rows] == ["1", "2", "3"]
    assert rows[1]["located"] == "1" and float(rows[1]["radius95_m"]) == 8.0
    assert rows[2]["lat_deg"] == "" and rows[2]["reason"] == "never heard"
    assert rows[1]["t_ref_s"] == "58.50" and rows[2]["t_ref_s"] == ""  # the time the position is for
    lat, lon = FRAME.to_wgs84(100.0, 50.0)
    assert abs(float(rows[1]["lat_deg"]) - lat) < 1e-7 and abs(float(rows[1]["lon_deg"]) - lon) < 1e-7


def test_geojson_has_estimates_and_truth():
    gj = json.loads(people_geojson(PEOPLE, {1: (42.63, 13.29)}))
    kinds = [(f["properties"]["kind"], f["properties"]["emitter_id"]) for f in gj["features"]]
    assert kinds == [("estimate", 1), ("estimate", 2), ("truth", 1)]
    assert gj["features"][2]["geometry"]["coordinates"] == [13.29, 42.63]  # GeoJSON is lon, lat


def test_kml_is_valid_xml_with_circles():
    root = etree.fromstring(people_kml(PEOPLE, FRAME).encode())
    ns = {"k": "http://www.opengis.net/kml/2.2"}
    assert len(root.findall(".//k:Placemark", ns)) == 4  # two people x (point + circle)
    ring = root.find(".//k:LinearRing/k:coordinates", ns).text.split()
    lon, lat, _ = map(float, ring[0].split(","))
    e, n = FRAME.to_local(lat, lon)
    assert abs(math.hypot(e - 300.0, n - 200.0) - 30.0) < 0.01


def test_table_reports_truth_error_and_who_is_not_located():
    text = results_table(PEOPLE, 15.0, {1: (303.0, 204.0), 2: (100.0, 50.0), 3: (0.0, 0.0)})
    assert "5.0 m" in text and "heard from one leg only" in text
    assert "1 of 3 people located within 15 m" in text


def test_write_results_makes_every_file(tmp_path):
    area = FRAME.to_wgs84_latlon(np.array([[0, 0], [500, 0], [500, 300], [0, 300]], float))
    tracks = {1: FRAME.to_wgs84_latlon(np.array([[0, 0], [400, 100], [0, 200]], float))}
    files = write_results(tmp_path, PEOPLE, frame=FRAME, area_latlon_deg=area, tracks_latlon_deg=tracks,
                          required_accuracy_m=15.0, truth_xy_m={1: (303.0, 204.0)}, name="t")
    assert sorted(p.name for p in files) == ["people.csv", "people.geojson", "people.kml", "result.png",
                                             "results.txt"]
    assert (tmp_path / "result.png").read_bytes()[:4] == b"\x89PNG"


SNAP = StatusSnapshot(12.5, [VehicleStatus(1, "scanning", "AUTO", 88.0, 4, 20), VehicleStatus(2, "lost", lost=True)],
                      [PersonStatusView(1, 7.0, True), PersonStatusView(2, math.nan, False)], 1234, 15.0)


def test_log_mode_prints_one_line_per_period():
    now = [0.0]
    out = io.StringIO()
    view = LiveView(out, tty=False, period_s=5.0, clock=lambda: now[0])
    for t in np.arange(0, 12, 0.5):
        now[0] = t
        view.update(SNAP)
    lines = out.getvalue().splitlines()
    assert len(lines) == 3 and "\x1b" not in out.getvalue()
    assert "located=1/2" in lines[0] and "UAV2" in lines[0] and "LOST" in lines[0]


def test_terminal_mode_redraws_in_place():
    out = io.StringIO()
    now = [0.0]
    view = LiveView(out, tty=True, clock=lambda: now[0])
    view.update(SNAP)
    now[0] = 1.0
    view.update(SNAP)
    text = out.getvalue()
    n = text.split("\x1b[J", 2)[1].count("\n")
    assert f"\x1b[{n}F\x1b[J" in text  # the second draw moves up exactly over the first
    assert "UAV1 AUTO" in text and "item 4/20" in text
