"""KML 2.2 for Google Earth, made from the project's GeoJSON FeatureCollections.

:func:`from_feature_collection` turns any FeatureCollection built with :mod:`mission_io.geojson`
into a KML document: one folder per ``vehicle`` property (others at the top), simplestyle
colours (``stroke``, ``fill``, ``marker-color``) as KML styles, and features with an
``altitude_m`` property drawn at that height above ground (so a route floats at flight
altitude). Output is deterministic (styles numbered in order of first use).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

from ._common import fmt_float, write_text

__all__ = ["from_feature_collection", "dumps", "write"]

KML_NS = "http://www.opengis.net/kml/2.2"


def _kml_color(hex_rgb: str, opacity: float = 1.0) -> str:
    """'#rrggbb' + opacity -> KML 'aabbggrr'."""
    h = hex_rgb.lstrip("#")
    if len(h) != 6:
        raise ValueError(f"colour must be '#rrggbb', got {hex_rgb!r}")
    a = max(0, min(255, round(opacity * 255)))
    return f"{a:02x}{h[4:6]}{h[2:4]}{h[0:2]}".lower()


def _coords(positions, alt: float | None) -> str:
    def one(p):
        lon, lat = p[0], p[1]
        z = alt if alt is not None else 0.0
        return f"{fmt_float(lon)},{fmt_float(lat)},{fmt_float(z)}"
    return " ".join(one(p) for p in positions)


def _geometry(parent: ET.Element, geom: dict, alt: float | None) -> None:
    kind, c = geom["type"], geom["coordinates"]
    mode = "relativeToGround" if alt is not None else "clampToGround"

    def add(tag: str, positions) -> ET.Element:
        el = ET.SubElement(parent, tag)
        if alt is not None and tag != "Polygon":
            ET.SubElement(el, "altitudeMode").text = mode
        if tag == "LineString":
            ET.SubElement(el, "tessellate").text = "1"
        if tag == "Polygon":
            ET.SubElement(el, "altitudeMode").text = "clampToGround"
            ring = ET.SubElement(ET.SubElement(el, "outerBoundaryIs"), "LinearRing")
            ET.SubElement(ring, "coordinates").text = _coords(positions, None)
        else:
            ET.SubElement(el, "coordinates").text = _coords(positions, alt)
        return el

    if kind == "Point":
        add("Point", [c])
    elif kind == "LineString":
        add("LineString", c)
    elif kind == "Polygon":
        add("Polygon", c[0])
    elif kind in ("MultiPoint", "MultiLineString", "MultiPolygon"):
        multi = ET.SubElement(parent, "MultiGeometry")
        for part in c:
            _geometry(multi, {"type": kind[5:], "coordinates": part}, alt)
    else:
        raise ValueError(f"geometry type {kind!r} is not supported in KML export")


def from_feature_collection(fc: dict, *, name: str | None = None) -> ET.Element:
    """A ``<kml>`` element for ``fc`` (see module docstring)."""
    ET.register_namespace("", KML_NS)
    kml = ET.Element("kml", xmlns=KML_NS)
    doc = ET.SubElement(kml, "Document")
    ET.SubElement(doc, "name").text = name or (fc.get("properties") or {}).get("name", "uavloc")
    styles: dict[tuple, str] = {}
    folders: dict[str, ET.Element] = {}
    placemarks: list[tuple[ET.Element, ET.Element]] = []
    for f in fc.get("features", []):
        props: dict[str, Any] = f.get("properties") or {}
        key = (props.get("stroke"), props.get("stroke-width"), props.get("fill"), props.get("fill-opacity"),
               props.get("marker-color"))
        if key not in styles:
            styles[key] = f"s{len(styles)}"
            _style(doc, styles[key], *key)
        vehicle = props.get("vehicle")
        parent = doc
        if vehicle is not None:
            if vehicle not in folders:
                folders[vehicle] = ET.Element("Folder")
                ET.SubElement(folders[vehicle], "name").text = str(vehicle)
            parent = folders[vehicle]
        pm = ET.Element("Placemark")
        ET.SubElement(pm, "name").text = str(props.get("name", props.get("kind", "feature")))
        desc = ", ".join(f"{k} = {v}" for k, v in props.items()
                         if k not in ("name", "stroke", "stroke-width", "fill", "fill-opacity", "marker-color"))
        if desc:
            ET.SubElement(pm, "description").text = desc
        ET.SubElement(pm, "styleUrl").text = f"#{styles[key]}"
        alt = props.get("altitude_m")
        _geometry(pm, f["geometry"], float(alt) if alt is not None else None)
        placemarks.append((parent, pm))
    # Styles first, then top-level placemarks, then one folder per vehicle (KML element order).
    for parent, pm in placemarks:
        parent.append(pm)
    for folder in folders.values():
        doc.append(folder)
    return kml


def _style(doc: ET.Element, sid: str, stroke, width, fill, fill_opacity, marker) -> None:
    st = ET.SubElement(doc, "Style", id=sid)
    if marker:
        icon = ET.SubElement(st, "IconStyle")
        ET.SubElement(icon, "color").text = _kml_color(marker)
    line = ET.SubElement(st, "LineStyle")
    ET.SubElement(line, "color").text = _kml_color(stroke or "#444444")
    ET.SubElement(line, "width").text = fmt_float(float(width or 2))
    poly = ET.SubElement(st, "PolyStyle")
    if fill:
        ET.SubElement(poly, "color").text = _kml_color(fill, float(fill_opacity if fill_opacity is not None else 0.3))
    else:
        ET.SubElement(poly, "fill").text = "0"


def dumps(kml: ET.Element) -> str:
    """Pretty, deterministic XML text with declaration."""
    ET.indent(kml, space=" ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(kml, encoding="unicode") + "\n"


def write(path: str | Path, kml: ET.Element) -> Path:
    return write_text(path, dumps(kml))
