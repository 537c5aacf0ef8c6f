"""``uavloc localize INPUT --scenario SCENARIO.toml --out DIR``: offline localization.

INPUT is a slot CSV (``t_s,vehicle_id,lat_deg,lon_deg,alt_m,emitter_id,rssi_dbm,n_samples``, optionally
``address,fingerprint,channel``) or a ``.tlog`` whose UAVLOC_RSSI_BATCH2 and (older) UAVLOC_RSSI_BATCH
messages are replayed. The addresses heard are first linked into people
(:mod:`uavloc_gcs.estimation.identity`; the identity for old inputs, where every address is stable),
then every person is estimated. Writes ``estimates.csv``, ``estimates.geojson`` (each person with
the addresses they were heard under and whether the link is uncertain) and ``estimates.png`` into
DIR (all or nothing) and prints a table.
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
from pathlib import Path

from ._inputs import number

log = logging.getLogger(__name__)

T_REF_MARGIN_S = 3600.0  # --t-ref this far outside the slots' times: a walker's circle is kilometres wide
# Slots farther than this outside the scenario's area are from another place (a wrong --scenario):
# a phone is heard a few hundred metres away at most (Wi2SAR: about 300 m in line of sight, SPEC
# 1.1), and vehicles fly from a launch point near the area.
FAR_FROM_AREA_M = 5000.0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "localize",
        help="estimate people's positions from recorded RSSI slots (CSV or .tlog)",
        description="Estimate every emitter heard in INPUT (a slot CSV or a .tlog) and write "
                    "estimates.csv, estimates.geojson and estimates.png into --out.",
    )
    p.add_argument("input", metavar="INPUT", help="slot CSV (t_s,vehicle_id,lat_deg,lon_deg,alt_m,emitter_id,"
                                                  "rssi_dbm,n_samples[,address,fingerprint,channel]) or a .tlog; "
                                                  "the shipped example by name: slots_small.csv")
    p.add_argument("--scenario", required=True,
                   help="scenario TOML (channel, people's speed bound, frame), or a shipped one by name: paper, small")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--static", action="store_true", help="assume people do not move (the paper's NM variant)")
    p.add_argument("--tx-power", action="store_true",
                   help="estimate each phone's transmit power offset (default: channel.estimate_tx_power)")
    p.add_argument("--t-ref", type=number(float), default=None, metavar="T_S",
                   help="report positions at this time [s], within an hour of the slots "
                        "(default: each emitter's last slot)")
    p.set_defaults(func=run)


def load_slots(path: Path, scenario):
    """Slots from a CSV or a .tlog, in the scenario's frame, with their address, fingerprint and
    channel where the input has them. For a .tlog, t_s counts from the whole second of its first
    RSSI message (either version)."""
    from ..errors import FileFormatError
    from ..estimation.slots_csv import read_slots_csv

    if not path.exists():
        raise FileFormatError("file not found", path=str(path))
    if path.is_dir():
        raise FileFormatError("is a directory; give a slot CSV or a .tlog file", path=str(path))
    if path.suffix.lower() == ".tlog":
        from ..dialect.rssi import decode_rssi_batches, is_rssi_message
        from ..link.tlog import iter_tlog

        try:
            every = [m for _, m in iter_tlog(path)]
        except OSError as exc:
            raise FileFormatError(f"cannot read the file ({exc.strerror})", path=str(path)) from None
        msgs = [m for m in every if is_rssi_message(m)]
        if not msgs:
            if path.stat().st_size == 0:
                raise FileFormatError("is empty: nothing to localize", path=str(path))
            raise FileFormatError(f"holds {len(every)} MAVLink message(s) but no UAVLOC_RSSI_BATCH2 or "
                                  "UAVLOC_RSSI_BATCH: nothing to localize (was the companion's RSSI routed to this "
                                  "log?)", path=str(path))
        epoch = math.floor(min(m.time_usec for m in msgs) / 1e6)
        return decode_rssi_batches(msgs, scenario.frame, epoch_unix_s=epoch)
    slots = read_slots_csv(path, scenario.frame)
    if not len(slots):
        raise FileFormatError("has the header but no slots: nothing to localize", path=str(path))
    return slots


def far_from_area_warning(slots, scenario, name: str) -> str | None:
    """A sentence when slots lie more than FAR_FROM_AREA_M outside the scenario's area (how many,
    and how far), else None."""
    import numpy as np
    import shapely

    area = shapely.Polygon(scenario.area_xy_m())
    d = shapely.distance(area, shapely.points(np.asarray(slots.xyz_m)[:, :2]))
    far = d > FAR_FROM_AREA_M
    if not far.any():
        return None
    lo, hi = float(d[far].min()), float(d[far].max())
    span = _km(hi) if _km(lo) == _km(hi) else f"{_km(lo)} to {_km(hi)}"
    return (f"warning: {int(far.sum())} of {len(d)} slots in {name} lie {span} km from the area of "
            f"{scenario.source} (more than {FAR_FROM_AREA_M / 1000:g} km): were they recorded in another "
            "scenario? Estimating anyway.")


def _km(m: float) -> str:
    return f"{m / 1000:.0f}" if m >= 10_000 else f"{m / 1000:.1f}"


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from ..estimation import ChannelModel, airborne_slots, estimate_all
    from ..heights import airborne_floor_m, planned_look_alt_m
    from ..estimation.export import estimates_csv, estimates_geojson, heard_tracks
    from ..estimation.identity import UNKNOWN_TX_MARGIN_DB, format_address, link
    from ..geo import polygon_area_m2
    from ..render.maps import origin_caption, save_figure
    from ..render.estimates import estimate_labels, estimates_figure
    from ..render.terminal import format_table
    from ..errors import FileFormatError
    from ..examples import shipped_path
    from ..scenario import load_scenario
    from ._output import atomic_output_dir, check_output_dir

    check_output_dir(args.out, "--out")  # before any work: a directory that cannot be written
    sc = load_scenario(args.scenario)
    source = shipped_path(args.input, ".csv")  # a file, or a shipped one by name (slots_small.csv)
    heard = load_slots(source, sc)
    # as the daemon does: slots heard taking off, landing or on the ground are not estimated from,
    # each judged by its own height (a look flies lower than the scan: uavloc_gcs/heights.py)
    floor = airborne_floor_m(sc)
    slots = airborne_slots(heard, floor, sc.dem)
    low = len(heard) - len(slots)
    if not len(slots):
        look = planned_look_alt_m(sc)
        raise FileFormatError(f"all {len(heard)} slots were heard below {floor:g} m above the ground (taking off, "
                              f"landing or on the ground; the scenario's scan flies at {sc.fleet.altitude_m:g} m"
                              + (f", its looks at {look:g} m" if look < sc.fleet.altitude_m else "")
                              + "): nothing to localize", path=str(source))
    if warning := far_from_area_warning(slots, sc, source.name):
        print(warning, file=sys.stderr)
    if args.t_ref is not None and len(slots.t_s):
        t0, t1 = float(slots.t_s.min()), float(slots.t_s.max())
        if not t0 - T_REF_MARGIN_S <= args.t_ref <= t1 + T_REF_MARGIN_S:
            from ..errors import ConfigError

            raise ConfigError(f"--t-ref {args.t_ref:g}: must be within an hour of the slots' times "
                              f"({t0:.1f}..{t1:.1f} s in {source.name})")
    channel = ChannelModel.from_scenario(sc)
    tx_power = args.tx_power or sc.channel.estimate_tx_power
    # the addresses heard, linked into people (the identity when every address is stable or no
    # fingerprint is known, as in old logs and the paper's world); real phones differ in transmit
    # power by several dB (SPEC 1), so the range bounds allow for it
    linking = link(slots, channel, max_speed_m_s=sc.people.max_speed_m_s, area_m2=polygon_area_m2(sc.area_xy_m()),
                   tx_margin_db=UNKNOWN_TX_MARGIN_DB)
    estimates = estimate_all(linking.slots, channel, max_speed_m_s=sc.people.max_speed_m_s, t_ref_s=args.t_ref,
                             model_motion=not args.static, estimate_tx_power=tx_power)
    tracks = heard_tracks(slots)
    with atomic_output_dir(args.out) as tmp:
        (tmp / "estimates.csv").write_text(estimates_csv(estimates, sc.frame, linking), encoding="utf-8")
        (tmp / "estimates.geojson").write_text(estimates_geojson(estimates, sc.frame, slots, linking),
                                               encoding="utf-8")
        fig = estimates_figure(estimates, area_xy_m=sc.area_xy_m(), tracks_xy_m=tracks,
                               title=f"Localization: {source.name}",
                               subtitle=origin_caption(*sc.launch_latlon_deg))
        save_figure(fig, tmp / "estimates.png")
    rows = []
    on_map = iter(estimate_labels(estimates))  # the labels of estimates.png
    for eid, e in sorted(estimates.items()):
        lat, lon = sc.frame.to_wgs84(*e.position_xy_m) if e.ok else (math.nan, math.nan)
        rows.append([next(on_map) if e.ok else "", eid, e.status, f"{lat:.6f}" if e.ok else "", f"{lon:.6f}" if e.ok else "",
                     f"{np.hypot(*e.velocity_m_s):.2f}" if e.ok else "", _r(e.radius95_m), _r(e.annulus_bound_m),
                     "yes" if e.ambiguous else "", e.n_slots, _addresses_cell(linking.addresses(eid), format_address),
                     "uncertain" if linking.uncertain(eid) else ""])
    print(format_table(["map", "emitter", "status", "lat", "lon", "speed m/s", "r95 m", "annulus m", "mirror?", "slots",
                        "addresses", "link"],
                       rows, title=f"{len(slots)} slots, {len(estimates)} emitter(s)" + (
                           f" ({low} slots heard below {floor:g} m, taking off or landing, not used)" if low
                           else "")))
    n_addr = len(np.unique(slots.address))
    unsure = [p for p in linking.people() if linking.uncertain(p)]
    print(f"{n_addr} address(es) heard, linked into {len(linking.people())} people"
          + (f"; uncertain links: {len(unsure)} (see the link_reason column)" if unsure else ""))
    for p in unsure[:5]:
        print(f"  {p}: {linking.uncertain(p)}")
    print(f"wrote {Path(args.out) / 'estimates.csv'}, estimates.geojson, estimates.png")
    return 0


def _addresses_cell(addresses: list[int], fmt) -> str:
    """The first address as a MAC, with how many more (the CSV has them all)."""
    if not addresses:
        return ""
    return fmt(addresses[0]) + (f" (+{len(addresses) - 1})" if len(addresses) > 1 else "")


def _r(x: float) -> str:
    return f"{x:.1f}" if math.isfinite(x) else "-"
