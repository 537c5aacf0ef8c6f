"""``uavloc sitl``: real ArduCopter or PX4 SITL vehicles with their companions, for ``uavloc daemon``.

    uavloc sitl examples/sitl_arducopter.toml --out mission.toml           # then, in another shell:
    uavloc daemon --config mission.toml
    uavloc sitl examples/field.toml --vehicles 3 --autopilot px4 --out mission.toml

Starts N autopilots (ArduCopter SITL or PX4 SIH; from ``--sitl-dir``, else ``$UAVLOC_SITL_DIR``,
else ``../shared/sitl``), homed at the scenario's launch point, with system ids 1..N on free ports,
and one simulated companion computer per vehicle that sends the RSSI of the scenario's simulated
people (one world, one world clock for all of them). When every vehicle is ready it writes the
mission file (the scenario with [fleet] and [link] set for these vehicles) and prints its [link]
block; then it stays alive as the autopilots' parent (ArduCopter SITL exits when its parent does)
until Ctrl-C or SIGTERM, which stops them all. An autopilot that exits by itself stops them all too,
unless ``--keep-flying``: then that is said in one sentence and the others fly on (a fault drill:
losing one vehicle in the air, which the daemon reports first, issue 42 items 2 and 6).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from ..errors import ConfigError
from ._inputs import number


def register(sub) -> None:
    p = sub.add_parser("sitl", help="start real ArduCopter/PX4 SITL vehicles and their companions for uavloc daemon",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenario", help="scenario TOML: area, simulated people, the rest of the mission file")
    p.add_argument("-n", "--vehicles", type=int, default=None,
                   help="how many vehicles, 1-10 (default: fleet.vehicles of the scenario)")
    p.add_argument("--autopilot", choices=("ardupilot", "px4"), default=None,
                   help="ArduCopter SITL or PX4 SIH (default: fleet.autopilot of the scenario)")
    p.add_argument("--sitl-dir", type=Path, default=None, metavar="PATH",
                   help="a folder with ardupilot/arducopter and px4/ (as ../shared/sitl), or your own build: "
                        "an arducopter binary (copter.parm beside it or in its ArduPilot checkout), or a PX4 "
                        "build folder with bin/px4 and etc/")
    p.add_argument("--out", type=Path, default=None, metavar="FILE",
                   help="write the mission file for uavloc daemon --config here (default: print [link] only)")
    p.add_argument("--speedup", type=float, default=None, help="simulated seconds per wall second (default 5)")
    p.add_argument("--base-port", type=int, default=None, metavar="PORT",
                   help="vehicle i's ground link on PORT+i-1 (default: free ports)")
    p.add_argument("--home-alt", type=float, default=None, metavar="M",
                   help="home altitude above sea level [m] (default: the DEM's at the launch point with "
                        "terrain.dem, absolute missions being planned from it; else 0)")
    p.add_argument("--seed", type=number(int, min=0, max=2**32 - 1), default=None,
                   help="simulated world seed (default: simulation.seed)")
    p.add_argument("--no-companion", action="store_true", help="no simulated companions (no RSSI)")
    p.add_argument("--ready-timeout", type=float, default=None, metavar="S",
                   help="wall seconds each vehicle has to become ready to fly (default 120)")
    p.add_argument("--keep-flying", action="store_true",
                   help="when one autopilot exits, say so and keep the other vehicles flying (a fault drill: "
                        "losing one vehicle); without it, one exit stops them all")
    p.set_defaults(func=run)


def _check_args(args, scenario):
    from ..service import sitl

    n = scenario.fleet.vehicles if args.vehicles is None else args.vehicles
    if not 1 <= n <= sitl.MAX_VEHICLES:
        raise ConfigError(f"{n} is out of range: give 1-{sitl.MAX_VEHICLES} vehicles", key="--vehicles")
    kind = args.autopilot or scenario.fleet.autopilot
    if kind not in sitl.AUTOPILOTS:
        raise ConfigError(f"the scenario's autopilot {kind!r} has no SITL here: give --autopilot ardupilot or px4",
                          key="--autopilot")
    speedup = sitl.DEFAULT_SPEEDUP if args.speedup is None else args.speedup
    if not (math.isfinite(speedup) and 0 < speedup <= 100):
        raise ConfigError(f"{args.speedup} is not a speed-up in (0, 100]", key="--speedup")
    if args.base_port is not None and not 1024 <= args.base_port <= 65535 - n + 1:
        raise ConfigError(f"{args.base_port} leaves no room for {n} port(s) in 1024-65535", key="--base-port")
    if args.home_alt is not None and not (math.isfinite(args.home_alt) and -500 <= args.home_alt <= 9000):
        raise ConfigError(f"{args.home_alt} is not an altitude in -500..9000 m", key="--home-alt")
    timeout = sitl.READY_TIMEOUT_S if args.ready_timeout is None else args.ready_timeout
    if not (math.isfinite(timeout) and timeout > 0):
        raise ConfigError(f"{args.ready_timeout} must be > 0 seconds", key="--ready-timeout")
    if args.out is not None:  # before any vehicle starts: a mission file that cannot be written
        from ._output import check_output_file

        check_output_file(args.out, "--out")
    return n, kind, speedup, timeout


def run(args) -> int:
    import asyncio
    import signal

    from ..atomicfile import atomic_write_text
    from ..scenario import load_scenario
    from ..service import sitl, sitl_fleet

    scenario = load_scenario(args.scenario)
    n, kind, speedup, timeout = _check_args(args, scenario)
    build = sitl.find_build(kind, args.sitl_dir)
    if kind == "ardupilot":
        sitl.copter_parm(build)
    lat, lon = scenario.launch_latlon_deg
    home_alt = args.home_alt if args.home_alt is not None else (
        scenario.dem.height_at(0.0, 0.0) if scenario.dem is not None else 0.0)
    home = (lat, lon, home_alt, 0.0)

    def on_term(signum, frame):
        raise KeyboardInterrupt
    previous = signal.signal(signal.SIGTERM, on_term)
    vehicles: list = []
    try:
        print(f"uavloc sitl: starting {n} {kind} SITL vehicle(s) from {build}, speed-up {speedup:g}, home "
              f"{lat:.6f}, {lon:.6f} (the scenario's launch point) ...", flush=True)
        vehicles = sitl_fleet.launch_fleet(kind, build, n, home=home, speedup=speedup, base_port=args.base_port,
                                     timeout_s=timeout, on_ready=lambda v: print(
                                         f"  vehicle {v.sysid}: {kind} instance {v.sitl.instance} ready after "
                                         f"{v.sitl.ready_after_s:.1f} s", flush=True))
        block = sitl_fleet.link_block(vehicles)
        if args.out is not None:
            text = sitl_fleet.mission_text(Path(args.scenario).read_text(encoding="utf-8"), vehicles, autopilot=kind,
                                     source=str(args.scenario), base_dir=Path(args.scenario).parent)
            atomic_write_text(args.out, text)
            print(f"mission file: {args.out}  (run: uavloc daemon --config {args.out})", flush=True)
        print(block, end="", flush=True)
        for v in vehicles:
            extra = f", RSSI beside it on {v.daemon_rssi}" if v.daemon_rssi else ", RSSI through it"
            print(f"  vehicle {v.sysid}: ground link {v.connection}, companion on {v.companion_url}"
                  f"{'' if args.no_companion else extra}; work dir {v.sitl.workdir}", flush=True)
        asyncio.run(_serve(args, scenario, vehicles))
    except KeyboardInterrupt:
        if not vehicles:
            raise
    finally:
        signal.signal(signal.SIGTERM, previous)
        for v in vehicles:
            v.sitl.stop()
    print(f"uavloc sitl: stopped {len(vehicles)} vehicle(s)", flush=True)
    return 0


async def _serve(args, scenario, vehicles) -> None:
    """Run the companions until interrupted; fail when an autopilot exits on its own."""
    import asyncio
    import signal

    from ..errors import UavlocError

    stop = asyncio.Event()
    asyncio.get_running_loop().add_signal_handler(signal.SIGTERM, stop.set)
    tasks = []
    if not args.no_companion:
        from sim_link.vehicles.companions import CompanionGroup

        group = CompanionGroup(scenario, [(v.companion_url, v.rssi_url) for v in vehicles], seed=args.seed)
        tasks.append(asyncio.ensure_future(group.run(stop)))
        print(f"companions: {len(group.world)} simulated people (seed "
              f"{scenario.simulation.seed if args.seed is None else args.seed}), one world clock; Ctrl-C to stop "
              "everything", flush=True)
    else:
        print("no companions; Ctrl-C to stop everything", flush=True)
    gone: set[int] = set()  # vehicles whose autopilot exited (--keep-flying)
    try:
        while not stop.is_set():
            try:
                await asyncio.wait_for(stop.wait(), 1.0)
            except asyncio.TimeoutError:
                pass
            for t in tasks:
                if t.done() and t.exception() is not None:
                    raise t.exception()
            dead = [v for v in vehicles if not v.sitl.alive() and v.sysid not in gone]
            if not dead:
                continue
            v = dead[0]
            what = (f"vehicle {v.sysid} ({v.sitl.kind} instance {v.sitl.instance}) exited with code "
                    f"{v.sitl.proc.returncode if v.sitl.proc else None}")
            gone.update(d.sysid for d in dead)
            if not args.keep_flying or len(gone) == len(vehicles):
                raise UavlocError(f"{what}; its output ends:\n{v.sitl.log_tail(15)}")
            for d in dead:  # a fault drill: the others fly on
                print(f"uavloc sitl: vehicle {d.sysid} ({d.sitl.kind} instance {d.sitl.instance}) exited with code "
                      f"{d.sitl.proc.returncode if d.sitl.proc else None}; vehicle(s) "
                      f"{', '.join(str(o.sysid) for o in vehicles if o.sysid not in gone)} keep flying "
                      "(--keep-flying); its output ends:\n" + d.sitl.log_tail(5), flush=True)
    finally:
        stop.set()
        if tasks:
            await asyncio.wait(tasks, timeout=5.0)
