"""Local metric frame about a search area, through pyproj.

East/north metres (ENU, z up) in an azimuthal equidistant projection centred on the origin.
All conversions between WGS84 and the local frame go through :class:`LocalFrame`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pyproj import CRS, Transformer

from .errors import ConfigError


@dataclass(frozen=True)
class LocalFrame:
    """A local east/north frame in metres centred on (``lat0_deg``, ``lon0_deg``)."""

    lat0_deg: float
    lon0_deg: float
    _fwd: Transformer = field(init=False, repr=False, compare=False)
    _inv: Transformer = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not (-90.0 < self.lat0_deg < 90.0) or not np.isfinite(self.lat0_deg):
            raise ConfigError(f"origin latitude {self.lat0_deg} is not between -90 and 90 degrees")
        if not (-180.0 <= self.lon0_deg <= 180.0) or not np.isfinite(self.lon0_deg):
            raise ConfigError(f"origin longitude {self.lon0_deg} is not between -180 and 180 degrees")
        local = CRS.from_proj4(
            f"+proj=aeqd +lat_0={self.lat0_deg!r} +lon_0={self.lon0_deg!r} +x_0=0 +y_0=0 "
            "+ellps=WGS84 +units=m +no_defs"
        )
        wgs84 = CRS.from_epsg(4326)
        object.__setattr__(self, "_fwd", Transformer.from_crs(wgs84, local, always_xy=True))
        object.__setattr__(self, "_inv", Transformer.from_crs(local, wgs84, always_xy=True))

    def to_local(self, lat_deg, lon_deg):
        """WGS84 degrees -> (east_m, north_m). Accepts scalars or arrays."""
        e, n = self._fwd.transform(lon_deg, lat_deg)
        return e, n

    def to_wgs84(self, east_m, north_m):
        """(east_m, north_m) -> (lat_deg, lon_deg). Accepts scalars or arrays."""
        lon, lat = self._inv.transform(east_m, north_m)
        return lat, lon

    def to_local_xy(self, latlon_deg: np.ndarray) -> np.ndarray:
        """(N, 2) array of [lat, lon] -> (N, 2) array of [east, north] metres."""
        a = np.asarray(latlon_deg, dtype=float).reshape(-1, 2)
        e, n = self.to_local(a[:, 0], a[:, 1])
        return np.column_stack([e, n])

    def to_wgs84_latlon(self, xy_m: np.ndarray) -> np.ndarray:
        """(N, 2) array of [east, north] metres -> (N, 2) array of [lat, lon] degrees."""
        a = np.asarray(xy_m, dtype=float).reshape(-1, 2)
        lat, lon = self.to_wgs84(a[:, 0], a[:, 1])
        return np.column_stack([lat, lon])


def polygon_area_m2(xy_m) -> float:
    """Area [m²] of a simple polygon given as (K, 2) vertices in metres (shoelace; either order)."""
    xy = np.asarray(xy_m, dtype=float).reshape(-1, 2)
    x, y = xy[:, 0], xy[:, 1]
    return float(abs(0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)))
