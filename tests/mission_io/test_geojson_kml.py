"""GeoJSON and KML export of the scan plan."""

import json
from pathlib import Path

import numpy as np
import pytest
from lxml import etree

from mission_io import geojson, kml
from uavloc_gcs import scan
from uavloc_gcs.errors import FileFormatError
from uavloc_gcs.scenario import load_scenario

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
KML = "{http://www.opengis.net/kml/2.2}"


@pytest.fixture(scope="module")
def polygon_plan():
    sc = load_scenario(EXAMPLES / "polygon.toml")
    return sc, scan.plan_scan(sc)


def test_builders_write_lon_lat_and_close_rings_ccw():
    assert geojson.point(47.5, 8.25)["coordinates"] == [8.25, 47.5]
    poly = geojson.polygon([(47.0, 8.0), (48.0, 8.0), (48.0, 9.0)])  # clockwise in lon/lat
    ring = np.array(poly["coordinates"][0])
    assert ring[0].tolist() == ring[-1].tolist() and len(ring) == 4
    signed = np.sum(ring[:-1, 0] * ring[1:, 1] - ring[1:, 0] * ring[:-1, 1])
    assert signed > 0  # counter-clockwise (RFC 7946 right-hand rule)
    with pytest.raises(ValueError):
        geojson.point(float("nan"), 8.0)


def test_scan_feature_collection_matches_the_plan(polygon_plan, tmp_path):
    sc, plan = polygon_plan
    fc = geojson.scan_feature_collection(sc, plan)
    path = geojson.write(tmp_path / "scan.geojson", fc)
    back = geojson.read(path)
    assert back == json.loads(geojson.dumps(fc))
    by_kind = {}
    for f in back["features"]:
        by_kind.setdefault(f["properties"]["kind"], []).append(f)
    assert len(by_kind["route"]) == len(plan.vehicles) == len(by_kind["lanes"])
    for f, v in zip(by_kind["route"], plan.vehicles):
        assert f["properties"]["length_m"] == pytest.approx(v.length_m, abs=1e-3)
        lonlat = np.array(f["geometry"]["coordinates"])
        xy = sc.frame.to_local_xy(lonlat[:, ::-1])
        assert np.allclose(xy, v.route_xy_m(), atol=1e-6)
        assert f["properties"]["stroke"].startswith("#")
    lanes = sum(len(f["geometry"]["coordinates"]) for f in by_kind["lanes"])
    assert lanes == sum(len(v.lanes_xy_m) for v in plan.vehicles)
    area = by_kind["area"][0]["geometry"]["coordinates"][0]
    assert len(area) == len(sc.polygon_latlon_deg) + 1


def test_geojson_read_errors(tmp_path):
    (tmp_path / "a.geojson").write_text('{"type": "Nonsense"}')
    with pytest.raises(FileFormatError, match="a.geojson.*not a GeoJSON object"):
        geojson.read(tmp_path / "a.geojson")
    with pytest.raises(FileFormatError, match="not valid JSON"):
        geojson.loads("{", path="b.geojson")


def test_kml_is_valid_xml_with_a_folder_per_vehicle(polygon_plan, tmp_path):
    sc, plan = polygon_plan
    fc = geojson.scan_feature_collection(sc, plan)
    path = kml.write(tmp_path / "scan.kml", kml.from_feature_collection(fc))
    root = etree.parse(str(path)).getroot()
    assert root.tag == f"{KML}kml"
    folders = root.findall(f"{KML}Document/{KML}Folder")
    assert [f.findtext(f"{KML}name") for f in folders] == [f"uav{v.index + 1}" for v in plan.vehicles]
    # Routes fly at the scan altitude above ground; the area is clamped to the ground.
    route = next(pm for pm in root.iter(f"{KML}Placemark") if pm.findtext(f"{KML}name") == "uav1 route")
    line = route.find(f"{KML}LineString")
    assert line.findtext(f"{KML}altitudeMode") == "relativeToGround"
    first = line.findtext(f"{KML}coordinates").split()[0].split(",")
    assert [float(c) for c in first] == [sc.launch_latlon_deg[1], sc.launch_latlon_deg[0], sc.fleet.altitude_m]
    styles = {s.get("id") for s in root.iter(f"{KML}Style")}
    assert all(pm.findtext(f"{KML}styleUrl")[1:] in styles for pm in root.iter(f"{KML}Placemark"))
    assert kml.dumps(kml.from_feature_collection(fc)) == path.read_text()  # deterministic


def test_kml_colour_is_aabbggrr():
    assert kml._kml_color("#0072B2", 0.5) == "80b27200"
    with pytest.raises(ValueError):
        kml._kml_color("blue")
