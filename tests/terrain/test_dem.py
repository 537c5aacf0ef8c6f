"""The DEM: reading GeoTIFF, SRTM .hgt and DTED, bilinear sampling, the scenario key and its errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from uavloc_gcs.errors import ConfigError
from uavloc_gcs.geo import LocalFrame
from uavloc_gcs.scenario import loads_scenario
from uavloc_gcs.terrain import FLAT_GROUND, describe, load_dem

from .dems import MOUNT_WASHINGTON, SUMMIT_LATLON, ridge_dem, write_geotiff

AREA = """
[area]
origin_lat_deg = {lat}
origin_lon_deg = {lon}
width_m = 600
height_m = 400
"""


def test_bilinear_sampling_reproduces_a_plane_exactly_in_a_projected_dem(tmp_path):
    # A tilted plane in UTM 33N about Amatrice: bilinear interpolation of a plane is the plane.
    frame = LocalFrame(42.63, 13.29)
    from pyproj import Transformer
    e0, n0 = Transformer.from_crs("EPSG:4326", "EPSG:32633", always_xy=True).transform(13.29, 42.63)
    cell = 25.0
    rows, cols = 80, 80
    west, north = e0 - 1000.0, n0 + 1000.0
    ce = west + (np.arange(cols) + 0.5) * cell
    cn = north - (np.arange(rows) + 0.5) * cell
    E, N = np.meshgrid(ce, cn)
    Z = (800.0 + 0.3 * (E - e0) - 0.1 * (N - n0)).astype(np.float64)
    dem = load_dem(write_geotiff(tmp_path / "plane.tif", Z, west=west, north=north, cell_x=cell, cell_y=cell,
                                 crs="EPSG:32633"), frame)
    assert dem.resolution_m == pytest.approx(25.0)
    rng = np.random.default_rng(3)
    xy = rng.uniform(-700, 700, size=(200, 2))
    Et, Nt = Transformer.from_crs(
        f"+proj=aeqd +lat_0=42.63 +lon_0=13.29 +ellps=WGS84 +units=m", "EPSG:32633", always_xy=True
    ).transform(xy[:, 0], xy[:, 1])
    want = 800.0 + 0.3 * (np.asarray(Et) - e0) - 0.1 * (np.asarray(Nt) - n0)
    assert np.max(np.abs(dem.height_xy(xy) - want)) < 1e-6
    # Outside the cell centres: NaN, or the edge with clamp.
    far = np.array([[5000.0, 0.0]])
    assert math.isnan(dem.height_xy(far)[0])
    assert math.isfinite(dem.height_xy(far, clamp=True)[0])


def test_an_srtm_hgt_tile_is_read_with_its_cells_where_srtm_puts_them(tmp_path):
    # SRTM3 .hgt: 1201 x 1201 big-endian int16, the first cell centred on the tile's NW corner.
    n = 1201
    z = np.zeros((n, n), dtype=">i2")
    r, c = 600, 300  # the cell centred at 45 - 600*3" = 44.5 N, -72 + 300*3" = -71.75
    z[r, c] = 1000
    p = tmp_path / "N44W072.hgt"
    z.tofile(p)
    frame = LocalFrame(44.5, -71.75)
    dem = load_dem(p, frame)
    assert dem.height_at(0.0, 0.0) == pytest.approx(1000.0, abs=1e-6)
    # Half a cell (1.5") east: bilinear halfway between 1000 and 0.
    half_e = frame.to_local(44.5, -71.75 + 1.5 / 3600)[0]
    assert dem.height_at(half_e, 0.0) == pytest.approx(500.0, abs=1.0)
    assert 60.0 < dem.resolution_m < 70.0  # 3 arc-seconds east-west at 44.5 N


def test_a_dted_tile_is_read_through_the_scenario_key(tmp_path):
    """DTED level 0 (30" posts on a 1-degree tile, written by GDAL's DTED driver from a GeoTIFF):
    a west-east plane 1000 m + 200 m per degree of longitude from 71.5 W, read back through
    ``[terrain] dem`` where the plane puts it (DTED stores whole metres)."""
    import rasterio
    import rasterio.shutil
    from affine import Affine

    n = 121
    step = 1.0 / (n - 1)
    lon = -72.0 + step * np.arange(n)
    z = np.tile(np.round(1000.0 + 200.0 * (lon + 71.5)).astype("int16"), (n, 1))
    src = tmp_path / "plane.tif"
    with rasterio.open(src, "w", driver="GTiff", height=n, width=n, count=1, dtype="int16", crs="EPSG:4326",
                       transform=Affine(step, 0.0, -72.0 - step / 2, 0.0, -step, 45.0 + step / 2)) as ds:
        ds.write(z, 1)
    rasterio.shutil.copy(src, tmp_path / "n44.dt0", driver="DTED")
    toml = AREA.format(lat=44.5, lon=-71.75) + '\n[terrain]\ndem = "n44.dt0"\n'
    sc = loads_scenario(toml, source=str(tmp_path / "s.toml"), base_dir=tmp_path)
    assert sc.dem is not None and "n44.dt0" in describe(sc)
    assert sc.dem.height_at(0.0, 0.0) == pytest.approx(950.0, abs=1.0)
    east = sc.frame.to_local(44.5, -71.70)[0]  # 0.05 degree east: 10 m higher
    assert sc.dem.height_at(east, 0.0) == pytest.approx(960.0, abs=1.0)
    assert 600.0 < sc.dem.resolution_m < 700.0  # 30" of longitude at 44.5 N


def test_the_shipped_srtm_crop_puts_mount_washington_summit_at_its_height():
    frame = LocalFrame(*SUMMIT_LATLON)
    dem = load_dem(MOUNT_WASHINGTON, frame)
    h = dem.height_at(0.0, 0.0)
    assert 1880.0 < h <= 1917.0  # USGS 1917 m; SRTM3 smooths the summit a little
    # 2 km west is the Ammonoosuc ravine, 500 m and more below.
    assert dem.height_at(-2000.0, 0.0) < h - 500.0


def test_scenario_key_reads_the_dem_relative_to_the_scenario_file_and_says_so(tmp_path):
    import shutil
    shutil.copy(MOUNT_WASHINGTON, tmp_path / "mw.tif")
    toml = AREA.format(lat=44.262, lon=-71.33) + '\n[terrain]\ndem = "mw.tif"\nmin_clearance_m = 40\n'
    sc = loads_scenario(toml, source=str(tmp_path / "s.toml"), base_dir=tmp_path)
    assert sc.dem is not None and sc.terrain.min_clearance_m == 40.0
    assert "mw.tif" in describe(sc) and "EGM96" in describe(sc)
    flat = loads_scenario(AREA.format(lat=44.262, lon=-71.33))
    assert flat.dem is None and FLAT_GROUND in describe(flat)
    # replace() keeps the DEM (its path was made absolute)
    assert sc.replace(fleet={"vehicles": 2}).dem is not None


@pytest.mark.parametrize("extra, key, words", [
    ('dem = "missing.tif"', "terrain.dem", "not found"),
    ('dem = "notadem.tif"', "terrain.dem", "not a DEM that GDAL can read"),
    ('dem = "mw.tif"\nvertical_datum = "ellipsoid"', "terrain.vertical_datum", "geoid undulation"),
    ('dem = "mw.tif"\nmin_clearance_m = 150', "terrain.min_clearance_m", "more than the scan height"),
    ('dem = "mw.tif"\nmax_climb_m_s = 0', "terrain.max_climb_m_s", "must be positive"),
    ('dem = "mw.tif"\nfollow = true', "terrain.follow", "unknown key"),
])
def test_bad_terrain_keys_and_files_are_one_sentence_naming_the_key(tmp_path, extra, key, words):
    import shutil
    shutil.copy(MOUNT_WASHINGTON, tmp_path / "mw.tif")
    (tmp_path / "notadem.tif").write_text("hello\n")
    toml = AREA.format(lat=44.262, lon=-71.33) + "\n[terrain]\n" + extra + "\n"
    with pytest.raises(ConfigError) as ei:
        loads_scenario(toml, source=str(tmp_path / "s.toml"), base_dir=tmp_path)
    msg = str(ei.value)
    assert key in msg and words in msg and "\n" not in msg


def test_an_area_the_dem_does_not_cover_is_refused_with_the_dem_s_extent(tmp_path):
    import shutil
    shutil.copy(MOUNT_WASHINGTON, tmp_path / "mw.tif")
    toml = AREA.format(lat=44.40, lon=-71.33) + '\n[terrain]\ndem = "mw.tif"\n'
    with pytest.raises(ConfigError, match=r"terrain\.dem.*outside it.*it covers latitude 44\.22"):
        loads_scenario(toml, source=str(tmp_path / "s.toml"), base_dir=tmp_path)


def test_a_dem_without_georeference_is_refused(tmp_path):
    import rasterio
    import warnings
    p = tmp_path / "plain.tif"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with rasterio.open(p, "w", driver="GTiff", height=4, width=4, count=1, dtype="int16") as ds:
            ds.write(np.zeros((4, 4), dtype="int16"), 1)
    toml = AREA.format(lat=44.262, lon=-71.33) + '\n[terrain]\ndem = "plain.tif"\n'
    with pytest.raises(ConfigError, match="no coordinate reference system"):
        loads_scenario(toml, source=str(tmp_path / "s.toml"), base_dir=tmp_path)


def test_the_synthetic_ridge_is_higher_than_the_flight_altitude(tmp_path):
    frame = LocalFrame(42.63, 13.29)
    dem = load_dem(ridge_dem(tmp_path / "ridge.tif", frame), frame)
    assert dem.height_at(0.0, 0.0) == pytest.approx(500.0, abs=1.0)
    assert dem.height_at(400.0, 0.0) - dem.height_at(0.0, 0.0) > 250.0  # above a 100 m scan


def test_a_low_flat_scan_without_a_dem_is_not_refused_for_the_default_clearance():
    sc = loads_scenario(AREA.format(lat=42.63, lon=13.29) + "\n[fleet]\naltitude_m = 20\ncomm_range_m = 100\n")
    assert sc.dem is None and sc.fleet.altitude_m < sc.terrain.min_clearance_m
