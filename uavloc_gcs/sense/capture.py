"""Capture files: classic pcap, pcapng and btsnoop, read from one buffer as a stream of records.

Every length read from the file is checked against what is left before it is used (as Wireshark's
and dpkt's readers do): a record that runs past the end of the file or claims an impossible length
ends the walk and is counted, never raised. Only a file that is not a capture at all (its first
bytes are neither pcap's, pcapng's nor btsnoop's magic) raises
:class:`~uavloc_gcs.errors.FileFormatError`.

btsnoop (RFC 1761's snoop, as Android's ``btsnoop_hci.log`` and BlueZ's ``btmon -w`` write it;
Wireshark's wiretap/btsnoop.c): ``"btsnoop\\0"``, version u32 = 1, datalink u32 (1001 H1: the HCI
packet without its type byte, which the record's flags give; 1002 H4: with it), then records of
``original length u32, included length u32, flags u32 (bit 0 received, bit 1 command or event),
cumulative drops u32, time i64 [us since 0000-01-01]``, all big-endian, each followed by the
packet. Its records are handed on as link type 187 (LINKTYPE_BLUETOOTH_HCI_H4), H1 packets with the
type byte put back (0x04 event, 0x01 command, 0x02 ACL data).

A record is ``(linktype, t_s, data, snapped)``: the interface's link-layer type (127 radiotap,
192 PPI, 105 bare 802.11, ...), the UNIX time in seconds, the captured bytes and whether the
capture cut the frame short (captured length below the original length).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

from ..errors import FileFormatError

LINKTYPE_IEEE802_11 = 105
LINKTYPE_PRISM = 119
LINKTYPE_RADIOTAP = 127
LINKTYPE_PPI = 192

MAX_RECORD = 262_144  # libpcap's largest snapshot length; a longer record is corruption
PCAP_MAGICS = {
    b"\xd4\xc3\xb2\xa1": ("<", 1e-6), b"\xa1\xb2\xc3\xd4": (">", 1e-6),
    b"\x4d\x3c\xb2\xa1": ("<", 1e-9), b"\xa1\xb2\x3c\x4d": (">", 1e-9),
}
PCAPNG_SHB = b"\x0a\x0d\x0d\x0a"
BTSNOOP_MAGIC = b"btsnoop\0"
BTSNOOP_H1, BTSNOOP_H4 = 1001, 1002
BTSNOOP_EPOCH_US = 0x00DCDDB30F2F8000  # microseconds from 0000-01-01 to 1970-01-01 (wiretap/btsnoop.c)
LINKTYPE_BLUETOOTH_HCI_H4 = 187

Record = tuple[int, float, bytes, bool]


@dataclass
class ReadStats:
    """What the reader met: records handed on, and records or bytes it could not read."""

    records: int = 0
    bad_records: int = 0  # a record header that runs past the end or claims an impossible length
    trailing_bytes: int = 0  # bytes left unread after the walk stopped
    other_blocks: dict[int, int] = field(default_factory=dict)  # pcapng block types not carrying packets


def capture_kind(head: bytes) -> str | None:
    """'pcap', 'pcapng', 'btsnoop' or None from a file's first 8 bytes."""
    if head[:4] in PCAP_MAGICS:
        return "pcap"
    if head[:4] == PCAPNG_SHB:
        return "pcapng"
    if head[:8] == BTSNOOP_MAGIC:
        return "btsnoop"
    return None


def read_records(buf: bytes, stats: ReadStats, *, path: str = "<buffer>") -> Iterator[Record]:
    """The records of a pcap or pcapng buffer. Raises FileFormatError only when the buffer is not a
    capture (no magic, or a header shorter than the format's)."""
    kind = capture_kind(buf[:8])
    if kind == "pcap":
        return _pcap(buf, stats, path)
    if kind == "pcapng":
        return _pcapng(buf, stats, path)
    if kind == "btsnoop":
        return _btsnoop(buf, stats, path)
    raise FileFormatError("is not a pcap, pcapng or btsnoop capture (its first bytes are "
                          f"{buf[:4].hex() or 'missing'}, not a capture's magic number)", path=path)


def read_capture_file(path: str | Path) -> bytes:
    """The whole file, refused in one sentence when missing or not a capture."""
    p = Path(path)
    try:
        buf = p.read_bytes()
    except FileNotFoundError:
        raise FileFormatError("file not found", path=str(p)) from None
    except IsADirectoryError:
        raise FileFormatError("is a directory, not a capture file", path=str(p)) from None
    if capture_kind(buf[:8]) is None:
        raise FileFormatError("is not a pcap, pcapng or btsnoop capture (its first bytes are "
                              f"{buf[:4].hex() or 'missing'}, not a capture's magic number)", path=str(p))
    return buf


def _pcap(buf: bytes, stats: ReadStats, path: str) -> Iterator[Record]:
    if len(buf) < 24:
        raise FileFormatError(f"pcap header is {len(buf)} bytes, needs 24", path=path)
    order, tick = PCAP_MAGICS[buf[:4]]
    linktype = struct.unpack_from(order + "I", buf, 20)[0] & 0x0FFFFFFF
    head = struct.Struct(order + "IIII")
    unpack = head.unpack_from
    pos, n = 24, len(buf)
    while pos + 16 <= n:
        sec, frac, incl, orig = unpack(buf, pos)
        end = pos + 16 + incl
        if incl > MAX_RECORD or end > n:
            stats.bad_records += 1
            break
        stats.records += 1
        yield linktype, sec + frac * tick, buf[pos + 16:end], incl < orig
        pos = end
    stats.trailing_bytes += n - pos


def _pcapng(buf: bytes, stats: ReadStats, path: str) -> Iterator[Record]:
    n = len(buf)
    pos = 0
    order = "<"
    links: list[tuple[int, int, float]] = []  # per interface of the section: linktype, ticks per s, tick
    while pos + 12 <= n:
        if buf[pos:pos + 4] == PCAPNG_SHB:  # a section header fixes the byte order of what follows
            if pos + 12 > n:
                break
            bom = buf[pos + 8:pos + 12]
            if bom == b"\x4d\x3c\x2b\x1a":
                order = "<"
            elif bom == b"\x1a\x2b\x3c\x4d":
                order = ">"
            else:
                if pos == 0:
                    raise FileFormatError("pcapng section header has no byte-order magic", path=path)
                stats.bad_records += 1
                break
            links = []
        btype, blen = struct.unpack_from(order + "II", buf, pos)
        if blen < 12 or blen % 4 or pos + blen > n:
            stats.bad_records += 1
            break
        body = pos + 8
        bend = pos + blen - 4
        if btype == 6 and bend - body >= 20:  # enhanced packet block
            iface, hi, lo, cap, orig = struct.unpack_from(order + "IIIII", buf, body)
            if iface < len(links) and body + 20 + cap <= bend:
                lt, per_s, tick = links[iface]
                stats.records += 1
                sec, rem = divmod((hi << 32) | lo, per_s)
                yield lt, sec + rem * tick, buf[body + 20:body + 20 + cap], cap < orig
            else:
                stats.bad_records += 1
        elif btype == 1 and bend - body >= 8:  # interface description block
            lt = struct.unpack_from(order + "H", buf, body)[0]
            links.append((lt, *_if_tick(buf, body + 8, bend, order)))
        elif btype == 3 and bend - body >= 4:  # simple packet block: no timestamp
            stats.bad_records += 1
        elif btype == 2 and bend - body >= 20:  # obsolete packet block
            iface, _, hi, lo, cap, orig = struct.unpack_from(order + "HHIIII", buf, body)
            if iface < len(links) and body + 20 + cap <= bend:
                lt, per_s, tick = links[iface]
                stats.records += 1
                sec, rem = divmod((hi << 32) | lo, per_s)
                yield lt, sec + rem * tick, buf[body + 20:body + 20 + cap], cap < orig
            else:
                stats.bad_records += 1
        elif btype != PCAPNG_SHB_TYPE:
            stats.other_blocks[btype] = stats.other_blocks.get(btype, 0) + 1
        pos += blen
    stats.trailing_bytes += n - pos


PCAPNG_SHB_TYPE = 0x0A0D0D0A
_H1_TYPE = {0: b"\x02", 1: b"\x02", 2: b"\x01", 3: b"\x04"}  # flags & 3 -> H4 type byte


def _btsnoop(buf: bytes, stats: ReadStats, path: str) -> Iterator[Record]:
    if len(buf) < 16:
        raise FileFormatError(f"btsnoop header is {len(buf)} bytes, needs 16", path=path)
    version, datalink = struct.unpack_from(">II", buf, 8)
    if version != 1 or datalink not in (BTSNOOP_H1, BTSNOOP_H4):
        raise FileFormatError(f"btsnoop version {version}, datalink {datalink} is not read (version 1 with "
                              "datalink 1001 H1 or 1002 H4 is)", path=path)
    unpack = struct.Struct(">IIIIq").unpack_from
    pos, n = 16, len(buf)
    while pos + 24 <= n:
        orig, incl, flags, _, ts = unpack(buf, pos)
        end = pos + 24 + incl
        if incl > MAX_RECORD or end > n:
            stats.bad_records += 1
            break
        data = buf[pos + 24:end]
        if datalink == BTSNOOP_H1:
            data = _H1_TYPE[flags & 3] + data
        stats.records += 1
        yield LINKTYPE_BLUETOOTH_HCI_H4, (ts - BTSNOOP_EPOCH_US) / 1e6, data, incl < orig
        pos = end
    stats.trailing_bytes += n - pos


def _if_tick(buf: bytes, pos: int, end: int, order: str) -> tuple[int, float]:
    """An interface's timestamp unit from its if_tsresol option (default microseconds), as
    (ticks per second, tick in seconds): times are computed as whole seconds plus the remainder, so
    a microsecond pcapng gives the same floats as a microsecond pcap."""
    while pos + 4 <= end:
        code, olen = struct.unpack_from(order + "HH", buf, pos)
        if code == 0:
            break
        if code == 9 and olen >= 1 and pos + 5 <= end:
            v = buf[pos + 4]
            per_s = 2 ** min(v & 0x7F, 63) if v & 0x80 else 10 ** min(v, 18)
            return per_s, 1.0 / per_s if v & 0x80 else 10.0 ** -min(v, 18)
        pos += 4 + olen + (-olen % 4)
    return 1_000_000, 1e-6
