"""The on-board sensor: Wi-Fi frames from a monitor-mode interface or a capture file -> RSSI slots.

Layers, bottom up: :mod:`.capture` (pcap/pcapng records), :mod:`.radiotap` (radio headers),
:mod:`.dot11` (probe requests, information elements, content fingerprint), :mod:`.frames` (records
-> frame columns, with skip counts), :mod:`.aggregate` (frames -> emitter ids and per-slot
entries), :mod:`.exclusion` (the team's own devices), :mod:`.flight` (slot positions from a
flight log), :mod:`.live` (libpcap capture with channel hopping) and :mod:`.mavout` (the
autopilot's clock and UAVLOC_RSSI_BATCH2 over MAVLink). The CLI is ``uavloc sense``.
"""

from __future__ import annotations

from pathlib import Path

from .capture import ReadStats, read_capture_file, read_records
from .frames import Frames, SkipCounts, parse_records

__all__ = ["Frames", "SkipCounts", "ReadStats", "parse_capture", "parse_capture_bytes"]


def parse_capture_bytes(buf: bytes, *, path: str = "<buffer>") -> tuple[Frames, SkipCounts]:
    """Probe requests of a capture held in memory, with what was skipped."""
    skips = SkipCounts()
    frames = parse_records(read_records(buf, skips.read, path=path), skips)
    return frames, skips


def parse_capture(path: str | Path) -> tuple[Frames, SkipCounts]:
    """Probe requests of a capture file. Raises FileFormatError only when it is not a capture."""
    return parse_capture_bytes(read_capture_file(path), path=str(path))
