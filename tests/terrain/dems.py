"""DEM files the terrain tests make: planes, ridges and SRTM tiles, written with rasterio."""

from __future__ import annotations

from pathlib import Path

import numpy as np

EXAMPLES = Path(__file__).resolve().parents[2] / "uavloc_gcs" / "examples"
MOUNT_WASHINGTON = EXAMPLES / "mount_washington_srtm3.tif"
SUMMIT_LATLON = (44.2706, -71.3033)  # Mount Washington, 1917 m (USGS); SRTM3's cell there: 1908 m


def write_geotiff(path: Path, heights: np.ndarray, *, west: float, north: float, cell_x: float, cell_y: float,
                  crs: str = "EPSG:4326", nodata=None) -> Path:
    import rasterio
    from affine import Affine

    prof = dict(driver="GTiff", height=heights.shape[0], width=heights.shape[1], count=1,
                dtype=str(heights.dtype), crs=crs, transform=Affine(cell_x, 0.0, west, 0.0, -cell_y, north))
    if nodata is not None:
        prof["nodata"] = nodata
    with rasterio.open(path, "w", **prof) as ds:
        ds.write(heights, 1)
    return path


def ridge_dem(path: Path, frame, *, base_m: float = 500.0, ridge_m: float = 300.0, ridge_x_m: float = 400.0,
              half_width_m: float = 120.0, extent_m: float = 2000.0, cell_m: float = 30.0) -> Path:
    """A UTM GeoTIFF around ``frame``'s origin: flat at ``base_m`` with a north-south ridge
    ``ridge_m`` high (a triangle ``half_width_m`` wide each side) at east ``ridge_x_m``."""
    from pyproj import CRS, Transformer

    zone = int((frame.lon0_deg + 180) // 6) + 1
    epsg = (32600 if frame.lat0_deg >= 0 else 32700) + zone
    tr = Transformer.from_crs(CRS.from_epsg(4326), CRS.from_epsg(epsg), always_xy=True)
    e0, n0 = tr.transform(frame.lon0_deg, frame.lat0_deg)
    n = int(2 * extent_m / cell_m)
    west, north = e0 - extent_m, n0 + extent_m
    xs = west + (np.arange(n) + 0.5) * cell_m - e0  # approximately the local east of each column
    z = base_m + ridge_m * np.clip(1.0 - np.abs(xs - ridge_x_m) / half_width_m, 0.0, None)
    heights = np.tile(z.astype(np.float32), (n, 1))
    return write_geotiff(path, heights, west=west, north=north, cell_x=cell_m, cell_y=cell_m, crs=f"EPSG:{epsg}")
