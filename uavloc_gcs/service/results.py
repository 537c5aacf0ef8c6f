"""What a search produced, for the people who act on it: table, CSV, GeoJSON, KML and a map.

:class:`PersonResult` is one located (or not located) person in operator units. The writers are
pure ``dumps``-style functions returning text with deterministic output; :func:`write_results`
puts them all (plus ``result.png``) into a directory.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence
from xml.sax.saxutils import escape

import numpy as np

from ..geo import LocalFrame

CSV_COLUMNS = (
    "emitter_id", "located", "lat_deg", "lon_deg", "east_m", "north_m", "vel_east_m_s",
    "vel_north_m_s", "radius95_m", "annulus_bound_m", "fix_time_s", "ambiguity_resolved",
    "reason", "t_ref_s",
)


@dataclass(frozen=True)
class PersonResult:
    """One person's final estimate. Positions in WGS84 and in the local frame (east/north m).

    ``located`` means the calibrated 95 % radius is within the required accuracy;
    ``reason`` says why not otherwise (one phrase). ``fix_time_s`` and ``t_ref_s`` are mission
    seconds (the daemon's clock).
    """

    emitter_id: int
    lat_deg: float
    lon_deg: float
    east_m: float
    north_m: float
    vel_east_m_s: float
    vel_north_m_s: float
    radius95_m: float
    annulus_bound_m: float
    fix_time_s: float
    located: bool
    ambiguity_resolved: bool
    reason: str = ""
    t_ref_s: float = math.nan  # mission time [s] the position refers to (people move)


def _num(x: float, nd: int) -> str:
    return "" if x is None or not math.isfinite(x) else f"{x:.{nd}f}"


def people_csv(people: Sequence[PersonResult]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for p in sorted(people, key=lambda p: p.emitter_id):
        w.writerow([p.emitter_id, int(p.located), _num(p.lat_deg, 7), _num(p.lon_deg, 7),
                    _num(p.east_m, 2), _num(p.north_m, 2), _num(p.vel_east_m_s, 3),
                    _num(p.vel_north_m_s, 3), _num(p.radius95_m, 2), _num(p.annulus_bound_m, 2),
                    _num(p.fix_time_s, 2), int(p.ambiguity_resolved), p.reason, _num(p.t_ref_s, 2)])
    return buf.getvalue()


def _clean(x: float, nd: int):
    return None if x is None or not math.isfinite(x) else round(float(x), nd)


def people_geojson(people: Sequence[PersonResult], truth_latlon: Mapping[int, tuple] | None = None) -> str:
    """A FeatureCollection: one Point per estimated person (properties: radius, velocity, ...),
    plus a Point per true position (``"kind": "truth"``) when the run was simulated."""
    feats = []
    for p in sorted(people, key=lambda p: p.emitter_id):
        if not (math.isfinite(p.lat_deg) and math.isfinite(p.lon_deg)):
            continue
        feats.append({
            "type": "Feature",
            "geometry": {"type": "Point", "coordinates": [round(p.lon_deg, 7), round(p.lat_deg, 7)]},
            "properties": {
                "kind": "estimate", "emitter_id": p.emitter_id, "located": p.located,
                "radius95_m": _clean(p.radius95_m, 2), "annulus_bound_m": _clean(p.annulus_bound_m, 2),
                "vel_east_m_s": _clean(p.vel_east_m_s, 3), "vel_north_m_s": _clean(p.vel_north_m_s, 3),
                "fix_time_s": _clean(p.fix_time_s, 2), "ambiguity_resolved": p.ambiguity_resolved,
                "reason": p.reason,
            },
        })
    for eid, (lat, lon) in sorted((truth_latlon or {}).items()):
        feats.append({
            "type": "Feature",
            "geometry": {"type": "Point", "coordinates": [round(float(lon), 7), round(float(lat), 7)]},
            "properties": {"kind": "truth", "emitter_id": int(eid)},
        })
    return json.dumps({"type": "FeatureCollection", "features": feats}, indent=1) + "\n"


def _circle_latlon(frame: LocalFrame, e: float, n: float, r: float, k: int = 36) -> np.ndarray:
    a = np.linspace(0, 2 * np.pi, k + 1)
    return frame.to_wgs84_latlon(np.column_stack([e + r * np.cos(a), n + r * np.sin(a)]))


def people_kml(people: Sequence[PersonResult], frame: LocalFrame, name: str = "uavloc") -> str:
    """KML for Google Earth: a placemark per person and its 95 % circle."""
    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           '<kml xmlns="http://www.opengis.net/kml/2.2"><Document>',
           f"<name>{escape(name)}</name>"]
    for p in sorted(people, key=lambda p: p.emitter_id):
        if not (math.isfinite(p.lat_deg) and math.isfinite(p.lon_deg)):
            continue
        state = "located" if p.located else f"not located: {p.reason}"
        desc = f"95 % radius {_num(p.radius95_m, 1)} m; {state}"
        out.append(f"<Placemark><name>person {p.emitter_id}</name><description>{escape(desc)}</description>"
                   f"<Point><coordinates>{p.lon_deg:.7f},{p.lat_deg:.7f},0</coordinates></Point></Placemark>")
        if math.isfinite(p.radius95_m):
            ring = _circle_latlon(frame, p.east_m, p.north_m, p.radius95_m)
            coords = " ".join(f"{lon:.7f},{lat:.7f},0" for lat, lon in ring)
            out.append(f"<Placemark><name>person {p.emitter_id} 95 %</name><Polygon><outerBoundaryIs>"
                       f"<LinearRing><coordinates>{coords}</coordinates></LinearRing></outerBoundaryIs>"
                       "</Polygon></Placemark>")
    out.append("</Document></kml>")
    return "\n".join(out) + "\n"


def results_table(people: Sequence[PersonResult], required_accuracy_m: float,
                  truth_xy_m: Mapping[int, Sequence[float]] | None = None) -> str:
    """A plain-text table for the terminal, with the error to the truth when simulated."""
    head = f"{'person':>10}  {'lat':>11}  {'lon':>11}  {'95% r':>7}  {'status':<10}"
    if truth_xy_m:
        head += f"  {'true error':>10}"
    lines = [head, "-" * len(head)]
    for p in sorted(people, key=lambda p: p.emitter_id):
        status = "located" if p.located else "NOT"
        row = (f"{p.emitter_id:>10}  {_num(p.lat_deg, 6):>11}  {_num(p.lon_deg, 6):>11}  "
               f"{_num(p.radius95_m, 1) + ' m' if math.isfinite(p.radius95_m) else '-':>7}  {status:<10}")
        if truth_xy_m:
            t = truth_xy_m.get(p.emitter_id)
            err = math.hypot(p.east_m - t[0], p.north_m - t[1]) if t is not None and math.isfinite(p.east_m) else math.nan
            row += f"  {_num(err, 1) + ' m' if math.isfinite(err) else '-':>10}"
        if not p.located and p.reason:
            row += f"  ({p.reason})"
        lines.append(row)
    n_ok = sum(p.located for p in people)
    lines.append(f"{n_ok} of {len(people)} people located within {required_accuracy_m:g} m (95 %).")
    return "\n".join(lines) + "\n"


def write_results(out_dir: str | Path, people: Sequence[PersonResult], *, frame: LocalFrame,
                  area_latlon_deg: np.ndarray, tracks_latlon_deg: Mapping[int, np.ndarray],
                  required_accuracy_m: float, truth_xy_m: Mapping[int, Sequence[float]] | None = None,
                  name: str = "uavloc") -> list[Path]:
    """Write people.csv, people.geojson, people.kml, result.png and results.txt into ``out_dir``."""
    from ..atomicfile import atomic_write_text

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    truth_latlon = None
    if truth_xy_m:
        ids = sorted(truth_xy_m)
        ll = frame.to_wgs84_latlon(np.array([truth_xy_m[i][:2] for i in ids], dtype=float))
        truth_latlon = {i: (float(a), float(b)) for i, (a, b) in zip(ids, ll)}
    files = {
        "people.csv": people_csv(people),
        "people.geojson": people_geojson(people, truth_latlon),
        "people.kml": people_kml(people, frame, name),
        "results.txt": results_table(people, required_accuracy_m, truth_xy_m),
    }
    written = []
    for fname, text in files.items():
        atomic_write_text(out / fname, text)
        written.append(out / fname)
    png = out / "result.png"
    render_result_png(png, people, frame=frame, area_latlon_deg=area_latlon_deg,
                      tracks_latlon_deg=tracks_latlon_deg, truth_xy_m=truth_xy_m, title=name)
    written.append(png)
    return written


def render_result_png(path: Path, people: Sequence[PersonResult], *, frame: LocalFrame,
                      area_latlon_deg: np.ndarray, tracks_latlon_deg: Mapping[int, np.ndarray],
                      truth_xy_m: Mapping[int, Sequence[float]] | None, title: str) -> None:
    """The result map in local metres (the project's shared map style, ``render.maps``): area,
    flown tracks, estimates with their 95 % circles (green located, red not), true positions
    joined to their estimates when the run was simulated."""
    from ..render import maps  # noqa: PLC0415

    area = frame.to_local_xy(np.asarray(area_latlon_deg, dtype=float))
    span = area.max(axis=0) - area.min(axis=0)
    n_ok = sum(p.located for p in people)
    fig, ax = maps.new_map(f"{title}: {n_ok} of {len(people)} people located",
                           subtitle=maps.origin_caption(*frame.to_wgs84(0.0, 0.0)), extent_m=tuple(span))
    maps.draw_area(ax, area)
    ids = sorted(tracks_latlon_deg)
    colors = maps.vehicle_colors(max(ids, default=0))
    tracks = [frame.to_local_xy(np.asarray(tracks_latlon_deg[v], dtype=float)) for v in ids]
    maps.draw_polylines(ax, tracks, [f"UAV {v} flown" for v in ids], [colors[v - 1] for v in ids],
                        linewidth=1.0, arrows=False)
    maps.draw_launch(ax)
    est = [p for p in people if math.isfinite(p.east_m)]
    for located, color, label in ((True, "#2ca02c", "located (95 % circle)"), (False, "#d62728", "not located")):
        group = [p for p in est if p.located == located]
        if not group:
            continue
        xy = np.array([[p.east_m, p.north_m] for p in group])
        maps.draw_circles(ax, xy, [p.radius95_m for p in group], color=color, alpha=0.12)
        maps.draw_points(ax, xy, label, color=color, marker="P", size=45,
                         annotations=[str(p.emitter_id) for p in group])
    if truth_xy_m:
        t = np.array([truth_xy_m[k][:2] for k in sorted(truth_xy_m)], dtype=float)
        maps.draw_points(ax, t, "true position", color="#111111", marker="X", size=40)
        for p in est:
            if p.emitter_id in truth_xy_m:
                tx, ty = truth_xy_m[p.emitter_id][:2]
                ax.plot([p.east_m, tx], [p.north_m, ty], color="#111111", linewidth=0.7, zorder=4)
    maps.add_scale_bar(ax)
    maps.add_legend(ax)
    maps.save_figure(fig, path)
