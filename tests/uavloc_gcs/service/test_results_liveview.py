"""Result files (CSV, GeoJSON, KML, PNG, table) and the live view in both output modes."""

import csv
import io
import json
import math
from dataclasses import replace

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
    assert "Located by 15 / 30 / 60 min of mission time: 1 / 1 / 1 of 3." in text  # fixed at 60 s
    late = [PEOPLE[0], replace(PEOPLE[0], emitter_id=4, fix_time_s=1900.0), PEOPLE[1]]
    assert "Located by 15 / 30 / 60 min of mission time: 1 / 1 / 2 of 3." in results_table(late, 15.0)
    assert "Located by" not in results_table(PEOPLE[1:], 15.0)  # nobody located: the line above says it


def test_write_results_makes_every_file(tmp_path):
    area = FRAME.to_wgs84_latlon(np.array([[0, 0], [500, 0], [500, 300], [0, 300]], float))
    tracks = {1: FRAME.to_wgs84_latlon(np.array([[0, 0], [400, 100], [0, 200]], float))}
    files = write_results(tmp_path, PEOPLE, frame=FRAME, area_latlon_deg=area, tracks_latlon_deg=tracks,
                          required_accuracy_m=15.0, truth_xy_m={1: (303.0, 204.0)}, name="t")
    assert sorted(p.name for p in files) == ["people.csv", "people.geojson", "people.kml", "result.png",
                                             "results.txt"]
    assert (tmp_path / "result.png").read_bytes()[:4] == b"\x89PNG"
    assert "Sorties" not in (tmp_path / "results.txt").read_text()


def test_results_txt_ends_with_the_sorties_flown_when_given(tmp_path):
    note = "Sorties flown (packs left): vehicle 1 2 (1 left)."
    write_results(tmp_path, PEOPLE, frame=FRAME, area_latlon_deg=FRAME.to_wgs84_latlon(np.array(
        [[0, 0], [500, 0], [500, 300]], float)), tracks_latlon_deg={}, required_accuracy_m=15.0, name="t", notes=(note,))
    assert (tmp_path / "results.txt").read_text().rstrip().splitlines()[-1] == note


def test_result_png_says_what_results_txt_says_under_its_table(tmp_path, monkeypatch):
    """The people located by time and the sorties flown are in the picture's caption too (issue 38
    item 4: the statement, results.txt, the live map and result.png say them)."""
    import uavloc_gcs.render.estimates as estimates

    said = {}
    real = estimates.result_figure

    def spy(people, **kw):
        said["caption"] = kw.get("subtitle") or ""
        return real(people, **kw)

    monkeypatch.setattr(estimates, "result_figure", spy)
    note = "Sorties flown (packs left): vehicle 1 2 (1 left)."
    write_results(tmp_path, PEOPLE, frame=FRAME, area_latlon_deg=FRAME.to_wgs84_latlon(np.array(
        [[0, 0], [500, 0], [500, 300]], float)), tracks_latlon_deg={}, required_accuracy_m=15.0, name="t", notes=(note,))
    text = (tmp_path / "results.txt").read_text()
    for line in ("Located by 15 / 30 / 60 min of mission time: 1 / 1 / 1 of 3.", note):
        assert line in text and line in said["caption"]


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


EPOCH = 1_795_000_000.0  # 2026-11-18T11:06:40Z


def _labelled():
    import dataclasses

    return [dataclasses.replace(p, label=lab) for p, lab in zip(PEOPLE, ("P02", "P01", "P03"))]


def test_every_file_carries_utc_time_mission_seconds_label_and_state():
    people = _labelled()
    rows = list(csv.DictReader(io.StringIO(people_csv(people, EPOCH))))
    assert [r["label"] for r in rows] == ["P01", "P02", "P03"]  # the labels' order, not the ids'
    assert rows[0]["emitter_id"] == "1" and rows[0]["state"] == "heard"
    assert rows[1]["state"] == "located" and rows[2]["state"] == "never heard"
    assert rows[1]["time_utc"] == "2026-11-18T11:07:38.5Z" and rows[1]["t_ref_s"] == "58.50"
    assert rows[1]["fix_time_utc"] == "2026-11-18T11:07:40.0Z"
    assert float(rows[1]["speed_m_s"]) == round(math.hypot(0.5, -0.2), 3)
    assert rows[2]["time_utc"] == ""  # never heard: no time, no position
    gj = json.loads(people_geojson(people, epoch_unix_s=EPOCH, frame=FRAME))
    points = [f for f in gj["features"] if f["properties"]["kind"] == "estimate"]
    assert [f["properties"]["name"] for f in points] == ["P01 #1", "P02 #2"]
    assert points[1]["properties"]["time_utc"] == "2026-11-18T11:07:38.5Z"
    assert points[1]["properties"]["state"] == "located" and points[1]["properties"]["radius95_m"] == 8.0
    circles = [f for f in gj["features"] if f["properties"]["kind"] == "circle95"]
    assert len(circles) == 2 and circles[0]["geometry"]["type"] == "Polygon"


def test_kml_uses_timestamps_for_the_time_slider():
    root = etree.fromstring(people_kml(_labelled(), FRAME, epoch_unix_s=EPOCH).encode())
    ns = {"k": "http://www.opengis.net/kml/2.2"}
    marks = root.findall(".//k:Placemark", ns)
    assert [m.find("k:name", ns).text for m in marks] == ["P01 #1", "P01 #1 95 %", "P02 #2", "P02 #2 95 %"]
    whens = [m.find("k:TimeStamp/k:when", ns).text for m in marks]
    assert whens == ["2026-11-18T11:07:38.5Z"] * 4
    data = {d.get("name"): d.find("k:value", ns).text for d in marks[2].findall(".//k:Data", ns)}
    assert data["state"] == "located" and data["t_ref_s"] == "58.5" and data["vel_east_m_s"] == "0.5"
    assert marks[0].find("k:styleUrl", ns).text == "#heard"


def test_table_names_people_by_label_and_id_with_the_time():
    text = results_table(_labelled(), 15.0, epoch_unix_s=EPOCH)
    lines = text.splitlines()
    assert lines[2].startswith("P01 #1 ") and lines[3].startswith("P02 #2 ") and lines[4].startswith("P03 #3 ")
    assert "11:07:38.5" in lines[3] and "located" in lines[3]


def test_terminal_view_shows_labels():
    from uavloc_gcs.service.labels import PersonLabels
    from uavloc_gcs.service.liveview import render_lines

    labels = PersonLabels()
    labels.add([2, 1])
    text = "\n".join(render_lines(SNAP, labels))
    assert "P01 #2" in text and "P02 #1" in text
    assert text.index("P01 #2") < text.index("P02 #1")


def test_person_view_shows_the_other_mirror_candidate_while_ambiguous():
    from types import SimpleNamespace as NS

    from uavloc_gcs.service.liveview import person_view

    est = NS(ambiguous=True, position_xy_m=np.array([100.0, 50.0]),
             mirror=NS(position_xy_m=np.array([100.0, -50.0]), radius95_m=12.0))
    status = dict(emitter_id=7, estimate=est, located=False, reason="mirror ambiguity", t_ref_s=30.0,
                  radius95_m=11.0, velocity_m_s=(0.5, 0.0))
    believes_primary = person_view(NS(xy_m=(100.0, 50.0), **status))
    assert believes_primary.ambiguous and (believes_primary.mirror_east_m, believes_primary.mirror_north_m) == (100.0, -50.0)
    believes_mirror = person_view(NS(xy_m=(100.0, -50.0), **status))
    assert (believes_mirror.east_m, believes_mirror.north_m) == (100.0, -50.0)
    assert (believes_mirror.mirror_east_m, believes_mirror.mirror_north_m) == (100.0, 50.0)
    located = person_view(NS(xy_m=(100.0, 50.0), **{**status, "located": True}))
    assert not located.ambiguous and math.isnan(located.mirror_east_m)  # a fix has one position


def test_terminal_view_gives_the_latitude_and_longitude_of_every_located_person():
    """Issue 29: no lat/lon anywhere in the live people table; a team walks to coordinates."""
    from uavloc_gcs.service.liveview import render_lines

    snap = StatusSnapshot(60.0, [VehicleStatus(1, "scanning", "AUTO", 80.0)],
                          [PersonStatusView(1, 7.0, True, east_m=100.0, north_m=50.0),
                           PersonStatusView(2, 40.0, False, east_m=300.0, north_m=10.0)], 99, 15.0)
    text = "\n".join(render_lines(snap, None, FRAME))
    lat, lon = FRAME.to_wgs84(100.0, 50.0)
    assert f"{float(lat):.6f}, {float(lon):.6f}" in text
    lat2, lon2 = FRAME.to_wgs84(300.0, 10.0)
    assert f"{float(lat2):.6f}" not in text  # not located: no coordinates to walk to
    assert f"{float(lat):.6f}" not in "\n".join(render_lines(snap))  # without a frame, as before


def test_every_output_says_the_same_people_states_and_radii(tmp_path):
    """One truth (issue 40 item 3): the table, the CSV, the GeoJSON, the KML and the statement name
    the same people with the same states and 95 % radii, and count them alike."""
    import re

    from uavloc_gcs.service.outcome import statement_for

    people = [replace(p, label=f"P{i + 1:02d}") for i, p in enumerate(PEOPLE)]
    area = FRAME.to_wgs84_latlon(np.array([[0, 0], [500, 0], [500, 300], [0, 300]], float))
    write_results(tmp_path, people, frame=FRAME, area_latlon_deg=area, tracks_latlon_deg={},
                  required_accuracy_m=15.0, truth_xy_m={1: (303.0, 204.0), 2: (100.0, 50.0), 3: (0.0, 0.0)}, name="t")
    table = (tmp_path / "results.txt").read_text()
    rows = {m.group(1): (m.group(3), m.group(2)) for m in
            re.finditer(r"^(P\d\d) #\S+\s+(?:\S+\s+\S+\s+)?([\d.]+ m|-)\s+\S+\s+(located|given up|heard|never heard)",
                         table, re.M)}
    csv_rows = {r["label"]: (r["state"], f"{float(r['radius95_m']):.1f} m" if r["radius95_m"] else "-")
                for r in csv.DictReader((tmp_path / "people.csv").open())}
    gj = json.loads((tmp_path / "people.geojson").read_text())
    gj_rows = {f["properties"]["label"]: (f["properties"]["state"], f"{f['properties']['radius95_m']:.1f} m")
               for f in gj["features"] if f["properties"]["kind"] == "estimate"}
    assert rows == csv_rows and len(rows) == 3
    assert gj_rows == {k: v for k, v in rows.items() if v[1] != "-"}  # who has a position has a feature
    kml = (tmp_path / "people.kml").read_text()
    assert all(k in kml for k, v in rows.items() if v[1] != "-")
    heard = [p for p in people if p.state != "never heard"]
    n_ok = sum(v[0] == "located" for v in rows.values())
    statement = statement_for(heard, 15.0, (), (), ())
    assert statement.startswith(f"{n_ok} of {len(heard)} people heard located within 15 m")
    assert f"{n_ok} of {len(rows)} people located within 15 m (95 %); {len(heard)} heard, 1 never heard." in table
    assert all(p.label in statement for p in heard if p.state != "located")
