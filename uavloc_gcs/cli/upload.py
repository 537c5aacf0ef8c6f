"""``uavloc upload FILE.plan|FILE.waypoints --to CONNECTION``: upload one mission to one vehicle,
read it back and compare, with progress on stderr and a one-line result on stdout.

Works against ArduPilot and PX4 SITL (``--to tcp:127.0.0.1:5760``, ``--to udpin::14540``) as well
as the fake vehicles (``--to udpout:127.0.0.1:14561``). The autopilot is taken from the vehicle's
HEARTBEAT unless ``--autopilot`` says otherwise; it decides the item-0 home rule.
"""

from __future__ import annotations

import argparse
import sys
import time

from ._inputs import number

HEARTBEAT_TIMEOUT_S = 10.0


def add_link_arguments(p: argparse.ArgumentParser) -> None:
    """Options shared by ``upload`` and ``download``."""
    p.add_argument("--autopilot", choices=("auto", "ardupilot", "px4"), default="auto",
                   help="mission encoding (home at seq 0 for ArduPilot); default: from the vehicle's HEARTBEAT")
    p.add_argument("--signing-key", metavar="HEX", help="MAVLink 2 signing key, 64 hex digits")
    p.add_argument("--system", type=number(int, min=1, max=255), metavar="ID",
                   help="vehicle system id, 1-255 (default: the first heard)")
    p.add_argument("--timeout", type=number(float, above=0, max=3600, unit="s"), default=HEARTBEAT_TIMEOUT_S,
                   metavar="S",
                   help=f"seconds to wait for the vehicle's heartbeat (default {HEARTBEAT_TIMEOUT_S:g})")
    p.add_argument("--tlog", metavar="PATH", help="record everything received to this .tlog")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("upload", help="upload a .plan/.waypoints mission to a vehicle and verify it",
                       description="Upload a mission to one vehicle over MAVLink, read it back and compare.")
    p.add_argument("file", metavar="FILE", help="mission file (.plan or .waypoints)")
    p.add_argument("--to", required=True, metavar="CONNECTION", dest="connection",
                   help="udpin:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT, tcpin:HOST:PORT or serial:DEVICE:BAUD")
    p.add_argument("--no-verify", action="store_true", help="skip the read-back comparison")
    add_link_arguments(p)
    p.set_defaults(func=run)


class Progress:
    """Progress of one transfer on stderr: a redrawn bar on a terminal, a few lines in a log."""

    def __init__(self, stream=None):
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty()
        self._last: tuple[str, int] | None = None

    def __call__(self, stage: str, done: int, total: int) -> None:
        if self.tty:
            width = 30
            filled = width * done // total if total else width
            self.stream.write(f"\r{stage:>8} [{'#' * filled}{'.' * (width - filled)}] {done}/{total}")
            if done == total:
                self.stream.write("\n")
            self.stream.flush()
            return
        quarter = 4 * done // total if total else 4
        if self._last != (stage, quarter):
            self._last = (stage, quarter)
            self.stream.write(f"{stage}: {done}/{total} items\n")
            self.stream.flush()


async def connect(args: argparse.Namespace):
    """Open the link and wait for the vehicle; returns (link, system, component, flavour)."""
    from ..link import flavour_for, flavour_named, open_link, parse_signing_key

    key = parse_signing_key(args.signing_key) if args.signing_key else None
    link = await open_link(args.connection, signing_key=key, tlog_path=args.tlog)
    try:
        hb = await link.wait_heartbeat(args.system, timeout_s=args.timeout)
    except BaseException:
        await link.close()
        raise
    seen = flavour_for(hb.autopilot)
    flavour = seen if args.autopilot == "auto" else flavour_named(args.autopilot)
    if seen.name in ("ardupilot", "px4") and flavour.name != seen.name:
        # an ArduPilot vehicle takes seq 0 of a PX4-encoded mission as its home (the take-off is
        # lost); refuse before a byte of the mission is sent
        await link.close()
        from ..errors import ConfigError

        raise ConfigError(f"--autopilot {args.autopilot}: vehicle {hb.get_srcSystem()} on {args.connection} says "
                          f"in its HEARTBEAT that it is {seen.label}; drop --autopilot or give --autopilot {seen.name}")
    return link, hb.get_srcSystem(), hb.get_srcComponent(), flavour


def encoding_for(flavour) -> str:
    """mission.py's autopilot name for a flavour (a generic MAVLink vehicle has no home item)."""
    return "ardupilot" if flavour.name == "ardupilot" else "px4"


def read_mission(path: str, autopilot: str | None):
    """Read a .plan or .waypoints file into a MissionPlan (the same reader as ``uavloc preview``)."""
    from mission_io import mission_file

    return mission_file.read(path, autopilot=autopilot)[0]


def check_commands(plan, path: str) -> None:
    """Refuse an item whose command MAVLink does not define (MAV_CMD): the vehicle would refuse
    it mid-transfer or stop the mission there."""
    from ..dialect import mavlink
    from ..errors import FileFormatError

    known, frames = mavlink.enums["MAV_CMD"], mavlink.enums["MAV_FRAME"]
    for n, it in enumerate(plan.items, start=1):
        if it.command not in known:
            raise FileFormatError(f"command {it.command} is not a MAVLink command (MAV_CMD); no autopilot would "
                                  "accept it", path=path, item=n, field="command")
        if it.frame not in frames:
            raise FileFormatError(f"frame {it.frame} is not a MAVLink frame (MAV_FRAME); no autopilot would accept it",
                                  path=path, item=n, field="frame")


def check_tlog(args: argparse.Namespace, inputs: dict) -> None:
    """``--tlog`` is appended to while the link is open: refuse, before connecting, a path that
    cannot be written or that is one of the command's own files."""
    if args.tlog is None:
        return
    from ._output import check_not_input, check_output_file

    check_output_file(args.tlog, "--tlog")
    check_not_input(args.tlog, "--tlog", inputs)


def run(args: argparse.Namespace) -> int:
    import asyncio

    check_tlog(args, {"the mission file being uploaded": args.file})
    return asyncio.run(_upload(args))


async def _no_space(n: int, autopilot: str, who: str, said: list[str]) -> str:
    """The sentence for NO_SPACE, with the vehicle's own words if it says them within a second
    (ArduPilot: "Only 650 items are supported", sent just after the MISSION_ACK)."""
    import asyncio

    from ..link.mission_capacity import no_space

    def words() -> str | None:
        return next((t for t in said if "items are supported" in t), None)

    for _ in range(20):
        if words():
            break
        await asyncio.sleep(0.05)
    return no_space(n, autopilot, who, words())


def check_items(plan, items, autopilot: str, path: str) -> None:
    """Refuse, before a byte is sent, an item ``autopilot`` would refuse mid-upload (leaving an
    ArduPilot with half a mission): link/mission_checks.py. Items are named as in the file."""
    from ..errors import FileFormatError
    from ..link.mission_checks import refusal

    first = 1 if autopilot == "ardupilot" else 0  # ArduPilot's seq 0 is its home
    for it, given in zip(items[first:], plan.items):
        if found := refusal(it, autopilot, given.frame):
            field, reason = found
            raise FileFormatError(reason, path=path, item=it.seq - first + 1, field=field)


def check_length(plan, autopilot: str, path: str) -> None:
    """Refuse a mission longer than any ``autopilot`` ("ardupilot", "px4", "generic") vehicle
    holds (link/mission_capacity.py), before a byte of it is sent."""
    from ..errors import FileFormatError
    from ..link.mission_capacity import too_long
    from ..mission import MissionEncodingError, to_wire

    try:
        n = len(to_wire(plan, "ardupilot" if autopilot == "ardupilot" else "px4"))
    except MissionEncodingError:
        return  # said once the vehicle's autopilot is known
    if reason := too_long(n, autopilot):
        raise FileFormatError(reason, path=path)


async def _upload(args: argparse.Namespace) -> int:
    from ..errors import FileFormatError, MissionTransferError
    from ..link import upload_mission
    from ..mission import MissionEncodingError, to_wire

    # a bad file fails before connecting
    first = read_mission(args.file, None if args.autopilot == "auto" else args.autopilot)
    if not first.items:  # MISSION_COUNT 0 is how a mission is cleared: never by accident
        raise FileFormatError("holds no mission items: nothing to upload (sending it would clear the vehicle's "
                              "mission)", path=args.file)
    check_commands(first, args.file)
    # too long for any vehicle of --autopilot (or for MAVLink's numbering): before connecting; too
    # long for the vehicle's autopilot: after its HEARTBEAT, before MISSION_COUNT
    check_length(first, "generic" if args.autopilot == "auto" else args.autopilot, args.file)
    if args.autopilot != "auto":
        try:
            check_items(first, to_wire(first, args.autopilot), args.autopilot, args.file)
        except MissionEncodingError:
            pass  # said below, once connected, in the vehicle's terms
    link, system, component, flavour = await connect(args)
    async with link:
        plan = read_mission(args.file, encoding_for(flavour))
        try:
            items = to_wire(plan, encoding_for(flavour))
        except MissionEncodingError as err:  # the file asks for something this autopilot cannot take
            raise FileFormatError(f"cannot be sent to {flavour.label}: {err}", path=args.file) from None
        check_length(plan, flavour.name, args.file)
        check_items(plan, items, flavour.name, args.file)
        said: list[str] = []
        started = time.monotonic()
        with link.subscribe("STATUSTEXT", source_system=system, callback=lambda m: said.append(m.text)):
            try:
                result = await upload_mission(link, system, component, items, verify=not args.no_verify,
                                              autopilot=flavour, progress=Progress())
            except MissionTransferError as err:
                if err.result_name != "MAV_MISSION_NO_SPACE":
                    raise
                who = f"vehicle {system} ({flavour.label}) on {args.connection}"
                raise FileFormatError(await _no_space(len(items), flavour.name, who, said), path=args.file) from None
    check = "read back and verified" if result.verified else "not verified (--no-verify)"
    print(f"Uploaded {len(plan.items)} mission items ({result.item_count} on the wire) to vehicle {system} "
          f"({flavour.label}) on {args.connection} in {time.monotonic() - started:.1f} s; {check}.")
    return 0
