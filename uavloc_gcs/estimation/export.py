"""Estimates as CSV and GeoJSON text (deterministic, for ``uavloc localize``).

CSV columns: ``emitter_id, lat_deg, lon_deg, vel_east_m_s, vel_north_m_s, radius95_m,
annulus_bound_m, t_ref_s, ambiguous, mirror_lat_deg, mirror_lon_deg`` (the mirror only when
ambiguous), then ``mirror_relative_likelihood, status, n_slots``, then who the person is on the
air: ``addresses`` (the 802.11 addresses they were heard under, ';'-separated MACs, first heard
first; the emitter id is the first), ``link`` ('sure' or 'uncertain') and ``link_reason``
(:mod:`.identity`). Unknown values (no estimate yet, an infinite radius, an empty ring
intersection) are empty cells.
"""

from __future__ import annotations

import csv
import io
import math
from typing import Mapping

import numpy as np

from ..geo import LocalFrame
from ..observations import SlotBatch
from .estimate import Estimate
from .identity import Linking, format_addresses

CSV_COLUMNS = ("emitter_id", "lat_deg", "lon_deg", "vel_east_m_s", "vel_north_m_s", "radius95_m",
               "annulus_bound_m", "t_ref_s", "ambiguous", "mirror_lat_deg", "mirror_lon_deg",
               "mirror_relative_likelihood", "status", "n_slots", "addresses", "link", "link_reason")
TRACK_GAP_S = 2.0


def _num(x, nd: int) -> str:
    return "" if x is None or not math.isfinite(float(x)) else f"{float(x):.{nd}f}"


def _clean(x, nd: int):
    return None if x is None or not math.isfinite(float(x)) else round(float(x), nd)


def identity_fields(eid: int, linking: Linking | None) -> tuple[list[int], str, str]:
    """A person's addresses, 'sure'/'uncertain' and the reason (''), from ``linking``; without one
    the emitter id is the address (old logs, the paper's world)."""
    if linking is None or not linking.addresses(eid):
        return [int(eid)], "sure", ""
    why = linking.uncertain(eid)
    return linking.addresses(eid), "uncertain" if why else "sure", why or ""


def estimates_csv(estimates: Mapping[int, Estimate], frame: LocalFrame, linking: Linking | None = None) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for eid in sorted(estimates):
        e = estimates[eid]
        lat, lon = frame.to_wgs84(*e.position_xy_m) if np.all(np.isfinite(e.position_xy_m)) else (math.nan,) * 2
        mlat = mlon = rel = math.nan
        if e.ambiguous and e.mirror is not None:
            mlat, mlon = frame.to_wgs84(*e.mirror.position_xy_m)
            rel = e.mirror.relative_likelihood
        addresses, state, why = identity_fields(eid, linking)
        w.writerow([eid, _num(lat, 8), _num(lon, 8), _num(e.velocity_m_s[0], 3), _num(e.velocity_m_s[1], 3),
                    _num(e.radius95_m, 2), _num(e.annulus_bound_m, 2), _num(e.t_ref_s, 3), int(e.ambiguous),
                    _num(mlat, 8), _num(mlon, 8), _num(rel, 4), e.status, e.n_slots, format_addresses(addresses),
                    state, why])
    return buf.getvalue()


def estimates_geojson(estimates: Mapping[int, Estimate], frame: LocalFrame, slots: SlotBatch | None = None,
                      linking: Linking | None = None) -> str:
    """A FeatureCollection: per emitter its estimate (Point; with its ``addresses`` as MACs,
    ``link`` and ``link_reason``), 95 % circle (Polygon) and, when ambiguous, the mirror candidate
    (Point); per vehicle the positions where it heard anyone."""
    from mission_io import geojson as gj

    feats = []
    for eid in sorted(estimates):
        e = estimates[eid]
        if not e.ok:
            continue
        lat, lon = frame.to_wgs84(*e.position_xy_m)
        props = dict(kind="estimate", emitter_id=eid, radius95_m=_clean(e.radius95_m, 2),
                     annulus_bound_m=_clean(e.annulus_bound_m, 2), vel_east_m_s=_clean(e.velocity_m_s[0], 3),
                     vel_north_m_s=_clean(e.velocity_m_s[1], 3), t_ref_s=_clean(e.t_ref_s, 3),
                     ambiguous=bool(e.ambiguous), n_slots=int(e.n_slots), marker_color="#d62728")
        addresses, state, why = identity_fields(eid, linking)
        props.update(addresses=format_addresses(addresses).split(";"), link=state, link_reason=why or None)
        feats.append(gj.feature(gj.point(float(lat), float(lon)), **props))
        if math.isfinite(e.radius95_m) and e.radius95_m > 0:
            ring = _circle(e.position_xy_m, e.radius95_m)
            feats.append(gj.feature(gj.polygon(frame.to_wgs84_latlon(ring).tolist()), kind="radius95",
                                    emitter_id=eid, stroke="#d62728", fill="#d62728", fill_opacity=0.15))
        if e.ambiguous and e.mirror is not None:
            mlat, mlon = frame.to_wgs84(*e.mirror.position_xy_m)
            feats.append(gj.feature(gj.point(float(mlat), float(mlon)), kind="mirror", emitter_id=eid,
                                    relative_likelihood=_clean(e.mirror.relative_likelihood, 4),
                                    marker_color="#ff7f0e"))
    for vehicle, segments in heard_tracks(slots).items() if slots is not None else ():
        lines = [frame.to_wgs84_latlon(seg).tolist() for seg in segments]
        feats.append(gj.feature(gj.multilinestring(lines), kind="track", vehicle_id=int(vehicle), stroke="#1f77b4"))
    return gj.dumps(gj.feature_collection(feats, name="uavloc estimates"))


def heard_tracks(slots: SlotBatch, *, max_points: int = 400) -> dict[int, list[np.ndarray]]:
    """Per vehicle, the ground positions (E, N) of its slots, split where it heard nothing for
    more than TRACK_GAP_S; thinned to about ``max_points`` per vehicle."""
    out: dict[int, list[np.ndarray]] = {}
    for v in np.unique(slots.vehicle):
        s = slots.take(slots.vehicle == v).sorted_by_time()
        t, xy = np.unique(s.t_s, return_index=True)[0], s.xyz_m[np.unique(s.t_s, return_index=True)[1], :2]
        cuts = np.nonzero(np.diff(t) > TRACK_GAP_S)[0] + 1
        step = max(1, len(t) // max_points)
        out[int(v)] = [seg[::step] if len(seg) > 2 * step else seg for seg in np.split(xy, cuts) if len(seg) >= 2]
    return out


def _circle(center, r: float, k: int = 48) -> np.ndarray:
    a = np.linspace(0.0, 2.0 * np.pi, k, endpoint=False)
    return np.asarray(center) + r * np.column_stack([np.cos(a), np.sin(a)])
