"""The sensor's running loop: sources -> frames -> (exclusion) -> MAVLink sender / frames kept.

Used by ``uavloc sense`` for live interfaces and for a capture replayed to MAVLink. Every
:data:`TICK_S` it drains the sources, parses what arrived, and lets the sender close slots and
send batches. Stops after ``--duration-s``, when a replayed capture is done, or on Ctrl-C;
``--out`` and ``--learn-team`` are written once it stops.
"""

from __future__ import annotations

import asyncio
import logging
import time
from pathlib import Path

from ..errors import LinkError
from .frames import Frames, SkipCounts, parse_records

log = logging.getLogger(__name__)

TICK_S = 0.05
REPLAY_DRAIN_S = 1.5
AUTOPILOT_WAIT_S = 30.0  # a replay to MAVLink waits this long for the autopilot's clock and position  # after a replay: time for the last slots' positions and batches


def run_stream(args, exclusion) -> int:
    return asyncio.run(_main(args, exclusion))


async def _main(args, exclusion) -> int:
    from .live import ChannelHopper, LiveInterface, ReplaySource, parse_channels

    skips = SkipCounts()
    sources, hopper, sender = [], None, None
    try:
        if args.capture:
            replay = ReplaySource(args.capture, skips.read)  # read now: a broken file fails before linking
        else:
            chans = parse_channels(args.channels) if args.channels else None
            for name in args.interface:
                sources.append(LiveInterface(name))
            if chans:
                hopper = ChannelHopper(args.interface[0], chans, args.dwell_ms / 1000.0)
        if args.mavlink:
            from .mavout import open_sender

            sender = await open_sender(args.mavlink, args.autopilot, slot_s=args.slot_ms / 1000.0, sysid=args.sysid)
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
            s = sender.stats
            print(f"sent {s.messages} UAVLOC_RSSI_BATCH2 ({s.entries_sent} entries, {s.bytes_sent} bytes) to "
                  f"{args.mavlink}; frames {s.frames_in}, before the autopilot's clock was known {s.frames_before_clock}, "
                  f"entries without a position {s.entries_no_position}")
            if sender.sysid is None:
                print("no autopilot heartbeat was heard: nothing could be time-tagged")
        print(f"{skips.read.records or sum(len(k) for k in kept)} frames read; skipped: {skips.summary()}")
        all_frames = Frames.concat(kept)
        _write_outputs(args, all_frames)
    finally:
        for s in sources:
            s.close()
        if hopper is not None:
            hopper.close()
        if sender is not None:
            sender.close()
            await sender.rssi_link.close()
            if sender.ap_link is not sender.rssi_link:
                await sender.ap_link.close()
    return 0


def _write_outputs(args, frames: Frames) -> None:
    from ..atomicfile import atomic_write_text
    from ..cli._output import atomic_output_dir
    from .aggregate import emitter_ids, frames_csv
    from .exclusion import learn_team

    if args.learn_team:
        atomic_write_text(Path(args.learn_team), learn_team(frames, min_frames=args.learn_min_frames,
                                                            fingerprints=args.learn_fingerprints))
        print(f"wrote {args.learn_team} ({len(frames)} frames heard; pass it to --exclude in flight)")
    if args.out:
        with atomic_output_dir(args.out) as tmp:
            (tmp / "frames.csv").write_text(frames_csv(frames, emitter_ids(frames)), encoding="utf-8")
        print(f"wrote {Path(args.out) / 'frames.csv'}")
