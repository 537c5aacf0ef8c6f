"""``uavloc sense``: the companion computer's sensor. Wi-Fi probe requests, BLE advertising -> RSSI slots.

Input: a capture file (``.pcap``/``.pcapng`` with radiotap or PPI Wi-Fi, or Bluetooth LE link types
256 / 272 / 201; a btsnoop HCI log), live monitor-mode interfaces (``--interface``, libpcap
through pcapy-ng) and/or a Linux Bluetooth adapter (``--ble-adapter``, bleak over BlueZ).
Output: ``--out DIR`` gets ``frames.csv`` (one row per frame used, with its radio) and, with
``--tlog FLIGHT.tlog``, ``slots.csv`` that ``uavloc localize`` reads; ``--mavlink URL`` sends
UAVLOC_RSSI_BATCH2 to the autopilot (or beside it), time-tagged in the autopilot's clock;
``--learn-team FILE`` writes the exclusion list of what is heard (on the ground, before take-off). Broken frames are counted, never fatal; a file that is not a capture exits 2.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from ._inputs import number

log = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "sense",
        help="the on-board sensor: Wi-Fi probe requests and BLE advertising from a capture or live -> RSSI",
        description="Read 802.11 probe requests (radiotap or PPI) and Bluetooth LE advertising (link types 256, "
                    "272, 201, btsnoop) from CAPTURE, or live from --interface(s) and --ble-adapter, aggregate "
                    "them into RSSI slots and write frames.csv / slots.csv (--out) or send UAVLOC_RSSI_BATCH2 "
                    "over MAVLink (--mavlink).",
    )
    p.add_argument("capture", nargs="?", metavar="CAPTURE", help=".pcap, .pcapng or btsnoop file to replay")
    p.add_argument("--interface", "-i", action="append", default=[], metavar="IFACE",
                   help="monitor-mode interface to capture from (repeat for several; needs pcapy-ng and "
                        "capture permission)")
    p.add_argument("--ble-adapter", default=None, metavar="HCI",
                   help="also scan for Bluetooth LE advertising on this Linux adapter, e.g. hci0 (needs bleak and "
                        "BlueZ; every advertisement is reported, duplicates included)")
    p.add_argument("--channels", default=None, metavar="LIST",
                   help="hop the (single) interface over these channels, e.g. 1,6,11, or with a dwell per channel "
                        "in ms, 1:400,6:200,11:200 (uses 'iw'; default: stay on the channel it is set to)")
    p.add_argument("--dwell-ms", type=number(float, above=0, max=60_000, unit="ms"), default=250.0,
                   help="time on each hopped channel [ms] (default 250)")
    p.add_argument("--duration-s", type=number(float, above=0, unit="s"), default=None,
                   help="stop a live capture after this long")
    p.add_argument("--out", default=None, metavar="DIR", help="write frames.csv (and slots.csv with --tlog) here")
    p.add_argument("--tlog", default=None, metavar="FLIGHT.tlog",
                   help="flight log whose positions place the slots: writes DIR/slots.csv for uavloc localize")
    p.add_argument("--vehicle", type=number(int, min=1, max=255), default=None,
                   help="system id of the vehicle in --tlog (default: its only one)")
    p.add_argument("--clock-offset-s", type=number(float), default=0.0,
                   help="add this to capture times to put them on the flight log's UNIX clock (default 0)")
    p.add_argument("--slot-ms", type=number(float, above=0, max=255, unit="ms"), default=25.0,
                   help="slot length [ms] (default 25, as the scenarios; at most 65.535 with --mavlink)")
    p.add_argument("--exclude", default=None, metavar="FILE",
                   help="exclusion list of the team's devices (mac/oui/fp lines; see --learn-team)")
    p.add_argument("--learn-team", default=None, metavar="FILE",
                   help="write what is heard as the team's exclusion list (run on the ground before take-off)")
    p.add_argument("--learn-min-frames", type=number(int, min=1), default=3,
                   help="--learn-team keeps addresses heard at least this often (default 3)")
    p.add_argument("--learn-fingerprints", action="store_true",
                   help="--learn-team also lists fingerprints of non-random addresses (excludes the whole model)")
    p.add_argument("--mavlink", default=None, metavar="URL",
                   help="send UAVLOC_RSSI_BATCH2 here (the autopilot's companion port, e.g. serial:/dev/ttyAMA0:921600 "
                        "or udpout:127.0.0.1:14550); positions and time come from the autopilot on this link")
    p.add_argument("--autopilot", default=None, metavar="URL",
                   help="read the autopilot's position and clock here and send the RSSI to --mavlink beside it "
                        "(default: the --mavlink link itself)")
    p.add_argument("--sysid", type=number(int, min=1, max=255), default=None,
                   help="autopilot system id to follow, 1-255 (default: the first heard)")
    p.add_argument("--signing-key", default=None, metavar="HEX",
                   help="MAVLink 2 signing key (64 hex digits), as the fleet's: signs what is sent, drops unsigned input")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..errors import ConfigError
    from ..scenario_limits import SLOT_US_MAX
    from ..sense import parse_capture
    from ..sense.exclusion import read_exclusion

    live = bool(args.interface or args.ble_adapter)
    if bool(args.capture) == live:
        raise ConfigError("give either a CAPTURE file or live sources (--interface, --ble-adapter), not both, "
                          "not neither", key="capture")
    if args.mavlink and args.slot_ms > SLOT_US_MAX / 1000:
        raise ConfigError(f"--slot-ms {args.slot_ms:g}: UAVLOC_RSSI_BATCH2 carries the slot length as a 16-bit count of "
                          f"microseconds, at most {SLOT_US_MAX / 1000:g} ms")
    if args.tlog and not args.out:
        raise ConfigError("--tlog writes DIR/slots.csv: give --out DIR too", key="--tlog")
    if args.tlog and (live or args.mavlink):
        raise ConfigError("--tlog places a capture file's slots on a recorded flight: not with --interface or "
                          "--mavlink", key="--tlog")
    if args.channels:
        from ..sense.live import parse_channels

        parse_channels(args.channels, args.dwell_ms / 1000.0)  # refused before anything starts
    if args.ble_adapter:
        from ..sense.ble_live import _import_bleak

        _import_bleak()  # a missing library is refused before anything starts
    if args.channels and len(args.interface) != 1:
        raise ConfigError("--channels hops one interface; give exactly one --interface (several interfaces stay "
                          "on their own fixed channels)", key="--channels")
    if args.signing_key:
        from ..link.connection import parse_signing_key

        if not args.mavlink:
            raise ConfigError("--signing-key signs the MAVLink output: give --mavlink URL too", key="--signing-key")
        parse_signing_key(args.signing_key)  # a bad key is refused before anything starts
    if not (args.out or args.learn_team or args.mavlink):
        raise ConfigError("nothing to do: give --out DIR, --mavlink URL or --learn-team FILE", key="--out")
    from ._output import check_not_input, check_output_dir, check_output_file

    if args.out:  # before reading a capture or opening an interface: an output that cannot be written
        check_output_dir(args.out, "--out")
    if args.learn_team:
        check_output_file(args.learn_team, "--learn-team")
        check_not_input(args.learn_team, "--learn-team", {"the capture being read": args.capture,
                                                          "the --exclude list": args.exclude,
                                                          "the --tlog flight log": args.tlog})
    exclusion = read_exclusion(args.exclude) if args.exclude else None
    if args.capture and not args.mavlink:
        frames, skips = parse_capture(args.capture)
        if args.clock_offset_s:
            from dataclasses import replace
            frames = replace(frames, t_s=frames.t_s + args.clock_offset_s)
        return _offline(args, frames, skips, exclusion)
    from ..sense.run import run_stream

    result = run_stream(args, exclusion)
    heard = result.heard
    if result.sender is not None:
        s = result.sender
        print(f"sent {s.messages} UAVLOC_RSSI_BATCH2 ({s.entries_sent} entries, {s.bytes_sent} bytes) to {args.mavlink}; "
              f"frames {s.frames_in}, of them before the autopilot's clock was known {s.frames_before_clock}; "
              f"entries without a position {s.entries_no_position}")
        if result.sysid is None:
            print("no autopilot heartbeat was heard: nothing could be time-tagged")
    print(f"{result.skips.read.records or len(heard)} frames read; skipped: {result.skips.summary()}")
    if args.learn_team:
        _learn(args, heard)
    if args.out:
        from ..sense.aggregate import emitter_ids, frames_csv
        from ._output import atomic_output_dir

        with atomic_output_dir(args.out) as tmp:
            (tmp / "frames.csv").write_text(frames_csv(heard, emitter_ids(heard)), encoding="utf-8")
        print(f"wrote {Path(args.out) / 'frames.csv'}")
    return 0


def _learn(args, frames) -> None:
    from ..sense.exclusion import learn_team

    _write_text(args.learn_team, learn_team(frames, min_frames=args.learn_min_frames,
                                            fingerprints=args.learn_fingerprints))
    print(f"wrote {args.learn_team} (the team's devices, {len(frames)} frames heard; pass it to --exclude in flight)")


def _offline(args, frames, skips, exclusion) -> int:
    import numpy as np

    from ..sense.aggregate import emitter_ids, frames_csv, slot_entries
    from ._output import atomic_output_dir

    ble = int(np.count_nonzero(frames.radio))
    print(f"{args.capture}: {skips.read.records} records, {len(frames) - ble} probe requests and {ble} BLE "
          f"advertisements used; skipped: {skips.summary()}")
    if args.learn_team:
        _learn(args, frames)
    if exclusion is not None:
        team = exclusion.mask(frames)
        frames = frames.take(~team)
        print(f"excluded {int(team.sum())} frames of the team's devices ({len(exclusion)} list entries)")
    if not args.out:
        return 0
    ids = emitter_ids(frames)
    entries = slot_entries(frames, args.slot_ms / 1000.0)
    slots_text = None
    if args.tlog:
        slots_text, dropped = _slots_for_flight(args, entries)
    with atomic_output_dir(args.out) as tmp:
        (tmp / "frames.csv").write_text(frames_csv(frames, ids), encoding="utf-8")
        if slots_text is not None:
            (tmp / "slots.csv").write_text(slots_text, encoding="utf-8")
    print(f"{len(np.unique(frames.address))} addresses, {len(np.unique(ids))} emitter ids, "
          f"{len(entries)} slot entries of {args.slot_ms:g} ms")
    if slots_text is not None:
        print(f"slots.csv: {len(entries) - dropped} slots placed on the flight"
              + (f" ({dropped} outside the flown time, dropped)" if dropped else ""))
    print(f"wrote {Path(args.out) / 'frames.csv'}" + (", slots.csv" if slots_text is not None else ""))
    return 0


def _slots_for_flight(args, entries):
    from ..errors import ConfigError
    from ..sense.flight import read_tracks, slots_csv

    tracks = read_tracks(args.tlog)
    if args.vehicle is None:
        if len(tracks) > 1:
            raise ConfigError(f"{args.tlog} holds vehicles {sorted(tracks)}: choose one with --vehicle", key="--vehicle")
        track = next(iter(tracks.values()))
    elif args.vehicle in tracks:
        track = tracks[args.vehicle]
    else:
        raise ConfigError(f"{args.tlog} has no vehicle {args.vehicle} (it has {sorted(tracks)})", key="--vehicle")
    return slots_csv(entries, track)


def _write_text(path: str, text: str) -> None:
    from ..atomicfile import atomic_write_text

    atomic_write_text(Path(path), text)
