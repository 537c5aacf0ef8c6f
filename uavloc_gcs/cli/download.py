"""``uavloc download --from CONNECTION --out FILE.plan|FILE.waypoints``: read a vehicle's mission
and save it (atomically), with progress on stderr and a one-line result on stdout."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from .upload import Progress, add_link_arguments, check_tlog, connect, encoding_for


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("download", help="download a vehicle's mission to a .plan/.waypoints file",
                       description="Download a vehicle's mission over MAVLink and save it.")
    p.add_argument("--from", required=True, metavar="CONNECTION", dest="connection",
                   help="udpin:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT, tcpin:HOST:PORT or serial:DEVICE:BAUD")
    p.add_argument("--out", required=True, metavar="FILE", help="where to write (.plan or .waypoints)")
    add_link_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import asyncio

    from ..errors import ConfigError

    from ._output import check_output_file

    check_output_file(args.out, "--out")
    if Path(args.out).suffix.lower() not in (".plan", ".waypoints", ".txt"):
        raise ConfigError(f"{args.out}: output file must end in .plan or .waypoints", key="out")
    check_tlog(args, {"the --out file": args.out})
    if args.tlog is not None and Path(args.tlog).absolute() == Path(args.out).absolute():
        raise ConfigError(f"--tlog {args.tlog} is also the --out file; give them different names")
    return asyncio.run(_download(args))


async def _download(args: argparse.Namespace) -> int:
    from mission_io import plan as plan_file
    from mission_io import waypoints as waypoints_file

    import dataclasses

    from ..link import download_mission, home_position, qgc_form
    from ..mission import from_wire

    link, system, component, flavour = await connect(args)
    async with link:
        started = time.monotonic()
        items = await download_mission(link, system, component, progress=Progress())
        home = await home_position(link, system, component)
    plan = from_wire(qgc_form(items), encoding_for(flavour))
    if home is not None:  # QGC's planned home is the vehicle's home
        plan = dataclasses.replace(plan, home_lat_deg=home[0], home_lon_deg=home[1], home_alt_m=home[2])
    writer = plan_file if Path(args.out).suffix.lower() == ".plan" else waypoints_file
    writer.write(args.out, plan)
    print(f"Downloaded {len(plan.items)} mission items ({len(items)} on the wire) from vehicle {system} "
          f"({flavour.label}) on {args.connection} in {time.monotonic() - started:.1f} s to {args.out}.")
    return 0
