"""Telemetry logs (``.tlog``) in the format QGroundControl and MAVProxy write.

Each record is an 8-byte big-endian UNIX timestamp in microseconds followed by one MAVLink
packet exactly as received (v1 or v2, signature included). :class:`TlogWriter` records what a
:class:`~uavloc_gcs.link.connection.Link` receives; :func:`iter_tlog` replays a file as
``(t_us, message)`` pairs, e.g. into the estimator (``uavloc localize flight.tlog``).
"""

from __future__ import annotations

import logging
import os
import struct
import time
from pathlib import Path
from typing import BinaryIO, Iterator

from ..dialect import mavlink
from ..dialect.signing import verify_signature_first
from ..errors import FileFormatError

log = logging.getLogger(__name__)

_STAMP = struct.Struct(">Q")
MAGIC_V1 = 0xFE
MAGIC_V2 = 0xFD
FLUSH_INTERVAL_S = 0.5  # a crash loses at most this much of the log


def packet_length(head: bytes) -> int | None:
    """Full length of the packet starting with ``head`` (needs 3 bytes), or None if no magic."""
    if head[0] == MAGIC_V2:
        signed = head[2] & mavlink.MAVLINK_IFLAG_SIGNED
        return 10 + head[1] + 2 + (mavlink.MAVLINK_SIGNATURE_BLOCK_LEN if signed else 0)
    if head[0] == MAGIC_V1:
        return 6 + head[1] + 2
    return None


class TlogWriter:
    """Append-only ``.tlog`` writer; flushes at most every FLUSH_INTERVAL_S and on close."""

    def __init__(self, path: str | os.PathLike, *, clock=time.time):
        self.path = Path(path)
        self._file: BinaryIO = open(self.path, "ab")
        self._clock = clock
        self._last_flush = clock()
        self.records = 0

    def write(self, packet: bytes, t_us: int | None = None) -> None:
        """Record one packet received at ``t_us`` (UNIX µs; now if None)."""
        now = self._clock()
        stamp = int(now * 1e6) if t_us is None else int(t_us)
        self._file.write(_STAMP.pack(stamp) + bytes(packet))
        self.records += 1
        if now - self._last_flush >= FLUSH_INTERVAL_S:
            self._file.flush()
            self._last_flush = now

    def close(self) -> None:
        if not self._file.closed:
            self._file.close()


def iter_tlog(path: str | os.PathLike, *, signing_key: bytes | None = None
              ) -> Iterator[tuple[int, "mavlink.MAVLink_message"]]:
    """Yield ``(t_us, message)`` for every decodable packet in the ``.tlog`` at ``path``.

    Packets with a bad CRC are skipped. With ``signing_key`` the file is filtered like a live
    signed link: unsigned or wrongly signed packets are skipped. A truncated last record (the
    writer was killed) ends the iteration quietly; anything else malformed raises
    FileFormatError naming the byte offset.
    """
    data = Path(path).read_bytes()
    codec = mavlink.MAVLink(None)
    codec.robust_parsing = True
    if signing_key is not None:
        codec.signing.secret_key = bytes(signing_key)
        verify_signature_first(codec)
    pos = 0
    while pos + _STAMP.size + 3 <= len(data):
        (t_us,) = _STAMP.unpack_from(data, pos)
        start = pos + _STAMP.size
        length = packet_length(data[start:start + 3])
        if length is None:
            raise FileFormatError(f"no MAVLink packet start at byte {start} (not a .tlog?)", path=str(path))
        if start + length > len(data):
            log.info("%s: truncated last record at byte %d", path, pos)
            return
        pos = start + length
        try:
            msgs = codec.parse_buffer(data[start:pos]) or []
        except mavlink.MAVError:
            continue
        for m in msgs:
            if not isinstance(m, mavlink.MAVLink_bad_data):
                yield t_us, m
