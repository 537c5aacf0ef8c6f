"""``uavloc demo``: the paper's search area on fake vehicles, the daemon flying them over UDP.

By default in the field world (``field``: phones that send probe bursts under changing addresses,
heard above a receiver's sensitivity); ``--scenario paper`` is the paper's own world.

Starts the simulated fleet (people, radio channel, MAVLink vehicles on loopback) at a speed-up,
runs the same daemon ``uavloc daemon`` runs against real vehicles, shows the live status, and
ends with the table of located people next to their true positions, people.csv /
people.geojson / people.kml, result.png, the store and one .tlog per vehicle.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import signal
import sys
from pathlib import Path

from ._inputs import number, override
from .daemon import add_web_options, print_web_url, reporter, web_options_from

MAX_PEOPLE = 1000  # simulated people: beyond this the fake fleet's world does not start in time


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="the paper's area in the field world on fake vehicles + daemon + live view (a few minutes)",
                       description=__doc__.replace("``", ""), formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scenario", metavar="FILE.toml", help="scenario TOML, or a shipped one by name: field, paper, small (default: field, "
                        "the paper's area in the field world; paper is the paper's own world)")
    p.add_argument("--out", default="uavloc-demo", metavar="DIR", help="output directory (default uavloc-demo)")
    p.add_argument("--speedup", type=number(float, above=0, max=1000), metavar="K", help="simulated seconds per second (default: scenario's)")
    p.add_argument("--autopilot", choices=("ardupilot", "px4"), help="fake vehicle flavour (default: scenario's)")
    p.add_argument("--people", type=number(int, min=0, max=MAX_PEOPLE), metavar="N", help="number of simulated people (default: scenario's)")
    p.add_argument("--seed", type=number(int, min=0, max=2**32 - 1), metavar="N", help="world seed (default: scenario's)")
    p.add_argument("--loss", type=number(float, min=0, max=0.99), default=0.0, metavar="P", help="packet loss fraction on every link")
    p.add_argument("--base-port", type=number(int, min=0, max=65000), default=14560, metavar="PORT",
                   help="vehicle i listens on UDP port PORT+i (default 14560: 14561, 14562, ...; 0 = any free)")
    p.add_argument("--signing-key", metavar="HEX", help="sign every link with this 32-byte key (64 hex digits)")
    p.add_argument("--direct-rssi", action="store_true",
                   help="the fake vehicles send the simulated slots as they are; by default each slot becomes the "
                        "radiotap probe requests behind it and goes through uavloc sense's parser and aggregator")
    add_web_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..errors import ConfigError
    from ..examples import scenario_path
    from ..link import parse_signing_key
    from ..scenario import load_scenario
    from ..service.lock import store_lock

    sc = load_scenario(scenario_path(args.scenario or "field"))
    sim = {}
    if args.speedup is not None:
        sim["speedup"] = args.speedup
    if args.people is not None:
        sim["people"] = args.people
    if args.seed is not None:
        sim["seed"] = args.seed
    for flag, key in (("--speedup", "speedup"), ("--people", "people"), ("--seed", "seed")):
        if key in sim:
            sc = override(sc, flag, simulation={key: sim[key]})
    if args.autopilot:
        sc = override(sc, "--autopilot", fleet={"autopilot": args.autopilot})
    if not 0.0 <= args.loss < 1.0:
        raise ConfigError(f"--loss must be in [0, 1), got {args.loss}")
    key = parse_signing_key(args.signing_key) if args.signing_key else None
    web = web_options_from(args)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"output path {out} exists and is not a directory")
    with store_lock(out, "demo"), _terminate_raises():
        for old in [out / "search.sqlite", out / "search.sqlite-wal", out / "search.sqlite-shm",
                    *out.glob("uav*.tlog")]:
            old.unlink(missing_ok=True)
        from ._inputs import discard_empty_leftovers, existing_files

        before = existing_files(out)
        try:
            return _run(args, sc, key, out, web)
        except BaseException:
            discard_empty_leftovers(out, before)  # a failure before anything was heard leaves nothing
            raise


@contextlib.contextmanager
def _terminate_raises():
    """SIGTERM outside the search (starting the fleet, writing results) ends the demo like Ctrl-C,
    through ``finally`` blocks, so the fake fleet's process is always stopped."""
    from ..errors import Interrupted

    def on_term(signum, _frame):
        raise Interrupted("stopped by SIGTERM", signal=signum)

    previous = signal.signal(signal.SIGTERM, on_term)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _run(args, sc, key, out: Path, web) -> int:
    import numpy as np

    from sim_link.vehicles.faults import FaultConfig
    from sim_link.world import World

    from ..service.daemon import DaemonOptions
    from ..service.liveview import LiveView
    from ..service.run import run_search
    from ._fleet import start_fleet_process

    faults = FaultConfig(loss=args.loss) if args.loss else None
    print(f"uavloc demo: scenario '{sc.name}', {sc.fleet.vehicles} {sc.fleet.autopilot} vehicles, "
          f"{sc.simulation.people} simulated people, speed-up {sc.simulation.speedup:g}x, "
          + ("RSSI straight from the simulated slots" if args.direct_rssi
             else "RSSI through the Wi-Fi sensor's parser (radiotap probe requests)"))
    fleet = start_fleet_process(sc, speedup=sc.simulation.speedup, seed=sc.simulation.seed,
                                base_port=args.base_port, faults=faults, signing_key=key,
                                vehicle_options=None if args.direct_rssi else {"via_sense": True},
                                team_swaps=sc.fleet.batteries > 1)  # the team swaps the packs of landed vehicles
    try:
        world = World(sc, seed=sc.simulation.seed)  # the fleet's world, rebuilt from the same seed

        def truth(people, epoch_unix_s: float):
            """True position of every simulated person at the time its estimate refers to, under
            the id the search reported them by (in the field world the first address heard of
            them, so one person split in two by the linking appears twice); people never heard
            under their world id."""
            shift = epoch_unix_s - fleet.epoch_unix_s
            refs = [p.t_ref_s for p in people if math.isfinite(p.t_ref_s)]
            t_end = max(refs, default=0.0) + shift
            out_xy, reported = {}, set()
            for p in people:
                i = int(world.person_of([p.emitter_id])[0])
                if i < 0:
                    continue
                t = p.t_ref_s + shift if math.isfinite(p.t_ref_s) else t_end
                out_xy[p.emitter_id] = tuple(np.asarray(world.positions(t))[i][:2].tolist())
                reported.add(i)
            for i, eid in enumerate(int(e) for e in world.emitter_ids):
                if i not in reported:
                    out_xy[eid] = tuple(np.asarray(world.positions(t_end))[i][:2].tolist())
            return out_xy

        opts = DaemonOptions(store_path=out / "search.sqlite", signing_key=key, tlog_dir=out,
                             lost_timeout_s=sc.link.lost_timeout_s, resume=False)
        view = LiveView(sys.stdout)
        connections = [(i + 1, conn) for i, (_name, conn) in enumerate(fleet.endpoints)]
        run_search(sc, connections, opts, out, view=view, truth=truth, web=web, on_web_url=print_web_url,
                   on_result=reporter(out, web))
    finally:
        fleet.stop()
    # The demonstration ran to its end; who was (not) located is in the table and the statement.
    # (`uavloc daemon` exits 1 when someone is not located, for scripts that act on it.)
    return 0
