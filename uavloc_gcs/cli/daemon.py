"""``uavloc daemon --config MISSION.toml``: run the search against real vehicles, SITL or fakes.

Connects to every vehicle in the config's ``[link]`` section, uploads the scan, starts it (or
waits for the operator), localizes, replans and uploads in flight, brings everyone home, and
writes the results. Restarted with the same ``--out`` after a crash it resumes the search.
Exit code 0 when every person heard was located within the required accuracy, 1 otherwise
(the statement says who and why), 2 for bad input, 3 for link failures, 4 when part of the area
was not searched because a vehicle was lost (or its scan never started) and no other vehicle could
take it over (the statement says how much and where; docs/guide/daemon.md), 5 when a vehicle was
lost in the air (silent while not on the ground and disarmed, and not heard again; the statement's
first sentence says which, where, how high, its battery and when it was last heard). 5 takes
precedence over 4, and 4 over 1.
"""

from __future__ import annotations

from ._inputs import number

import argparse
import sys
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("daemon", help="run the closed-loop search against a fleet over MAVLink",
                       description=__doc__.replace("``", ""), formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--config", required=True, metavar="MISSION.toml", help="scenario + [link] section")
    p.add_argument("--out", metavar="DIR", help="results, store and .tlog files (default: ./uavloc-NAME)")
    p.add_argument("--fresh", action="store_true", help="start a new search even if DIR holds one")
    p.add_argument("--start", choices=("auto", "operator"), help="override [link] start")
    p.add_argument("--signing-key", metavar="HEX", help="override [link] signing_key_hex (64 hex digits)")
    p.add_argument("--connect-timeout", type=number(float, above=0, max=3600, unit="s"), default=15.0, metavar="S",
                   help="seconds to wait for each vehicle's heartbeat (default 15)")
    p.add_argument("--planner-time-limit", type=number(float, above=0, max=600, unit="s"), metavar="S",
                   help="planner time per replan (default: the config's, capped to ~2 s of mission time)")
    add_web_options(p)
    p.set_defaults(func=run)


def add_web_options(p: argparse.ArgumentParser) -> None:
    """The live map's options (shared with ``uavloc demo``)."""
    g = p.add_argument_group("live map (a web page served while the search runs)")
    g.add_argument("--no-web", action="store_true", help="do not serve the live map (headless)")
    g.add_argument("--web-host", default="127.0.0.1", metavar="ADDR",
                   help="address to serve it on (default 127.0.0.1, this machine only; 0.0.0.0 = the LAN, "
                        "with a token)")
    g.add_argument("--web-port", type=number(int, min=0, max=65535), metavar="PORT",
                   help="TCP port (default 8765, or any free one if that is busy; 0 = any free port)")
    g.add_argument("--web-token", metavar="TOKEN",
                   help="token the page needs (default: a random one when not on 127.0.0.1)")
    g.add_argument("--web-keep", action="store_true",
                   help="after the search, go on serving the map (with the final results) until Ctrl-C")
    g.add_argument("--map-tiles", metavar="URL|DIR|FILE.mbtiles",
                   help="background map: an XYZ tile URL with {z}/{x}/{y}, a folder of z/x/y tiles or an "
                        "MBTiles file (default: none, the map is drawn from the search's own geometry)")


def web_options_from(args):
    """``WebOptions`` from the command line, or None with --no-web."""
    from ..errors import ConfigError
    from ..service.web import DEFAULT_PORT, WebOptions

    if args.no_web:
        return None
    port = DEFAULT_PORT if args.web_port is None else args.web_port
    if not 0 <= port <= 65535:
        raise ConfigError(f"--web-port must be 0..65535, got {port}")
    opts = WebOptions(host=args.web_host, port=port, token=args.web_token, tiles=args.map_tiles,
                      port_fallback=args.web_port is None, keep=args.web_keep)
    if opts.tiles:
        from ..service.web.server import _Tiles  # noqa: PLC0415 - check the tile source before flying

        _Tiles(opts.tiles)
    return opts


def print_web_url(url: str) -> None:
    print(f"live map: {url}", flush=True)


def reporter(out: Path, web):
    """What the operator reads at the end: the table, the statement, where the files are."""
    def report(result) -> None:
        print()
        print(result.table, end="")
        print(result.outcome.statement)
        print(f"results in {out}/: " + ", ".join(p.name for p in result.files) + ", search.sqlite, uav*.tlog")
        if web is not None and web.keep:
            print("the live map shows the final result until Ctrl-C", flush=True)
        sys.stdout.flush()

    return report


def options_from(args, scenario, out: Path):
    from ..link import parse_signing_key
    from ..service.daemon import DaemonOptions
    from ..service.run import rssi_connections_for

    key_hex = args.signing_key if getattr(args, "signing_key", None) else scenario.link.signing_key_hex
    key = parse_signing_key(key_hex) if key_hex else None
    tlog_dir = Path(scenario.link.tlog_path) if scenario.link.tlog_path else out
    return DaemonOptions(
        store_path=out / "search.sqlite", start=getattr(args, "start", None) or scenario.link.start,
        signing_key=key, tlog_dir=tlog_dir, lost_timeout_s=scenario.link.lost_timeout_s,
        connect_timeout_s=args.connect_timeout, planner_time_limit_s=getattr(args, "planner_time_limit", None),
        source_system=scenario.link.source_system, resume=not getattr(args, "fresh", False),
        rssi_connections=rssi_connections_for(scenario), set_speed_params=scenario.link.set_speed_params,
        on_stop=scenario.link.on_stop)


def run(args: argparse.Namespace) -> int:
    from ..errors import ConfigError
    from ..scenario import load_scenario
    from ..service.liveview import LiveView
    from ..service.lock import store_lock
    from ..service.run import connections_for, run_search

    scenario = load_scenario(args.config)
    connections = connections_for(scenario)
    web = web_options_from(args)
    out = Path(args.out) if args.out else Path(f"uavloc-{scenario.name}")
    if out.exists() and not out.is_dir():
        raise ConfigError(f"output path {out} exists and is not a directory")
    from ._inputs import discard_empty_leftovers, existing_files, require_fleet

    require_fleet(scenario)
    if scenario.link.tlog_path:  # before any vehicle is reached: a log directory that cannot be written
        from ..errors import OutputError
        from ._output import check_output_dir

        try:
            check_output_dir(scenario.link.tlog_path, "")
        except OutputError as err:
            raise ConfigError(str(err).strip(), source=scenario.source, key="link.tlog_path") from None
    with store_lock(out, "daemon"):
        if args.fresh:
            for f in [out / "search.sqlite", out / "search.sqlite-wal", out / "search.sqlite-shm",
                      *out.glob("uav*.tlog")]:
                f.unlink(missing_ok=True)
        before = existing_files(out)
        try:
            opts = options_from(args, scenario, out)
            view = LiveView(sys.stdout)
            result = run_search(scenario, connections, opts, out, view=view, web=web, on_web_url=print_web_url,
                                on_result=reporter(out, web))
        except BaseException:
            discard_empty_leftovers(out, before)  # a failure before anything was heard leaves nothing
            raise
    return exit_code(result.outcome)


def exit_code(outcome) -> int:
    """The exit code of a search that ran to its end (``service.outcome.SearchOutcome``): 5 a
    vehicle lost in the air, else 4 part of the area left unsearched by a lost vehicle, else 1
    someone heard not located, else 0."""
    from ..service.lost import EXIT_VEHICLE_LOST
    from ..service.outcome import EXIT_UNSEARCHED

    if outcome.lost_in_air:
        return EXIT_VEHICLE_LOST  # a vehicle lost in the air: before anything else (the statement's first sentence)
    if outcome.unsearched_after_loss:
        return EXIT_UNSEARCHED  # part of the area was not searched: a lost vehicle's, nobody took it over
    return 0 if outcome.all_located else 1
