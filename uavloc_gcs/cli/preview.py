"""``uavloc preview FILE [--png OUT]``: a terminal picture and item table of a .plan/.waypoints."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

HELP = "show a .plan or .waypoints mission in the terminal (and optionally as a picture)"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("preview", help=HELP, description=HELP + ".")
    p.add_argument("file", metavar="FILE", help="a QGroundControl .plan or a QGC WPL 110 .waypoints file")
    p.add_argument("--png", metavar="OUT", help="also draw the mission to OUT (.png or .svg)")
    p.add_argument("--width", type=int, default=72, help="width of the terminal picture in columns (default 72)")
    p.add_argument("--no-table", action="store_true", help="omit the item table")
    p.set_defaults(func=run)


def load_mission(path: str | Path):
    """Read a mission file, choosing the format by suffix or, failing that, by content."""
    from mission_io import plan as plan_file
    from mission_io import waypoints as wpl_file
    from mission_io._common import read_text

    p = Path(path)
    text = read_text(p)
    suffix = p.suffix.lower()
    if suffix == ".plan" or (suffix not in (".waypoints", ".txt") and text.lstrip().startswith("{")):
        return plan_file.loads(text, path=str(p)), "QGroundControl plan"
    return wpl_file.loads(text, path=str(p)), "QGC WPL 110 waypoints"


def _names(enum: str) -> dict[int, str]:
    from ..dialect import mavlink

    prefix = enum + "_"
    return {k: e.name[len(prefix):] if e.name.startswith(prefix) else e.name
            for k, e in mavlink.enums.get(enum, {}).items()}


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from ..energy import path_length_m
    from ..errors import ConfigError
    from ..geo import LocalFrame
    from ..mission import GLOBAL_FRAMES, NAV_RETURN_TO_LAUNCH, NAV_TAKEOFF, NAV_WAYPOINT
    from ..render.terminal import Layer, char_map

    if args.width < 20:
        raise ConfigError(f"--width must be at least 20 columns, got {args.width}")
    if args.png and Path(args.png).suffix.lower() not in (".png", ".svg"):
        raise ConfigError(f"--png {args.png}: the picture must end in .png or .svg")
    if args.png:
        from ._output import check_output_file

        check_output_file(args.png, "--png")
    mission, kind = load_mission(args.file)
    positional = [it for it in mission.items if it.frame in GLOBAL_FRAMES]
    has_home = not (math.isnan(mission.home_lat_deg) or math.isnan(mission.home_lon_deg))
    if has_home:
        origin = (mission.home_lat_deg, mission.home_lon_deg)
    elif positional:
        origin = (positional[0].lat_deg, positional[0].lon_deg)
    else:
        origin = None
    # WPL 110 does not record the autopilot; a .plan does (mission.firmwareType).
    ap = ("ArduPilot" if mission.autopilot == "ardupilot" else "PX4") if kind.endswith("plan") \
        else "autopilot not recorded"
    n_wp = sum(1 for it in mission.items if it.command == NAV_WAYPOINT)
    holds = sum(1 for it in mission.items if it.command == NAV_WAYPOINT and it.params[0] > 0)
    hold_text = "" if n_wp == 0 else (" (all pass-through)" if holds == 0 else f" ({holds} with a hold)")
    print(f"{args.file}: {kind}, {ap}, {len(mission.items)} item(s), {n_wp} waypoint(s){hold_text}")
    if has_home:
        alt = "unknown AMSL altitude" if math.isnan(mission.home_alt_m) else f"{mission.home_alt_m:g} m AMSL"
        print(f"home {mission.home_lat_deg:.7f}, {mission.home_lon_deg:.7f} ({alt})")

    xy = np.zeros((0, 2))
    fence_xy = None
    if origin is not None:
        frame = LocalFrame(*origin)
        xy = frame.to_local_xy(np.array([[it.lat_deg, it.lon_deg] for it in positional]).reshape(-1, 2))
        route = xy
        if has_home:
            route = np.vstack([[0.0, 0.0], xy])
            if any(it.command == NAV_RETURN_TO_LAUNCH for it in mission.items):
                route = np.vstack([route, [0.0, 0.0]])
        speed = mission.cruise_speed_m_s
        length = path_length_m(route)
        timing = f", about {length / speed / 60:.1f} min at {speed:g} m/s" if speed else ""
        print(f"route {length / 1000:.2f} km{' from home and back' if has_home else ''}{timing}\n")
        layers = []
        for inclusion, ring in mission.geofence_polygons:
            fence_xy = frame.to_local_xy(np.array(ring)) if inclusion and fence_xy is None else fence_xy
            layers.append(Layer(frame.to_local_xy(np.array(ring)), "." if inclusion else "x", "ring",
                                name="geofence" if inclusion else "exclusion fence"))
        layers.append(Layer(route, "*", "line", name="route"))
        marks = [("T" if it.command == NAV_TAKEOFF else "o") for it in positional]
        layers.append(Layer(xy, "o", "points", labels=tuple(marks), name="waypoint"))
        if has_home:
            layers.append(Layer(np.zeros((1, 2)), "H", "points", name="home"))
        if len(xy):
            print(char_map(layers, width=args.width))
        else:
            print("(no positional items to draw)")
    else:
        print("(no positional items to draw)")
    if not args.no_table:
        print()
        print(item_table(mission))
    if args.png:
        _picture(args, mission, route if origin is not None else xy, fence_xy, origin)
        print(f"\nWrote {args.png}")
    return 0


def item_table(mission) -> str:
    """One row per item: number (home = 0), command, frame, position, hold, speed/params."""
    from ..mission import DO_CHANGE_SPEED, GLOBAL_FRAMES, NAV_WAYPOINT
    from ..render.terminal import format_table

    cmds, frames = _names("MAV_CMD"), _names("MAV_FRAME")
    rows = []
    if not math.isnan(mission.home_lat_deg):
        rows.append([0, "home", "", f"{mission.home_lat_deg:.7f}", f"{mission.home_lon_deg:.7f}",
                     "" if math.isnan(mission.home_alt_m) else f"{mission.home_alt_m:g}", ""])
    for k, it in enumerate(mission.items, start=1):
        pos = it.frame in GLOBAL_FRAMES
        if it.command == NAV_WAYPOINT:
            note = f"hold {it.params[0]:g} s" + (" (pass-through)" if it.params[0] == 0 else "")
        elif it.command == DO_CHANGE_SPEED:
            note = f"speed {it.params[1]:g} m/s"
        else:
            note = " ".join(f"{p:g}" for p in it.params if not math.isnan(p) and p != 0)
        rows.append([k, cmds.get(it.command, str(it.command)), frames.get(it.frame, str(it.frame)),
                     f"{it.lat_deg:.7f}" if pos else "", f"{it.lon_deg:.7f}" if pos else "",
                     f"{it.alt_m:g}" if pos else "", note])
    return format_table(["#", "command", "frame", "lat", "lon", "alt m", "notes"], rows)


def _picture(args, mission, route_xy, fence_xy, origin) -> None:
    from ..render.maps import origin_caption, save_figure
    from ..render.scan_plot import mission_figure

    sub = origin_caption(*origin) if origin else None
    fig = mission_figure([route_xy], [Path(args.file).name], title=f"Mission {Path(args.file).name}",
                         subtitle=sub, fence_xy=fence_xy)
    save_figure(fig, args.png)
