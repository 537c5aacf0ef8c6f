"""Read a search-area polygon from a GeoJSON file or a QGroundControl ``.plan`` geofence.

Accepted inputs (the first usable polygon wins, outer ring only):

* GeoJSON ``Polygon``, ``MultiPolygon`` (first polygon), ``Feature`` holding one of those, or
  ``FeatureCollection`` (first feature with a polygon geometry). GeoJSON positions are
  ``[lon, lat]`` (RFC 7946); the result is ``[[lat, lon], ...]``.
* QGC ``.plan``: the first ``geoFence.polygons`` entry with ``"inclusion": true``
  (positions there are ``[lat, lon]``).

The returned ring is not closed (a repeated last vertex is dropped).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from uavloc_gcs.errors import FileFormatError

from ._common import read_text

__all__ = ["read_area_polygon", "loads_area_polygon"]


def read_area_polygon(path: str | Path) -> list[list[float]]:
    """Read the area polygon ``[[lat_deg, lon_deg], ...]`` from a GeoJSON or ``.plan`` file."""
    p = Path(path)
    text = read_text(p)
    return loads_area_polygon(text, path=str(p))


def loads_area_polygon(text: str, *, path: str = "<string>") -> list[list[float]]:
    """Parse GeoJSON or ``.plan`` text; see :func:`read_area_polygon`."""
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise FileFormatError(f"not valid JSON ({exc.msg})", path=path, line=exc.lineno) from None
    if not isinstance(doc, dict):
        raise FileFormatError("expected a JSON object at the top level", path=path)
    if doc.get("fileType") == "Plan":
        return _from_plan(doc, path)
    if "type" not in doc:
        raise FileFormatError(
            "neither a GeoJSON object (no 'type') nor a QGroundControl plan (no 'fileType': 'Plan')",
            path=path, field="type",
        )
    return _from_geojson(doc, path)


def _from_plan(doc: dict, path: str) -> list[list[float]]:
    fence = doc.get("geoFence")
    if not isinstance(fence, dict):
        raise FileFormatError("missing or not an object", path=path, field="geoFence")
    polys = fence.get("polygons", [])
    if not isinstance(polys, list):
        raise FileFormatError("must be a list", path=path, field="geoFence.polygons")
    for i, entry in enumerate(polys):
        if not isinstance(entry, dict):
            raise FileFormatError("must be an object", path=path, item=i, field="geoFence.polygons")
        if entry.get("inclusion", True) is not True:
            continue
        ring = entry.get("polygon")
        return _ring(ring, path, f"geoFence.polygons[{i}].polygon", lonlat=False)
    raise FileFormatError("the plan has no inclusion geofence polygon", path=path, field="geoFence.polygons")


_POLY_TYPES = ("Polygon", "MultiPolygon")


def _from_geojson(doc: dict, path: str) -> list[list[float]]:
    kind = doc.get("type")
    if kind == "FeatureCollection":
        feats = doc.get("features")
        if not isinstance(feats, list):
            raise FileFormatError("must be a list", path=path, field="features")
        for i, f in enumerate(feats):
            geom = f.get("geometry") if isinstance(f, dict) else None
            if isinstance(geom, dict) and geom.get("type") in _POLY_TYPES:
                return _geometry(geom, path, f"features[{i}].geometry")
        raise FileFormatError("no feature has a Polygon or MultiPolygon geometry", path=path, field="features")
    if kind == "Feature":
        geom = doc.get("geometry")
        if not isinstance(geom, dict):
            raise FileFormatError("missing or not an object", path=path, field="geometry")
        return _geometry(geom, path, "geometry")
    return _geometry(doc, path, "")


def _geometry(geom: dict, path: str, where: str) -> list[list[float]]:
    pre = f"{where}." if where else ""
    kind = geom.get("type")
    coords = geom.get("coordinates")
    if kind == "Polygon":
        if not isinstance(coords, list) or not coords:
            raise FileFormatError("must be a non-empty list of rings", path=path, field=f"{pre}coordinates")
        return _ring(coords[0], path, f"{pre}coordinates[0]", lonlat=True)
    if kind == "MultiPolygon":
        if not isinstance(coords, list) or not coords or not isinstance(coords[0], list) or not coords[0]:
            raise FileFormatError("must be a non-empty list of polygons", path=path, field=f"{pre}coordinates")
        return _ring(coords[0][0], path, f"{pre}coordinates[0][0]", lonlat=True)
    raise FileFormatError(
        f"geometry type is {kind!r}; expected 'Polygon' or 'MultiPolygon'", path=path, field=f"{pre}type"
    )


def _ring(ring: Any, path: str, field: str, *, lonlat: bool) -> list[list[float]]:
    if not isinstance(ring, list):
        raise FileFormatError("must be a list of positions", path=path, field=field)
    out: list[list[float]] = []
    for i, pos in enumerate(ring):
        ok = (
            isinstance(pos, list)
            and len(pos) >= 2
            and all(isinstance(c, (int, float)) and not isinstance(c, bool) for c in pos[:2])
        )
        if not ok:
            raise FileFormatError(f"position {i} must be a list of 2 numbers, got {pos!r}", path=path, field=field)
        a, b = float(pos[0]), float(pos[1])
        lat, lon = (b, a) if lonlat else (a, b)
        order = "[lon, lat]" if lonlat else "[lat, lon]"
        if not (math.isfinite(lat) and -90.0 <= lat <= 90.0 and math.isfinite(lon) and -180.0 <= lon <= 180.0):
            raise FileFormatError(
                f"position {i} {pos!r} is not a valid {order} in degrees", path=path, field=field
            )
        out.append([lat, lon])
    if len(out) >= 2 and out[0] == out[-1]:
        out = out[:-1]
    if len(out) < 3:
        raise FileFormatError(f"a polygon needs at least 3 distinct vertices, got {len(out)}", path=path, field=field)
    return out
