"""Area polygons from GeoJSON and .plan geofences, and scenarios that use them."""

import json

import pytest

from mission_io.area import loads_area_polygon, read_area_polygon
from uavloc_gcs.errors import ConfigError, FileFormatError
from uavloc_gcs.scenario import load_scenario

RING_LONLAT = [[13.283, 42.625], [13.294, 42.625], [13.294, 42.634], [13.283, 42.634], [13.283, 42.625]]
EXPECTED = [[42.625, 13.283], [42.625, 13.294], [42.634, 13.294], [42.634, 13.283]]
POLY = {"type": "Polygon", "coordinates": [RING_LONLAT]}


@pytest.mark.parametrize(
    "doc",
    [
        POLY,
        {"type": "MultiPolygon", "coordinates": [[RING_LONLAT], [[[0, 0], [1, 0], [1, 1], [0, 0]]]]},
        {"type": "Feature", "properties": {}, "geometry": POLY},
        {"type": "FeatureCollection", "features": [
            {"type": "Feature", "properties": {}, "geometry": {"type": "Point", "coordinates": [13.2, 42.6]}},
            {"type": "Feature", "properties": {}, "geometry": POLY},
        ]},
    ],
    ids=["Polygon", "MultiPolygon", "Feature", "FeatureCollection"],
)
def test_geojson_variants_give_lat_lon_ring(doc):
    assert loads_area_polygon(json.dumps(doc)) == EXPECTED


def test_plan_geofence_inclusion_polygon():
    plan = {
        "fileType": "Plan", "version": 1, "groundStation": "QGroundControl", "mission": {},
        "geoFence": {"circles": [], "version": 2, "polygons": [
            {"inclusion": False, "polygon": [[1, 1], [1, 2], [2, 2]], "version": 1},
            {"inclusion": True, "polygon": EXPECTED, "version": 1},
        ]},
        "rallyPoints": {"points": [], "version": 2},
    }
    assert loads_area_polygon(json.dumps(plan)) == EXPECTED


@pytest.mark.parametrize(
    "text, field, fragment",
    [
        ("{not json", None, "not valid JSON"),
        ("[1, 2]", None, "JSON object"),
        ('{"foo": 1}', "type", "neither a GeoJSON"),
        ('{"type": "Point", "coordinates": [1, 2]}', "type", "'Point'"),
        ('{"type": "Polygon", "coordinates": []}', "coordinates", "non-empty"),
        ('{"type": "Polygon", "coordinates": [[[13, 42], [13, "x"], [14, 43], [13, 42]]]}',
         "coordinates[0]", "position 1"),
        ('{"type": "Polygon", "coordinates": [[[13, 42], [13, 95], [14, 43], [13, 42]]]}',
         "coordinates[0]", "not a valid [lon, lat]"),
        ('{"type": "Polygon", "coordinates": [[[13, 42], [14, 43], [13, 42]]]}', "coordinates[0]", "at least 3"),
        ('{"type": "Feature", "geometry": null}', "geometry", "missing"),
        ('{"type": "FeatureCollection", "features": []}', "features", "no feature"),
        ('{"fileType": "Plan", "geoFence": {"polygons": []}}', "geoFence.polygons", "no inclusion"),
        ('{"fileType": "Plan"}', "geoFence", "missing"),
        ('{"fileType": "Plan", "geoFence": {"polygons": [{"inclusion": true, "polygon": 5}]}}',
         "geoFence.polygons[0].polygon", "list of positions"),
    ],
)
def test_malformed_area_names_file_and_field(text, field, fragment):
    with pytest.raises(FileFormatError) as ei:
        loads_area_polygon(text, path="area.geojson")
    msg = str(ei.value)
    assert msg.startswith("area.geojson")
    assert fragment in msg
    if field:
        assert ei.value.field == field


def test_missing_file(tmp_path):
    with pytest.raises(FileFormatError, match="not found"):
        read_area_polygon(tmp_path / "nope.geojson")


def test_scenario_with_polygon_file_loads(tmp_path):
    (tmp_path / "area.geojson").write_text(json.dumps({"type": "Feature", "geometry": POLY, "properties": {}}))
    (tmp_path / "s.toml").write_text('[area]\npolygon_file = "area.geojson"\n[fleet]\nvehicles = 2\n')
    sc = load_scenario(tmp_path / "s.toml")
    assert [list(v) for v in sc.polygon_latlon_deg] == EXPECTED
    assert sc.launch_latlon_deg == (42.625, 13.283)


def test_scenario_with_bad_polygon_file_names_the_key(tmp_path):
    (tmp_path / "area.geojson").write_text('{"type": "Point", "coordinates": [1, 2]}')
    (tmp_path / "s.toml").write_text('[area]\npolygon_file = "area.geojson"\n')
    with pytest.raises(ConfigError) as ei:
        load_scenario(tmp_path / "s.toml")
    assert "area.polygon_file" in str(ei.value) and "area.geojson" in str(ei.value)
