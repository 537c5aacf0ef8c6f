"""The sensor's running loop: sources -> frames -> (exclusion) -> MAVLink sender / frames kept.

Used by ``uavloc sense`` for live interfaces and for a capture replayed to MAVLink. Every
:data:`TICK_S` it drains the sources, parses what arrived, and lets the sender close slots and
send batches. Stops after ``--duration-s``, when a replayed capture is done, or on Ctrl-C, and
returns what it heard and sent (the CLI prints it and writes ``--out`` and ``--learn-team``).
"""

from __future__ import annotations

import asyncio
import logging
import time

from dataclasses import dataclass

from ..errors import LinkError
from .frames import Frames, SkipCounts, parse_records
from .mavout import SenderStats

log = logging.getLogger(__name__)

TICK_S = 0.05
REPLAY_DRAIN_S = 1.5
AUTOPILOT_WAIT_S = 30.0  # a replay to MAVLink waits this long for the autopilot's clock and position  # after a replay: time for the last slots' positions and batches


@dataclass
class StreamResult:
    heard: Frames  # kept only when ``args.out`` or ``args.learn_team``
    skips: SkipCounts
    sender: SenderStats | None  # None without --mavlink
    sysid: int | None  # the autopilot followed, None if none was heard


def run_stream(args, exclusion) -> StreamResult:
    """Run until stopped (duration, end of a replay, Ctrl-C)."""
    return asyncio.run(_main(args, exclusion))


async def _main(args, exclusion) -> StreamResult:
    from .live import ChannelHopper, LiveInterface, ReplaySource, parse_channels

    skips = SkipCounts()
    sources, hopper, sender = [], None, None
    try:
        if args.capture:
            replay = ReplaySource(args.capture, skips.read)  # read now: a broken file fails before linking
        else:
            plan = parse_channels(args.channels, args.dwell_ms / 1000.0) if args.channels else None
            for name in args.interface:
                sources.append(LiveInterface(name))
            if plan:
                hopper = ChannelHopper(args.interface[0], plan)
            if getattr(args, "ble_adapter", None):
                from .ble_live import BleScanner

                scanner = BleScanner(args.ble_adapter)
                await scanner.start()
                sources.append(scanner)
        if args.mavlink:
            from .mavout import open_sender

            key = None
            if args.signing_key:
                from ..link.connection import parse_signing_key

                key = parse_signing_key(args.signing_key)
            sender = await open_sender(args.mavlink, args.autopilot, slot_s=args.slot_ms / 1000.0, sysid=args.sysid,
                                       signing_key=key)
        kept: list[Frames] = []
        keep = bool(args.out or args.learn_team)
        t_start = time.monotonic()
        done_at = None
        try:
            while True:
                if args.capture and not sources and sender is not None and not sender.ready \
                        and time.monotonic() - t_start > AUTOPILOT_WAIT_S:
                    raise LinkError(f"no autopilot clock and position on {args.autopilot or args.mavlink} within "
                                    f"{AUTOPILOT_WAIT_S:g} s (HEARTBEAT, SYSTEM_TIME and GLOBAL_POSITION_INT are needed "
                                    "to time-tag and place the replay)", operation="sense")
                if args.capture and not sources and (sender is None or sender.ready):
                    replay.restart()  # a replay starts once the autopilot's clock and position are known
                    sources.append(replay)
                recs = [r for s in sources for r in s.poll()]
                frames = parse_records(recs, skips)
                if exclusion is not None and len(frames):
                    team = exclusion.mask(frames)
                    skips.reasons["excluded"] += int(team.sum())
                    frames = frames.take(~team)
                if keep and len(frames):
                    kept.append(frames)
                if sender is not None:
                    sender.add(frames)
                    sender.tick()
                now = time.monotonic()
                if args.duration_s is not None and now - t_start >= args.duration_s:
                    break
                if args.capture and sources and sources[0].done:
                    done_at = done_at or now
                    if now - done_at >= REPLAY_DRAIN_S:
                        break
                await asyncio.sleep(TICK_S)
        except (KeyboardInterrupt, asyncio.CancelledError):
            log.info("stopped")
        if sender is not None:
            sender.tick(final=True)
        result = StreamResult(Frames.concat(kept), skips, sender.stats if sender else None,
                              sender.sysid if sender else None)
    finally:
        for s in sources:
            if hasattr(s, "stop"):  # the BLE scanner stops on the event loop
                await s.stop()
            else:
                s.close()
        if hopper is not None:
            hopper.close()
        if sender is not None:
            sender.close()
            await sender.rssi_link.close()
            if sender.ap_link is not sender.rssi_link:
                await sender.ap_link.close()
    return result
