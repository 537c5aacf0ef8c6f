"""``uavloc daemon --config MISSION.toml``: run the search against real vehicles, SITL or fakes.

Connects to every vehicle in the config's ``[link]`` section, uploads the scan, starts it (or
waits for the operator), localizes, replans and uploads in flight, brings everyone home, and
writes the results. Restarted with the same ``--out`` after a crash it resumes the search.
Exit code 0 when every person heard was located within the required accuracy, 1 otherwise
(the statement says who and why), 2 for bad input, 3 for link failures.
"""

from __future__ import annotations

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
    p.add_argument("--connect-timeout", type=float, default=15.0, metavar="S",
                   help="seconds to wait for each vehicle's heartbeat (default 15)")
    p.add_argument("--planner-time-limit", type=float, metavar="S",
                   help="planner time per replan (default: the config's, capped to ~2 s of mission time)")
    p.set_defaults(func=run)


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
    out = Path(args.out) if args.out else Path(f"uavloc-{scenario.name}")
    if out.exists() and not out.is_dir():
        raise ConfigError(f"output path {out} exists and is not a directory")
    with store_lock(out, "daemon"):
        if args.fresh:
            for f in [out / "search.sqlite", out / "search.sqlite-wal", out / "search.sqlite-shm",
                      *out.glob("uav*.tlog")]:
                f.unlink(missing_ok=True)
        opts = options_from(args, scenario, out)
        view = LiveView(sys.stdout)
        result = run_search(scenario, connections, opts, out, view=view)
    print()
    print(result.table, end="")
    print(result.outcome.statement)
    print(f"results in {out}/: " + ", ".join(p.name for p in result.files) + ", search.sqlite, uav*.tlog")
    return 0 if result.outcome.all_located else 1
