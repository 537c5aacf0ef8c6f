"""GeoJSON (RFC 7946) for areas, lanes, routes and, later, results.

Small builders (:func:`point`, :func:`linestring`, :func:`polygon`, ...) take ``[lat, lon]``
pairs like the rest of uavloc and write RFC 7946 ``[lon, lat]`` positions; :func:`feature`
attaches properties (use the simplestyle keys ``stroke``, ``stroke-width``, ``fill``,
``fill-opacity``, ``marker-color`` so geojson.io and QGIS draw them in colour; ``kml`` reuses
them). :func:`dumps` is deterministic. :func:`scan_feature_collection` is the scan plan as one
file: area, launch point, and per vehicle its sub-area, lanes, route and waypoints.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

from uavloc_gcs.errors import FileFormatError
from uavloc_gcs.render.palette import vehicle_colors

from ._common import read_text, write_text

__all__ = [
    "point", "multipoint", "linestring", "multilinestring", "polygon", "feature", "feature_collection",
    "dumps", "loads", "read", "write", "scan_feature_collection",
]


def _pos(lat: float, lon: float) -> list[float]:
    if not (math.isfinite(lat) and math.isfinite(lon)):
        raise ValueError(f"position ({lat}, {lon}) is not finite")
    return [float(lon), float(lat)]


def point(lat_deg: float, lon_deg: float) -> dict:
    return {"type": "Point", "coordinates": _pos(lat_deg, lon_deg)}


def multipoint(latlon_deg: Iterable[Sequence[float]]) -> dict:
    return {"type": "MultiPoint", "coordinates": [_pos(a, b) for a, b in latlon_deg]}


def linestring(latlon_deg: Iterable[Sequence[float]]) -> dict:
    return {"type": "LineString", "coordinates": [_pos(a, b) for a, b in latlon_deg]}


def multilinestring(lines_latlon_deg: Iterable[Iterable[Sequence[float]]]) -> dict:
    return {"type": "MultiLineString", "coordinates": [[_pos(a, b) for a, b in ln] for ln in lines_latlon_deg]}


def polygon(ring_latlon_deg: Sequence[Sequence[float]]) -> dict:
    """A Polygon from one open or closed ring; written closed and counter-clockwise (RFC 7946)."""
    ring = [_pos(a, b) for a, b in ring_latlon_deg]
    if ring and ring[0] == ring[-1]:
        ring = ring[:-1]
    xy = np.array(ring)
    signed = np.sum(xy[:, 0] * np.roll(xy[:, 1], -1) - np.roll(xy[:, 0], -1) * xy[:, 1]) if len(xy) else 0.0
    if signed < 0:
        ring = ring[::-1]
    return {"type": "Polygon", "coordinates": [ring + ring[:1]]}


def feature(geometry: dict, **properties: Any) -> dict:
    """A Feature; property names may use ``_`` for ``-`` (``stroke_width`` -> ``stroke-width``)."""
    props = {k.replace("_", "-") if k in _STYLE_KEYS else k: v for k, v in properties.items()}
    return {"type": "Feature", "properties": props, "geometry": geometry}


_STYLE_KEYS = {"stroke_width", "stroke_opacity", "fill_opacity", "marker_color", "marker_symbol"}


def feature_collection(features: Iterable[dict], **properties: Any) -> dict:
    fc: dict[str, Any] = {"type": "FeatureCollection", "features": list(features)}
    if properties:
        fc["properties"] = properties  # a foreign member (RFC 7946 §6.1): name, source, ...
    return fc


def dumps(obj: dict) -> str:
    """Deterministic text (fixed key order as built, 1-space indent, newline at the end)."""
    return json.dumps(obj, indent=1, allow_nan=False) + "\n"


def loads(text: str, *, path: str = "<string>") -> dict:
    """Parse GeoJSON text into a dict, checking only that it is a GeoJSON object."""
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise FileFormatError(f"not valid JSON ({exc.msg})", path=path, line=exc.lineno) from None
    kinds = {"FeatureCollection", "Feature", "Point", "MultiPoint", "LineString", "MultiLineString", "Polygon",
             "MultiPolygon", "GeometryCollection"}
    if not isinstance(doc, dict) or doc.get("type") not in kinds:
        raise FileFormatError("not a GeoJSON object (missing or unknown 'type')", path=path, field="type")
    return doc


def read(path: str | Path) -> dict:
    return loads(read_text(path), path=str(path))


def write(path: str | Path, obj: dict) -> Path:
    return write_text(path, dumps(obj))


def scan_feature_collection(scenario, plan, *, colors: Sequence[str] | None = None) -> dict:
    """The scan plan of ``scenario`` (a :class:`uavloc_gcs.scan.ScanPlan`) as a FeatureCollection.

    Features, each with a ``kind`` property: ``area``, ``launch``, and per vehicle (``vehicle``
    = "uavN") ``subarea``, ``lanes``, ``route`` (launch -> waypoints -> launch, with
    ``length_m``, ``duration_s``, ``energy_j``) and ``waypoints``. ``altitude_m`` is the flight
    altitude above the launch point.
    """
    frame = scenario.frame
    to_ll = frame.to_wgs84_latlon
    alt = scenario.fleet.altitude_m
    colors = list(colors) if colors is not None else vehicle_colors(len(plan.vehicles))
    feats = [
        feature(polygon(scenario.polygon_latlon_deg), kind="area", name=f"search area ({scenario.name})",
                stroke="#444444", stroke_width=2, fill="#444444", fill_opacity=0.05),
        feature(point(*scenario.launch_latlon_deg), kind="launch", name="launch / home", marker_color="#d62728"),
    ]
    for v, col in zip(plan.vehicles, colors):
        name = f"uav{v.index + 1}"
        for part in v.subarea_parts_xy_m:
            feats.append(feature(polygon(to_ll(part)), kind="subarea", vehicle=name, name=f"{name} sub-area",
                                 stroke=col, stroke_width=1, fill=col, fill_opacity=0.15))
        feats.append(feature(multilinestring(to_ll(seg) for seg in v.lanes_xy_m), kind="lanes", vehicle=name,
                             name=f"{name} lanes", stroke=col, stroke_width=3, altitude_m=alt,
                             lane_spacing_m=round(plan.lane_spacing_m, 3)))
        feats.append(feature(linestring(to_ll(v.route_xy_m())), kind="route", vehicle=name,
                             name=f"{name} route", stroke=col, stroke_width=2, altitude_m=alt,
                             length_m=round(v.length_m, 3), duration_s=round(v.duration_s, 3),
                             energy_j=round(v.energy_j, 1)))
        feats.append(feature(multipoint(to_ll(v.waypoints_xy_m)), kind="waypoints", vehicle=name,
                             name=f"{name} waypoints", marker_color=col, altitude_m=alt))
    return feature_collection(feats, name=f"uavloc scan plan: {scenario.name}", coverage=plan.coverage,
                              lane_spacing_m=round(plan.lane_spacing_m, 3), range_m=round(plan.range_m, 3))
