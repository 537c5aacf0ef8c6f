"""``uavloc preview FILE [--png OUT]``: a terminal picture and item table of a .plan/.waypoints."""

from __future__ import annotations

from ._inputs import number

import argparse
import math
from pathlib import Path

HELP = "show a .plan or .waypoints mission in the terminal (and optionally as a picture)"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("preview", help=HELP, description=HELP + ".")
    p.add_argument("file", metavar="FILE", help="a QGroundControl .plan or a QGC WPL 110 .waypoints file")
    p.add_argument("--png", metavar="OUT", help="also draw the mission to OUT (.png or .svg)")
    p.add_argument("--width", type=number(int, min=20, max=1000), default=72, help="width of the terminal picture in columns (default 72)")
    p.add_argument("--no-table", action="store_true", help="omit the item table")
    p.set_defaults(func=run)


def load_mission(path: str | Path):
    """Read a mission file, choosing the format by suffix or, failing that, by content."""
    from mission_io import mission_file

    return mission_file.read(path)


def _names(enum: str) -> dict[int, str]:
    from ..dialect import mavlink

    prefix = enum + "_"
    return {k: e.name[len(prefix):] if e.name.startswith(prefix) else e.name
            for k, e in mavlink.enums.get(enum, {}).items()}


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from mission_io.mission_file import PLAN

    from ..energy import path_length_m
    from ..errors import ConfigError
    from ..mission import NAV_WAYPOINT
    from ..render.mission_view import circle_ring, mission_view
    from ..render.terminal import Layer, char_map

    if args.width < 20:
        raise ConfigError(f"--width must be at least 20 columns, got {args.width}")
    if args.png is not None:
        from ._output import check_output_file

        check_output_file(args.png, "--png")
        if Path(args.png).suffix.lower() not in (".png", ".svg"):
            raise ConfigError(f"--png {args.png}: the picture must end in .png or .svg")
    mission, kind = load_mission(args.file)
    view = mission_view(mission)
    # WPL 110 does not record the autopilot; a .plan does (mission.firmwareType).
    ap = ("ArduPilot" if mission.autopilot == "ardupilot" else "PX4") if kind == PLAN else "autopilot not recorded"
    n_wp = sum(1 for it in mission.items if it.command == NAV_WAYPOINT)
    holds = sum(1 for it in mission.items if it.command == NAV_WAYPOINT and it.params[0] > 0)
    hold_text = "" if n_wp == 0 else (" (all pass-through)" if holds == 0 else f" ({holds} with a hold)")
    print(f"{args.file}: {kind}, {ap}, {len(mission.items)} item(s), {n_wp} waypoint(s){hold_text}")
    if view.has_home:
        alt = "unknown AMSL altitude" if math.isnan(mission.home_alt_m) else f"{mission.home_alt_m:g} m AMSL"
        print(f"home {mission.home_lat_deg:.7f}, {mission.home_lon_deg:.7f} ({alt})")
    else:
        print("home not in the file (the vehicle's own home is used)")
    if view.placeholders:
        print(f"{view.placeholders} item(s) with lat/lon 0, 0 (\"here\", not a place) are not drawn")
    extras = _extras_text(mission)
    if extras:
        print(extras)

    if len(view.route_xy) >= 2:
        speed = mission.cruise_speed_m_s
        length = path_length_m(view.route_xy)
        timing = f", about {length / speed / 60:.1f} min at {speed:g} m/s" if speed else ""
        print(f"route {length / 1000:.2f} km{' from home' if view.has_home else ''}{timing}")
    print()
    layers = []
    for inclusion, ring in view.fences:
        layers.append(Layer(ring, "." if inclusion else "x", "ring",
                            name="geofence" if inclusion else "exclusion fence"))
    for inclusion, centre, radius in view.circles:
        layers.append(Layer(circle_ring(centre, radius), "." if inclusion else "x", "ring",
                            name="geofence circle" if inclusion else "exclusion circle"))
    if len(view.route_xy) >= 2:
        layers.append(Layer(view.route_xy, "*", "line", name="route"))
    if len(view.rally_xy):
        layers.append(Layer(view.rally_xy, "R", "points", name="rally point"))
    if len(view.points_xy):
        layers.append(Layer(view.points_xy, "o", "points", labels=view.marks, name="waypoint"))
    if view.has_home:
        layers.append(Layer(np.zeros((1, 2)), "H", "points", name="home"))
    if layers and (len(view.points_xy) or view.fences or view.circles or len(view.rally_xy)):
        print(char_map(layers, width=args.width))
    else:
        print("(no positional items to draw)")
    if not args.no_table:
        print()
        print(item_table(mission))
    if args.png:
        _picture(args, view)
        print(f"\nWrote {args.png}")
    return 0


def _extras_text(mission) -> str:
    parts = []
    inc = sum(1 for i, _ in mission.geofence_polygons if i) + sum(1 for i, _, _ in mission.geofence_circles if i)
    exc = len(mission.geofence_polygons) + len(mission.geofence_circles) - inc
    if inc or exc:
        parts.append(f"geofence: {inc} inclusion, {exc} exclusion zone(s)")
    if mission.rally_points:
        parts.append(f"{len(mission.rally_points)} rally point(s)")
    return "; ".join(parts)


def item_table(mission) -> str:
    """One row per item: number (home = 0), command, frame, position, hold, speed/params. Items
    without a real position (the 0, 0 placeholder, null, or a non-global frame) show none."""
    from ..mission import DO_CHANGE_SPEED, GLOBAL_FRAMES, NAV_WAYPOINT
    from ..render.terminal import format_table

    cmds, frames = _names("MAV_CMD"), _names("MAV_FRAME")
    rows = []
    if not math.isnan(mission.home_lat_deg):
        rows.append([0, "home", "", f"{mission.home_lat_deg:.7f}", f"{mission.home_lon_deg:.7f}",
                     "" if math.isnan(mission.home_alt_m) else f"{mission.home_alt_m:g}", ""])
    for k, it in enumerate(mission.items, start=1):
        placed = it.has_position
        if it.command == NAV_WAYPOINT:
            note = f"hold {it.params[0]:g} s" + (" (pass-through)" if it.params[0] == 0 else "")
        elif it.command == DO_CHANGE_SPEED:
            note = f"speed {it.params[1]:g} m/s"
        else:
            note = " ".join(f"{p:g}" for p in it.params if not math.isnan(p) and p != 0)
        lat, lon = (f"{it.lat_deg:.7f}", f"{it.lon_deg:.7f}") if placed else \
            (("here", "") if it.frame in GLOBAL_FRAMES and it.lat_deg == 0.0 and it.lon_deg == 0.0 else ("", ""))
        alt = f"{it.alt_m:g}" if it.frame in GLOBAL_FRAMES and math.isfinite(it.alt_m) else ""
        rows.append([k, cmds.get(it.command, str(it.command)), frames.get(it.frame, str(it.frame)), lat, lon, alt,
                     note])
    return format_table(["#", "command", "frame", "lat", "lon", "alt m", "notes"], rows)


def _picture(args, view) -> None:
    from ..render.maps import origin_caption, save_figure
    from ..render.scan_plot import mission_figure

    sub = origin_caption(*view.origin) if view.origin else None
    fig = mission_figure([view.route_xy if len(view.route_xy) >= 2 else view.points_xy], [Path(args.file).name],
                         title=f"Mission {Path(args.file).name}", subtitle=sub,
                         fences=view.fences, circles=view.circles, rally_xy=view.rally_xy,
                         home=view.has_home, points_xy=view.points_xy, marks=view.marks)
    save_figure(fig, args.png)
