"""Terrain: a digital elevation model (DEM) under the search area, sampled in the local frame.

A scenario names its DEM with ``[terrain] dem = "file"`` (GeoTIFF, SRTM ``.hgt`` or DTED, read with
rasterio/GDAL, any CRS pyproj knows). Without one the ground is flat at the launch point's height,
as uavloc always assumed; :func:`describe` says which of the two a scenario uses, in one line.

Heights are sampled bilinearly between the DEM's cell centres. ``resolution_m`` is the DEM's cell
size on the ground, the step at which legs are checked for clearance (``terrain_safe``).

Vertical datum. SRTM heights are orthometric, above the EGM96 geoid (NASA/NGA SRTM documentation);
ArduPilot's absolute mission altitudes and its own terrain database (built from SRTM) are above mean
sea level as the GNSS receiver reports it, and MAVLink's MAV_FRAME_GLOBAL is "above mean sea level"
for PX4 and ArduPilot alike. So an EGM96 or EGM2008 DEM is used as is: no converting library ships
the geoid grids on PyPI (pyproj needs PROJ's network grid ``us_nga_egm96_15.tif``), and the two
geoids differ by about a metre in most places, far less than SRTM's own 16 m (90 %) absolute
height error. A DEM above the WGS84 ellipsoid would be off by the geoid undulation (up to about
100 m) and is refused (``terrain.vertical_datum``). Relative missions (``altitude_frame =
"relative"``) use only height differences, so no datum enters them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import numpy as np

from .errors import ConfigError, InfeasibleError

if TYPE_CHECKING:  # pragma: no cover
    from .geo import LocalFrame

__all__ = ["Terrain", "TerrainSpec", "load_dem", "describe", "check_spec", "FLAT_GROUND"]

FLAT_GROUND = ("no DEM (terrain.dem): the ground is taken as flat at the launch point's height, "
               "so altitudes are above the launch point")


@dataclass(frozen=True)
class Terrain:
    """A DEM tied to a local frame: ``height_xy`` gives the ground's height [m above the geoid]
    at local east/north metres."""

    heights_m: np.ndarray  # (rows, cols), float, NaN where the DEM has no data
    transform: tuple  # affine (a, b, c, d, e, f): x = a col + b row + c, y = d col + e row + f (cell edges)
    crs_wkt: str
    frame: "LocalFrame"
    source: str
    resolution_m: float
    _to_dem: object = field(repr=False, compare=False, default=None)
    _inv: tuple = field(repr=False, compare=False, default=())

    def __post_init__(self) -> None:
        from pyproj import CRS, Transformer

        a, b, c, d, e, f = self.transform
        det = a * e - b * d
        inv = (e / det, -b / det, -d / det, a / det)
        object.__setattr__(self, "_inv", inv)
        local = CRS.from_proj4(f"+proj=aeqd +lat_0={self.frame.lat0_deg!r} +lon_0={self.frame.lon0_deg!r} "
                               "+x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs")
        object.__setattr__(self, "_to_dem", Transformer.from_crs(local, CRS.from_wkt(self.crs_wkt), always_xy=True))

    # -- sampling -----------------------------------------------------------------------------
    def _cells(self, xy_m) -> tuple[np.ndarray, np.ndarray]:
        """Fractional (col, row) of cell-centre coordinates for local points (N, 2)."""
        xy = np.asarray(xy_m, dtype=float).reshape(-1, 2)
        X, Y = self._to_dem.transform(xy[:, 0], xy[:, 1])
        a, b, c, d, e, f = self.transform
        ia, ib, id_, ie = self._inv
        dx, dy = np.asarray(X) - c, np.asarray(Y) - f
        col = ia * dx + ib * dy - 0.5
        row = id_ * dx + ie * dy - 0.5
        return col, row

    def inside(self, xy_m) -> np.ndarray:
        """Whether each local point lies within the DEM's cell centres (where bilinear sampling works)."""
        col, row = self._cells(xy_m)
        rows, cols = self.heights_m.shape
        return (col >= 0) & (row >= 0) & (col <= cols - 1) & (row <= rows - 1)

    def height_xy(self, xy_m, *, clamp: bool = False) -> np.ndarray:
        """Ground height [m] at local points (N, 2), bilinear between cell centres. Outside the DEM:
        NaN, or the nearest edge's height with ``clamp``. Voids stay NaN."""
        col, row = self._cells(xy_m)
        rows, cols = self.heights_m.shape
        out = ~((col >= 0) & (row >= 0) & (col <= cols - 1) & (row <= rows - 1))
        col = np.clip(col, 0.0, cols - 1.0)
        row = np.clip(row, 0.0, rows - 1.0)
        c0 = np.minimum(np.floor(col).astype(int), max(cols - 2, 0))
        r0 = np.minimum(np.floor(row).astype(int), max(rows - 2, 0))
        c1, r1 = np.minimum(c0 + 1, cols - 1), np.minimum(r0 + 1, rows - 1)
        tc, tr = col - c0, row - r0
        h = self.heights_m
        z = ((1 - tr) * ((1 - tc) * h[r0, c0] + tc * h[r0, c1])
             + tr * ((1 - tc) * h[r1, c0] + tc * h[r1, c1]))
        if not clamp:
            z = np.where(out, np.nan, z)
        return z

    def height_at(self, x_m: float, y_m: float, *, clamp: bool = True) -> float:
        return float(self.height_xy(np.array([[x_m, y_m]]), clamp=clamp)[0])

    def bounds_latlon(self) -> tuple[float, float, float, float]:
        """(south, north, west, east) of the DEM's cell centres, in degrees (for messages)."""
        from pyproj import CRS, Transformer

        rows, cols = self.heights_m.shape
        a, b, c, d, e, f = self.transform
        cc = np.array([0.5, cols - 0.5, 0.5, cols - 0.5])
        rr = np.array([0.5, 0.5, rows - 0.5, rows - 0.5])
        X, Y = a * cc + b * rr + c, d * cc + e * rr + f
        tr = Transformer.from_crs(CRS.from_wkt(self.crs_wkt), CRS.from_epsg(4326), always_xy=True)
        lon, lat = tr.transform(X, Y)
        return float(np.min(lat)), float(np.max(lat)), float(np.min(lon)), float(np.max(lon))

    def coverage_text(self) -> str:
        s, n, w, e = self.bounds_latlon()
        return f"it covers latitude {s:.4f}..{n:.4f}, longitude {w:.4f}..{e:.4f}"

    def grid_xy(self, xy_min, xy_max, step_m: float | None = None):
        """A regular local grid over a box (for pictures): (xs, ys, Z) with Z[i, j] at (xs[j], ys[i])."""
        step = step_m or self.resolution_m
        x0, y0 = xy_min
        x1, y1 = xy_max
        nx = int(min(400, max(2, math.ceil((x1 - x0) / step) + 1)))
        ny = int(min(400, max(2, math.ceil((y1 - y0) / step) + 1)))
        xs, ys = np.linspace(x0, x1, nx), np.linspace(y0, y1, ny)
        X, Y = np.meshgrid(xs, ys)
        Z = self.height_xy(np.column_stack([X.ravel(), Y.ravel()]), clamp=True).reshape(ny, nx)
        return xs, ys, Z


@dataclass(frozen=True)
class TerrainSpec:
    """``[terrain]``: the DEM under the area and how the missions keep clear of it.

    ``dem``: a GeoTIFF, SRTM ``.hgt`` or DTED file (relative to the scenario file); none = flat ground.
    ``min_clearance_m``: the least height above the ground anywhere on a scan, look or return leg
    (the scan itself flies at ``fleet.altitude_m`` above the ground where the climb rates allow).
    ``max_climb_m_s`` / ``max_descent_m_s``: the vertical speeds the missions are planned within
    (ArduCopter WPNAV_SPEED_UP 2.5 / WPNAV_SPEED_DN 1.5 m/s, PX4 MPC_Z_V_AUTO_UP 3 / _DN 1.5 m/s).
    ``max_height_above_launch_m``: the highest a vehicle may fly above its launch point (a fence or
    a legal ceiling); a mission that would need more to keep clearance is refused.
    ``altitude_frame``: ``"amsl"`` writes absolute altitudes (MAV_FRAME_GLOBAL, both autopilots);
    ``"relative"`` writes them above the launch point, from the DEM's height differences.
    ``vertical_datum``: the geoid the DEM's heights are above (SRTM: EGM96).
    """

    dem: str | None = None
    min_clearance_m: float = 30.0
    # Trees and buildings standing above the DEM's ground [m] (issue 41): every leg keeps
    # min_clearance_m above ground + obstacles, and a look's floor (search.look_min_height_m) is above
    # them too. 0 by default: SRTM-like DEMs partly include roofs and canopy, and without a DEM
    # search.look_min_height_m is chosen to clear a town's buildings by itself.
    obstacle_height_m: float = 0.0
    max_climb_m_s: float = 2.5
    max_descent_m_s: float = 1.5
    max_height_above_launch_m: float | None = None
    altitude_frame: Literal["amsl", "relative"] = "amsl"
    vertical_datum: Literal["egm96", "egm2008", "ellipsoid"] = "egm96"


def check_spec(sc, base_dir: Path | None) -> str:
    """Validate ``sc.terrain`` (a TerrainSpec); return the DEM's resolved path ("" for none).
    Every problem is one ConfigError sentence naming the key."""
    t = sc.terrain

    def need(cond: bool, msg: str, key: str) -> None:
        if not cond:
            raise ConfigError(msg, source=sc.source, key=f"terrain.{key}")

    need(t.min_clearance_m > 0, f"must be positive, got {t.min_clearance_m} m", "min_clearance_m")
    if t.dem is not None:  # without a DEM the clearance is never used (a low flat scan stays valid)
        need(t.min_clearance_m <= sc.fleet.altitude_m,
             f"{t.min_clearance_m} m is more than the scan height fleet.altitude_m = {sc.fleet.altitude_m} m",
             "min_clearance_m")
        need(t.min_clearance_m + t.obstacle_height_m <= sc.fleet.altitude_m,
             f"{t.obstacle_height_m:g} m of obstacles plus terrain.min_clearance_m = {t.min_clearance_m:g} m is more "
             f"than the scan height fleet.altitude_m = {sc.fleet.altitude_m:g} m", "obstacle_height_m")
    need(t.max_climb_m_s > 0, f"must be positive, got {t.max_climb_m_s} m/s", "max_climb_m_s")
    need(t.max_descent_m_s > 0, f"must be positive, got {t.max_descent_m_s} m/s", "max_descent_m_s")
    if t.max_height_above_launch_m is not None and t.dem is not None:
        need(t.max_height_above_launch_m >= sc.fleet.altitude_m,
             f"{t.max_height_above_launch_m} m is below the scan height fleet.altitude_m = {sc.fleet.altitude_m} m",
             "max_height_above_launch_m")
    need(t.vertical_datum != "ellipsoid",
         "heights above the WGS84 ellipsoid differ from the autopilots' mean sea level by the geoid undulation "
         "(up to about 100 m) and uavloc has no geoid grid to convert them; give a DEM above the EGM96 or "
         "EGM2008 geoid (SRTM is EGM96)", "vertical_datum")
    if t.dem is None:
        return ""
    need(isinstance(t.dem, str) and t.dem.strip() != "", "must name a DEM file", "dem")
    p = Path(t.dem).expanduser()
    if not p.is_absolute() and base_dir is not None:
        p = base_dir / p
    return str(p.absolute())


_CACHE: dict = {}


def load_dem(path: str | Path, frame: "LocalFrame", *, key: str = "terrain.dem", source: str | None = None) -> Terrain:
    """Read a DEM file for use about ``frame``. A bad file is a ConfigError naming ``key``."""
    p = Path(path)
    try:
        stat = p.stat()
    except FileNotFoundError:
        raise ConfigError(f"DEM file {p} not found", source=source, key=key) from None
    except OSError as exc:
        raise ConfigError(f"cannot read the DEM file {p} ({exc.strerror})", source=source, key=key) from None
    ck = (str(p.resolve()), stat.st_mtime_ns, stat.st_size, frame.lat0_deg, frame.lon0_deg)
    if ck in _CACHE:
        return _CACHE[ck]
    try:
        import rasterio
        from rasterio.errors import RasterioError
    except ImportError:  # pragma: no cover - a dependency
        raise ConfigError("reading a DEM needs the rasterio package (pip install rasterio)", source=source,
                          key=key) from None
    import warnings

    try:
        with warnings.catch_warnings():  # a file without georeference is refused below, in a sentence
            warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
            ds = rasterio.open(p)
        with ds:
            if ds.crs is None:
                raise ConfigError(f"{p} has no coordinate reference system, so its cells cannot be placed; "
                                  "use a georeferenced GeoTIFF, an SRTM .hgt or a DTED file", source=source, key=key)
            band = ds.read(1, masked=True).astype(float)
            t = ds.transform
            crs_wkt = ds.crs.to_wkt()
            units = ds.crs.linear_units if ds.crs.is_projected else "degree"
    except RasterioError as exc:
        raise ConfigError(f"{p} is not a DEM that GDAL can read ({str(exc).splitlines()[0]})", source=source,
                          key=key) from None
    heights = np.ma.filled(band, np.nan)
    rows, cols = heights.shape
    if rows < 2 or cols < 2:
        raise ConfigError(f"{p} has {rows} x {cols} cells; a DEM needs at least 2 x 2", source=source, key=key)
    finite = heights[np.isfinite(heights)]
    if finite.size == 0:
        raise ConfigError(f"{p} holds no heights (every cell is a void)", source=source, key=key)
    if finite.min() < -500.0 or finite.max() > 9000.0:
        raise ConfigError(f"{p} has heights {finite.min():.0f}..{finite.max():.0f}, not metres of ground on Earth",
                          source=source, key=key)
    if units not in ("degree", "metre", "meter", "m"):
        raise ConfigError(f"{p} is in units of {units!r}; uavloc reads DEMs in degrees or metres", source=source,
                          key=key)
    tr = (t.a, t.b, t.c, t.d, t.e, t.f)
    # Cell size on the ground: metres directly, or degrees converted at the DEM's centre.
    if units == "degree":
        lat_c = t.f + t.e * rows / 2
        res = min(abs(t.a) * 111_320.0 * math.cos(math.radians(lat_c)), abs(t.e) * 110_574.0)
    else:
        res = min(abs(t.a), abs(t.e))
    ter = Terrain(heights, tr, crs_wkt, frame, str(p), float(res))
    _CACHE[ck] = ter
    return ter


def describe(scenario) -> str:
    """One line: which ground a scenario's altitudes are over."""
    ter = scenario.dem
    if ter is None:
        return "Terrain: " + FLAT_GROUND + "."
    t = scenario.terrain
    home = ter.height_at(0.0, 0.0)
    return (f"Terrain: {Path(ter.source).name} ({ter.resolution_m:.0f} m cells, heights above the "
            f"{t.vertical_datum.upper()} geoid), launch ground {home:.0f} m; scan at {scenario.fleet.altitude_m:g} m "
            f"above the ground, at least {t.min_clearance_m:g} m on every leg.")


def check_covers(ter: Terrain, xy_m: np.ndarray, what: str, *, source: str | None, key: str = "terrain.dem") -> None:
    """Refuse a DEM that does not cover ``xy_m`` (the area's vertices and launch) or has voids there."""
    xy = np.asarray(xy_m, dtype=float).reshape(-1, 2)
    h = ter.height_xy(xy)
    bad = np.flatnonzero(~np.isfinite(h))
    if bad.size:
        lat, lon = ter.frame.to_wgs84_latlon(xy[bad[0]])[0]
        why = "outside it" if not ter.inside(xy[bad[0]])[0] else "a void in it"
        raise ConfigError(f"{ter.source} does not give the ground under {what} at {lat:.5f}, {lon:.5f} ({why}; "
                          f"{ter.coverage_text()})", source=source, key=key)


def refuse(message: str) -> None:
    raise InfeasibleError(message)
