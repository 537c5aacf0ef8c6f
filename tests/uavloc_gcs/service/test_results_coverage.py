"""The coverage claims in the operator's files and statement: the POD per cell and overall, the
unsearched area and where, the expected people missed; "nothing flew" said as such."""

import csv
import io
import json
import math

import numpy as np
import pytest

from tests.e2e_helpers import small_scenario
from uavloc_gcs.search.coverage import Coverage
from uavloc_gcs.service.outcome import coverage_statement, statement_for
from uavloc_gcs.service.results import (PersonResult, people_csv, people_geojson, people_kml, results_table,
                                        write_results)


def _half_flown(density=None):
    """A lane along the south edge only: the north of the area is unsearched."""
    sc = small_scenario()
    if density is not None:
        sc = sc.replace(people={"density_per_km2": density})
    cov = Coverage(sc)
    xs = np.linspace(-20.0, 420.0, 60)
    cov.add_track(1, xs / 15.0, np.column_stack([xs, np.full(60, 10.0), np.full(60, 60.0)]))
    return sc, cov.summary()


def _person(sc, s, e, n):
    lat, lon = sc.frame.to_wgs84(e, n)
    return PersonResult(7, float(lat), float(lon), e, n, 0.0, 0.0, 9.0, math.nan, 12.0, True, True, "",
                        label="P01", pod_here=s.pod_at((e, n)))


def test_summary_says_where_the_area_was_not_searched_and_whom_it_may_have_missed():
    sc, s = _half_flown(density=40.0)
    assert 0 < s.unsearched_m2 < s.area_m2 and s.below_target_m2 >= s.unsearched_m2
    north = s.grid.xy_m[:, 1] > 10.0 + sc.horizontal_range_m + s.grid.cell_m
    assert np.all(s.pod1[north] == 0.0)
    assert s.expected_missed == pytest.approx(40.0 * np.sum(1 - s.pod1) * s.grid.cell_area_m2 / 1e6)
    text = s.sentence()
    assert f"{s.overall1:.2f} over the area" in text and "Unsearched" in text and "north" in text
    assert "Expected people missed at 40 per km²" in text


def test_no_phone_heard_is_said_with_the_pod_or_as_nothing_flown():
    sc, s = _half_flown()
    text = statement_for([], 15.0, [], [], coverage=s)
    assert text.startswith("No phone was heard where the vehicles flew (achieved POD")
    empty = Coverage(sc).summary()
    assert statement_for([], 15.0, [], [], coverage=empty).startswith(
        "No phone was heard: nothing flew over the search area at survey altitude.")
    assert "anywhere in the search area" not in statement_for([], 15.0, [], [])
    # a vehicle lost with part of the area unsearched: said, and the flag behind exit code 4
    said, left = coverage_statement(s, lost=[2])
    assert left and "was not searched: vehicle(s) 2" in said
    assert coverage_statement(s, lost=[])[1] is False


def test_files_carry_the_pod_per_cell_and_overall(tmp_path):
    sc, s = _half_flown(density=40.0)
    south, north = _person(sc, s, 200.0, 20.0), _person(sc, s, 200.0, 240.0)
    assert south.pod_here == 1.0 and north.pod_here == 0.0
    rows = list(csv.DictReader(io.StringIO(people_csv([south]))))
    assert rows[0]["pod_here"] == "1.000"
    gj = json.loads(people_geojson([south], frame=sc.frame, coverage=s))
    cells = [f for f in gj["features"] if f["properties"]["kind"] == "pod_cell"]
    assert len(cells) == len(s.pod1)
    assert sum(c["properties"]["unsearched"] for c in cells) * s.grid.cell_area_m2 == pytest.approx(s.unsearched_m2)
    est = [f for f in gj["features"] if f["properties"]["kind"] == "estimate"]
    assert est[0]["properties"]["pod_here"] == 1.0
    assert gj["coverage"]["pod_overall"] == pytest.approx(s.overall1, abs=1e-4)
    assert gj["coverage"]["expected_missed"] == pytest.approx(s.expected_missed, abs=1e-3)
    kml = people_kml([south], sc.frame, coverage=s)
    assert "<name>achieved POD</name>" in kml and kml.count("<Data name=\"pod\">") == len(s.pod1)
    assert s.sentence() in results_table([south], 15.0, coverage=s)
    files = write_results(tmp_path, [south, north], frame=sc.frame, area_latlon_deg=np.array(sc.polygon_latlon_deg),
                          tracks_latlon_deg={}, required_accuracy_m=15.0, coverage=s)
    assert (tmp_path / "result.png") in files and (tmp_path / "result.png").read_bytes()[:4] == b"\x89PNG"
