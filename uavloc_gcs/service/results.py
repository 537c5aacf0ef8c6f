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

from ..estimation.identity import format_address, format_addresses
from ..geo import LocalFrame
from .clock import MissionClock, clock_label, utc_text  # noqa: F401 (utc_text: re-exported)

CSV_COLUMNS = (
    "label", "emitter_id", "state", "located", "time_utc", "t_ref_s", "lat_deg", "lon_deg", "east_m",
    "north_m", "vel_east_m_s", "vel_north_m_s", "speed_m_s", "radius95_m", "annulus_bound_m",
    "fix_time_s", "fix_time_utc", "ambiguity_resolved", "reason", "addresses", "link", "link_reason",
    "pod_here", "radio",
)
STATES = ("located", "heard", "given up", "never heard")


@dataclass(frozen=True)
class PersonResult:
    """One person's final estimate. Positions in WGS84 and in the local frame (east/north m).

    ``located`` means the calibrated 95 % radius is within the required accuracy;
    ``reason`` says why not otherwise (one phrase). ``fix_time_s`` and ``t_ref_s`` are mission
    seconds (the daemon's clock). ``addresses``: the 802.11 addresses the person was heard under
    (first heard first; empty: the emitter id is the only one, as in old logs and the paper's
    world); ``link_reason``: why linking those addresses into one person is uncertain ('' = sure;
    :mod:`uavloc_gcs.estimation.identity`).
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
    label: str = ""  # "P01", ... (service.labels): the same in the table, the files and the maps
    addresses: tuple = ()  # int 48-bit addresses; () = (emitter_id,)
    link_reason: str = ""
    pod_here: float = math.nan  # achieved POD of the cell at the reported position (search.coverage)
    # the radio the person was heard by (uavloc_gcs.radios): "wifi" probe bursts or "ble" beacons; one
    # phone heard by both is two identities, reported apart (they share no content to link them by)
    radio: str = "wifi"

    @property
    def link(self) -> str:
        """'uncertain' when one of the person's address links is, else 'sure'."""
        return "uncertain" if self.link_reason else "sure"

    @property
    def address_list(self) -> list[int]:
        return [int(a) for a in self.addresses] or [int(self.emitter_id)]

    @property
    def state(self) -> str:
        """located, heard (not located yet / not located), given up, or never heard."""
        return person_state(self.located, self.reason)

    @property
    def name(self) -> str:
        """'P01 #17': the short label with the emitter id (just '#17' without a label)."""
        from ..estimation.identity import person_name  # noqa: PLC0415

        ident = person_name(self.emitter_id)  # the first address heard, as a MAC, in the field world
        return f"{self.label} #{ident}" if self.label else f"#{ident}"


def person_state(located: bool, reason: str) -> str:
    """The state a person is shown in: located, heard, given up, never heard."""
    if located:
        return "located"
    if reason == "never heard":
        return "never heard"
    if reason.startswith("given up"):
        return "given up"
    return "heard"


def _speed(p: PersonResult) -> float:
    return math.hypot(p.vel_east_m_s, p.vel_north_m_s)


def _num(x: float, nd: int) -> str:
    return "" if x is None or not math.isfinite(x) else f"{x:.{nd}f}"


def _order(people: Sequence[PersonResult]) -> list[PersonResult]:
    """Labelled people by label (P01, P02, ...), then the rest by emitter id."""
    return sorted(people, key=lambda p: (not p.label, len(p.label), p.label, p.emitter_id))


def people_csv(people: Sequence[PersonResult], epoch_unix_s: float | None = None) -> str:
    """One row per person. ``time_utc``/``t_ref_s``: when the position was true (UTC, mission s);
    ``fix_time_utc``/``fix_time_s``: when the person was located."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for p in _order(people):
        w.writerow([p.label, p.emitter_id, p.state, int(p.located), utc_text(epoch_unix_s, p.t_ref_s),
                    _num(p.t_ref_s, 2), _num(p.lat_deg, 7), _num(p.lon_deg, 7), _num(p.east_m, 2),
                    _num(p.north_m, 2), _num(p.vel_east_m_s, 3), _num(p.vel_north_m_s, 3), _num(_speed(p), 3),
                    _num(p.radius95_m, 2), _num(p.annulus_bound_m, 2), _num(p.fix_time_s, 2),
                    utc_text(epoch_unix_s, p.fix_time_s), int(p.ambiguity_resolved), p.reason,
                    format_addresses(p.address_list), p.link, p.link_reason, _num(p.pod_here, 3), p.radio])
    return buf.getvalue()


def _clean(x: float, nd: int):
    return None if x is None or not math.isfinite(x) else round(float(x), nd)


def _properties(p: PersonResult, epoch_unix_s: float | None) -> dict:
    return {
        "label": p.label, "emitter_id": p.emitter_id, "name": p.name, "state": p.state, "located": p.located,
        "time_utc": utc_text(epoch_unix_s, p.t_ref_s) or None, "t_ref_s": _clean(p.t_ref_s, 2),
        "radius95_m": _clean(p.radius95_m, 2), "annulus_bound_m": _clean(p.annulus_bound_m, 2),
        "vel_east_m_s": _clean(p.vel_east_m_s, 3), "vel_north_m_s": _clean(p.vel_north_m_s, 3),
        "speed_m_s": _clean(_speed(p), 3), "fix_time_s": _clean(p.fix_time_s, 2),
        "fix_time_utc": utc_text(epoch_unix_s, p.fix_time_s) or None,
        "ambiguity_resolved": p.ambiguity_resolved, "reason": p.reason,
        "addresses": [format_address(a) for a in p.address_list], "link": p.link,
        "link_reason": p.link_reason or None, "pod_here": _clean(p.pod_here, 3), "radio": p.radio,
    }


def people_geojson(people: Sequence[PersonResult], truth_latlon: Mapping[int, tuple] | None = None, *,
                   epoch_unix_s: float | None = None, frame: LocalFrame | None = None, coverage=None) -> str:
    """A FeatureCollection: one Point per estimated person (``"kind": "estimate"``; properties:
    label, state, UTC time and mission seconds of the position, velocity, radius, the achieved POD
    where it is, ...), its 95 % circle as a Polygon (``"kind": "circle95"``, when ``frame`` is
    given), plus a Point per true position (``"kind": "truth"``) when the run was simulated. With
    ``coverage`` (search.coverage.CoverageSummary) and ``frame``: a square Polygon per cell of the
    area (``"kind": "pod_cell"``: pod, pod2, below_target, unsearched) and the whole search's
    figures as the collection's ``"coverage"`` member (overall POD, target, unsearched m², expected
    people missed)."""
    feats = []
    for p in _order(people):
        if not (math.isfinite(p.lat_deg) and math.isfinite(p.lon_deg)):
            continue
        feats.append({
            "type": "Feature",
            "geometry": {"type": "Point", "coordinates": [round(p.lon_deg, 7), round(p.lat_deg, 7)]},
            "properties": {"kind": "estimate", **_properties(p, epoch_unix_s)},
        })
        if frame is not None and math.isfinite(p.radius95_m) and p.radius95_m > 0:
            ring = _circle_latlon(frame, p.east_m, p.north_m, p.radius95_m)
            feats.append({
                "type": "Feature",
                "geometry": {"type": "Polygon",
                             "coordinates": [[[round(float(lo), 7), round(float(la), 7)] for la, lo in ring]]},
                "properties": {"kind": "circle95", "label": p.label, "emitter_id": p.emitter_id,
                               "state": p.state, "radius95_m": _clean(p.radius95_m, 2),
                               "time_utc": utc_text(epoch_unix_s, p.t_ref_s) or None},
            })
    for eid, (lat, lon) in sorted((truth_latlon or {}).items()):
        feats.append({
            "type": "Feature",
            "geometry": {"type": "Point", "coordinates": [round(float(lon), 7), round(float(lat), 7)]},
            "properties": {"kind": "truth", "emitter_id": int(eid)},
        })
    out = {"type": "FeatureCollection", "features": feats}
    if epoch_unix_s is not None:
        out["time_utc_clock"] = clock_label(epoch_unix_s)  # which clock the UTC times are (issue 42)
    if coverage is not None and frame is not None:
        feats[:0] = coverage.cells_geojson_features(frame)  # under the people in a GIS
        out["coverage"] = {**coverage.to_dict(), "statement": coverage.sentence()}
    return json.dumps(out, indent=1) + "\n"


def _circle_latlon(frame: LocalFrame, e: float, n: float, r: float, k: int = 36) -> np.ndarray:
    a = np.linspace(0, 2 * np.pi, k + 1)
    return frame.to_wgs84_latlon(np.column_stack([e + r * np.cos(a), n + r * np.sin(a)]))


# KML colours are aabbggrr
_KML_STYLE = {"located": "ff2ca02c", "heard": "ff0e7fff", "given up": "ff2827d6", "never heard": "ff7f7f7f"}


def people_kml(people: Sequence[PersonResult], frame: LocalFrame, name: str = "uavloc", *,
               epoch_unix_s: float | None = None, coverage=None) -> str:
    """KML for Google Earth: a placemark per person and its 95 % circle, each with a TimeStamp
    (the UTC time the position refers to) so the time slider works; colour by state. With
    ``coverage``: the document's description states what was searched, and a folder "achieved POD"
    holds one square per cell, shaded from red (POD 0, unsearched) to green (the target reached)."""
    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           '<kml xmlns="http://www.opengis.net/kml/2.2"><Document>',
           f"<name>{escape(name)}</name>"]
    if coverage is not None:
        out.append(f"<description>{escape(coverage.sentence())}</description>")
        out.append(_kml_cells(coverage, frame))
    for state, color in _KML_STYLE.items():
        sid = state.replace(" ", "-")
        out.append(f'<Style id="{sid}"><IconStyle><color>{color}</color></IconStyle>'
                   f"<LineStyle><color>{color}</color><width>2</width></LineStyle>"
                   f"<PolyStyle><color>33{color[2:]}</color></PolyStyle></Style>")
    for p in _order(people):
        if not (math.isfinite(p.lat_deg) and math.isfinite(p.lon_deg)):
            continue
        when = utc_text(epoch_unix_s, p.t_ref_s)
        stamp = f"<TimeStamp><when>{when}</when></TimeStamp>" if when else ""
        style = f"<styleUrl>#{p.state.replace(' ', '-')}</styleUrl>"
        state = "located" if p.located else f"{p.state}: {p.reason}" if p.reason else p.state
        desc = (f"{state}; 95 % radius {_num(p.radius95_m, 1)} m; position at {when or '?'} {clock_label(epoch_unix_s)} "
                f"(mission {_num(p.t_ref_s, 1)} s); velocity east {_num(p.vel_east_m_s, 2)} m/s, "
                f"north {_num(p.vel_north_m_s, 2)} m/s; heard under {format_addresses(p.address_list, ', ')}"
                + (f"; link uncertain: {p.link_reason}" if p.link_reason else ""))
        data = "".join(f'<Data name="{k}"><value>{escape(_kml_value(v))}</value></Data>'
                       for k, v in _properties(p, epoch_unix_s).items())
        out.append(f"<Placemark><name>{escape(p.name)}</name>{stamp}{style}"
                   f"<description>{escape(desc)}</description><ExtendedData>{data}</ExtendedData>"
                   f"<Point><coordinates>{p.lon_deg:.7f},{p.lat_deg:.7f},0</coordinates></Point></Placemark>")
        if math.isfinite(p.radius95_m):
            ring = _circle_latlon(frame, p.east_m, p.north_m, p.radius95_m)
            coords = " ".join(f"{lon:.7f},{lat:.7f},0" for lat, lon in ring)
            out.append(f"<Placemark><name>{escape(p.name)} 95 %</name>{stamp}{style}<Polygon><outerBoundaryIs>"
                       f"<LinearRing><coordinates>{coords}</coordinates></LinearRing></outerBoundaryIs>"
                       "</Polygon></Placemark>")
    out.append("</Document></kml>")
    return "\n".join(out) + "\n"


def _kml_cells(coverage, frame: LocalFrame) -> str:
    """The POD layer: a folder of cell squares (ExtendedData pod, pod2), colour by POD."""
    parts = ['<Folder><name>achieved POD</name>']
    for feat in coverage.cells_geojson_features(frame):
        prop = feat["properties"]
        ring = " ".join(f"{lon:.7f},{lat:.7f},0" for lon, lat in feat["geometry"]["coordinates"][0])
        r, g, b = _pod_rgb(prop["pod"], coverage.target)
        color = f"88{b:02x}{g:02x}{r:02x}"  # aabbggrr
        parts.append(f"<Placemark><name>POD {prop['pod']:.2f}</name><Style><LineStyle><width>0</width></LineStyle>"
                     f"<PolyStyle><color>{color}</color><outline>0</outline></PolyStyle></Style>"
                     f'<ExtendedData><Data name="pod"><value>{prop["pod"]}</value></Data>'
                     f'<Data name="pod2"><value>{prop["pod2"]}</value></Data>'
                     f'<Data name="unsearched"><value>{str(prop["unsearched"]).lower()}</value></Data></ExtendedData>'
                     f"<Polygon><outerBoundaryIs><LinearRing><coordinates>{ring}</coordinates></LinearRing>"
                     "</outerBoundaryIs></Polygon></Placemark>")
    parts.append("</Folder>")
    return "".join(parts)


def _pod_rgb(pod: float, target: float) -> tuple[int, int, int]:
    """Red (POD 0) through yellow to green (the target or more): the POD layers' colour."""
    f = min(1.0, max(0.0, pod / target)) if target > 0 else 1.0
    if f < 0.5:
        return 214, int(39 + (190 - 39) * f * 2), 40
    return int(214 - (214 - 44) * (f - 0.5) * 2), int(190 - (190 - 160) * (f - 0.5) * 2), int(40 + (44 - 40) * (f - 0.5) * 2)


def _kml_value(v) -> str:
    if v is None:
        return ""
    return ";".join(map(str, v)) if isinstance(v, list) else str(v)


BY_MINUTES = (15, 30, 60)  # the times results.txt counts the people located by


def results_table(people: Sequence[PersonResult], required_accuracy_m: float,
                  truth_xy_m: Mapping[int, Sequence[float]] | None = None, *,
                  epoch_unix_s: float | None = None, coverage=None, notes: Sequence[str] = ()) -> str:
    """A plain-text table for the terminal, with the error to the truth when simulated; ``notes``:
    sentences after it (the sorties flown and packs left, issue 38)."""
    width = max([13, *(len(p.name) for p in people)])
    head = f"{'person':<{width}}  {'lat':>11}  {'lon':>11}  {'95% r':>7}  {'at (UTC)':>10}  {'status':<10}"
    if truth_xy_m:
        head += f"  {'true error':>10}"
    lines = [head, "-" * len(head)]
    for p in _order(people):
        at = utc_text(epoch_unix_s, p.t_ref_s)[11:21] or "-"
        row = (f"{p.name:<{width}}  {_num(p.lat_deg, 6):>11}  {_num(p.lon_deg, 6):>11}  "
               f"{_num(p.radius95_m, 1) + ' m' if math.isfinite(p.radius95_m) else '-':>7}  {at:>10}  {p.state:<10}")
        if truth_xy_m:
            t = truth_xy_m.get(p.emitter_id)
            err = math.hypot(p.east_m - t[0], p.north_m - t[1]) if t is not None and math.isfinite(p.east_m) else math.nan
            row += f"  {_num(err, 1) + ' m' if math.isfinite(err) else '-':>10}"
        if not p.located and p.reason:
            row += f"  ({p.reason})"
        lines.append(row)
    n_ok = sum(p.located for p in people)
    from .outcome import radio_note  # noqa: PLC0415

    heard = [p for p in people if p.state != "never heard"]
    never = len(people) - len(heard)  # rows only a simulation has: its people no vehicle heard
    lines.append(f"{n_ok} of {len(people)} people located within {required_accuracy_m:g} m (95 %)"
                 + (f"; {len(heard)} heard, {never} never heard." if never else ".") + radio_note(heard))
    by = located_by_text(people)
    if by:
        lines.append(by)
    if isinstance(epoch_unix_s, MissionClock) and epoch_unix_s.simulated:
        lines.append(f"Times: {epoch_unix_s.label}.")
    if coverage is not None:
        lines.append(coverage.sentence())
    lines.extend(notes)
    return "\n".join(lines) + "\n"


def located_by_text(people: Sequence[PersonResult]) -> str:
    """Time is the figure (issue 38 item 4): "Located by 15 / 30 / 60 min of mission time: a / b / c
    of N." ("" when nobody is located: the count before it says so)."""
    if not any(p.located for p in people):
        return ""
    by = [sum(p.located and math.isfinite(p.fix_time_s) and p.fix_time_s <= m * 60.0 for p in people)
          for m in BY_MINUTES]
    return (f"Located by {' / '.join(str(m) for m in BY_MINUTES)} min of mission time: "
            f"{' / '.join(str(n) for n in by)} of {len(people)}.")


def write_results(out_dir: str | Path, people: Sequence[PersonResult], *, frame: LocalFrame,
                  area_latlon_deg: np.ndarray, tracks_latlon_deg: Mapping[int, np.ndarray],
                  required_accuracy_m: float, truth_xy_m: Mapping[int, Sequence[float]] | None = None,
                  name: str = "uavloc", epoch_unix_s: float | None = None, coverage=None,
                  terrain=None, fence_latlon_deg=None, notes: Sequence[str] = ()) -> list[Path]:
    """Write people.csv, people.geojson, people.kml, result.png and results.txt into ``out_dir``.
    ``epoch_unix_s``: a ``service.clock.MissionClock`` (or the UNIX time of mission time 0, the
    vehicles' clock taken as real time): the UTC times in the files (omitted when None).
    ``coverage`` (search.coverage.CoverageSummary): what was searched, in every file (the POD
    cells in the GeoJSON, KML and picture, the statement in results.txt)."""
    from ..atomicfile import atomic_write_text

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    truth_latlon = None
    if truth_xy_m:
        ids = sorted(truth_xy_m)
        ll = frame.to_wgs84_latlon(np.array([truth_xy_m[i][:2] for i in ids], dtype=float))
        truth_latlon = {i: (float(a), float(b)) for i, (a, b) in zip(ids, ll)}
    files = {
        "people.csv": people_csv(people, epoch_unix_s),
        "people.geojson": people_geojson(people, truth_latlon, epoch_unix_s=epoch_unix_s, frame=frame,
                                         coverage=coverage),
        "people.kml": people_kml(people, frame, name, epoch_unix_s=epoch_unix_s, coverage=coverage),
        "results.txt": results_table(people, required_accuracy_m, truth_xy_m, epoch_unix_s=epoch_unix_s,
                                     coverage=coverage, notes=notes),
    }
    written = []
    for fname, text in files.items():
        atomic_write_text(out / fname, text)
        written.append(out / fname)
    png = out / "result.png"
    render_result_png(png, people, frame=frame, area_latlon_deg=area_latlon_deg,
                      tracks_latlon_deg=tracks_latlon_deg, truth_xy_m=truth_xy_m, title=name,
                      epoch_unix_s=epoch_unix_s, coverage=coverage, terrain=terrain,
                      fence_latlon_deg=fence_latlon_deg, notes=notes)
    written.append(png)
    return written


def render_result_png(path: Path, people: Sequence[PersonResult], *, frame: LocalFrame,
                      area_latlon_deg: np.ndarray, tracks_latlon_deg: Mapping[int, np.ndarray],
                      truth_xy_m: Mapping[int, Sequence[float]] | None, title: str,
                      epoch_unix_s: float | None = None, coverage=None, terrain=None,
                      fence_latlon_deg=None, notes: Sequence[str] = ()) -> None:
    """The result map in local metres (``render.estimates.result_figure``); ``fence_latlon_deg``:
    the scenario's geofence, if it gives one. The caption says what results.txt says under its
    table: the people located by time, what was searched and ``notes`` (the sorties flown)."""
    from ..render import maps  # noqa: PLC0415
    from ..render.estimates import result_figure  # noqa: PLC0415

    area = frame.to_local_xy(np.asarray(area_latlon_deg, dtype=float))
    tracks = {v: frame.to_local_xy(np.asarray(t, dtype=float)) for v, t in tracks_latlon_deg.items() if len(t)}
    caption = maps.origin_caption(*frame.to_wgs84(0.0, 0.0))
    times = [utc_text(epoch_unix_s, p.t_ref_s) for p in people]
    times = sorted(t for t in times if t)
    if times:
        caption += f"\npositions at {times[0][:19].replace('T', ' ')} to {times[-1][11:19]} {clock_label(epoch_unix_s)}"
    by = located_by_text(people)
    if by:
        caption += "\n" + by
    if coverage is not None:
        caption += "\n" + coverage.sentence()
    for note in notes:
        if note:
            caption += "\n" + note
    fig = result_figure(people, area_xy_m=area, tracks_xy_m=tracks, truth_xy_m=truth_xy_m, title=title,
                        subtitle=caption, coverage=coverage, terrain=terrain,
                        fence_xy_m=(frame.to_local_xy(np.asarray(fence_latlon_deg, dtype=float))
                                    if fence_latlon_deg is not None and len(fence_latlon_deg) else None))
    maps.save_figure(fig, path)
