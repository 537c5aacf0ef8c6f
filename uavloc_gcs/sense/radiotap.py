"""Radio headers in front of 802.11 frames: radiotap (link type 127) and PPI (192).

Radiotap (https://www.radiotap.org): ``version u8 = 0, pad u8, length u16 LE, present u32 LE``,
more present words while bit 31 is set, then the fields of the set bits in bit order, each aligned
to its natural size counted from the header's start. Bit 29 starts a new radiotap namespace (how
drivers report each antenna separately), bit 30 a vendor namespace whose data is skipped by the
length its header gives; a word after one with neither goes on with bits 32-63 of the same
namespace (a real capture in tcpdump's tests sets some: no field is defined there, so parsing
stops). The layout of a given run of present words is computed once and cached, so a capture from
one adapter costs one dict look-up per frame.

Returned per frame: :class:`RadioInfo` with the signal in dBm (the first antenna-signal field, the
combined one where the driver gives several), the per-antenna signals, the channel frequency, the
TSFT and the flags (FCS present / FCS bad).
"""

from __future__ import annotations

import struct
from typing import NamedTuple

# (alignment, size) of radiotap fields by bit number; None: unknown size (parsing stops there)
FIELDS: dict[int, tuple[int, int]] = {
    0: (8, 8), 1: (1, 1), 2: (1, 1), 3: (2, 4), 4: (1, 2), 5: (1, 1), 6: (1, 1), 7: (2, 2),
    8: (2, 2), 9: (2, 2), 10: (1, 1), 11: (1, 1), 12: (1, 1), 13: (1, 1), 14: (2, 2), 15: (2, 2),
    16: (1, 1), 17: (1, 1), 18: (4, 8), 19: (1, 3), 20: (4, 8), 21: (2, 12), 22: (8, 12),
    23: (2, 12), 24: (2, 12), 25: (2, 6), 26: (1, 1), 27: (2, 4),
}
TSFT, FLAGS, CHANNEL, ANT_SIGNAL, ANTENNA, XCHANNEL = 0, 1, 3, 5, 11, 18
FLAG_FCS = 0x10  # the frame ends with its 4-byte FCS
FLAG_BAD_FCS = 0x40  # the FCS check failed

_U16 = struct.Struct("<H")
_U32 = struct.Struct("<I")


class RadioInfo(NamedTuple):
    header_len: int  # bytes before the 802.11 frame
    rssi_dbm: int | None  # first antenna signal [dBm]
    antennas_dbm: tuple[int, ...]  # every antenna-signal field, in order
    freq_mhz: int  # 0 when unknown
    xchannel: int  # channel number from the XChannel field, 0 when absent
    flags: int


class Malformed(Exception):
    """A radio header whose lengths do not fit the frame; ``reason`` names the skip counter."""

    def __init__(self, reason: str):
        super().__init__(reason)
        self.reason = reason


# layout cache: present-word bytes -> (offsets of signal fields, flags, channel, xchannel) or None
_LAYOUTS: dict[bytes, tuple | None] = {}
_MAX_LAYOUTS = 4096


def _layout(data: bytes, hlen: int) -> tuple[tuple | None, int]:
    """Walk the present words of a radiotap header: (layout, end of present words). A layout is
    (signal offsets, flags offset, channel offset, xchannel offset); offsets are -1 when absent.
    Raises Malformed."""
    pos = 4
    words = []
    while True:
        if pos + 4 > hlen:
            raise Malformed("bad_radiotap")
        w = _U32.unpack_from(data, pos)[0]
        words.append(w)
        pos += 4
        if not w & 0x80000000:
            break
    key = data[4:pos]
    cached = _LAYOUTS.get(key)
    if cached is not None:
        return cached, pos
    off = pos
    sig: list[int] = []
    flags = chan = xchan = -1
    base = 0  # bit number of this word's bit 0 in its namespace
    for w in words:
        for b in range(29):
            if not w & (1 << b):
                continue
            bit = base + b
            spec = FIELDS.get(bit)
            if spec is None:  # a field we cannot size (TLVs, new bits): what follows is unreachable
                return _finish(key, sig, flags, chan, xchan), pos
            align, size = spec
            off += -off % align
            if bit == ANT_SIGNAL:
                sig.append(off)
            elif bit == FLAGS and flags < 0:
                flags = off
            elif bit == CHANNEL and chan < 0:
                chan = off
            elif bit == XCHANNEL and xchan < 0:
                xchan = off
            off += size
        if w & (1 << 30):  # vendor namespace header: OUI(3), sub-namespace(1), skip length(2)
            off += -off % 2
            if off + 6 > hlen:
                raise Malformed("bad_radiotap")
            skip = _U16.unpack_from(data, off + 4)[0]
            off += 6 + skip
            if off > hlen:
                raise Malformed("bad_radiotap")
            # the skip depends on this frame's data: the layout is not cached, and fields after the
            # vendor namespace (rare: drivers put it last) are not read
            return (tuple(sig), flags, chan, xchan), pos
        # bit 29: the next word starts the radiotap namespace again (another antenna's fields);
        # otherwise it goes on with bits 32-63 of this one (none is defined: parsing stops there)
        base = 0 if w & (1 << 29) else base + 32
    if off > hlen:
        raise Malformed("bad_radiotap")
    return _finish(key, sig, flags, chan, xchan), pos


def _finish(key: bytes, sig, flags, chan, xchan):
    layout = (tuple(sig), flags, chan, xchan)
    if len(_LAYOUTS) < _MAX_LAYOUTS:
        _LAYOUTS[key] = layout
    return layout


def parse_radiotap(data: bytes) -> RadioInfo:
    """The radiotap header in front of an 802.11 frame. Raises Malformed."""
    if len(data) < 8 or data[0] != 0:
        raise Malformed("bad_radiotap")
    hlen = _U16.unpack_from(data, 2)[0]
    if hlen < 8 or hlen > len(data):
        raise Malformed("bad_radiotap")
    (sig, flags_off, chan_off, xchan_off), _ = _layout(data, hlen)
    for o in sig:
        if o >= hlen:
            raise Malformed("bad_radiotap")
    antennas = tuple(b - 256 if b > 127 else b for b in (data[o] for o in sig))
    flags = data[flags_off] if 0 <= flags_off < hlen else 0
    freq = _U16.unpack_from(data, chan_off)[0] if 0 <= chan_off and chan_off + 2 <= hlen else 0
    xch = data[xchan_off + 6] if 0 <= xchan_off and xchan_off + 8 <= hlen else 0
    if not freq and 0 <= xchan_off and xchan_off + 8 <= hlen:
        freq = _U16.unpack_from(data, xchan_off + 4)[0]
    return RadioInfo(hlen, antennas[0] if antennas else None, antennas, freq, xch, flags)


def parse_ppi(data: bytes) -> RadioInfo:
    """A PPI header (version 0) with its 802.11-common field (type 2) in front of an 802.11 frame.
    Raises Malformed (also when the PPI header does not wrap 802.11)."""
    if len(data) < 8 or data[0] != 0:
        raise Malformed("bad_ppi")
    hlen = _U16.unpack_from(data, 2)[0]
    dlt = _U32.unpack_from(data, 4)[0]
    if hlen < 8 or hlen > len(data):
        raise Malformed("bad_ppi")
    if dlt != 105:
        raise Malformed("not_80211")
    pos = 8
    rssi = None
    freq = flags = 0
    while pos + 4 <= hlen:
        ftype, flen = struct.unpack_from("<HH", data, pos)
        if pos + 4 + flen > hlen:
            raise Malformed("bad_ppi")
        if ftype == 2 and flen >= 20:  # 802.11-common: tsft(8) flags(2) rate(2) freq(2) chflags(2) fhss(2) dbm(1)
            f = pos + 4
            pflags = _U16.unpack_from(data, f + 8)[0]
            flags = (FLAG_FCS if pflags & 0x1 else 0) | (FLAG_BAD_FCS if pflags & 0x4 else 0)
            freq = _U16.unpack_from(data, f + 12)[0]
            b = data[f + 18]
            rssi = b - 256 if b > 127 else b
            if rssi == 0 or rssi == -128:  # "no value" in PPI
                rssi = None
        pos += 4 + flen
    return RadioInfo(hlen, rssi, () if rssi is None else (rssi,), freq, 0, flags)


def freq_to_channel(freq_mhz: int) -> int:
    """802.11 channel number of a centre frequency (2.4, 5 and 6 GHz bands); 0 when unknown."""
    if freq_mhz == 2484:
        return 14
    if 2412 <= freq_mhz <= 2472:
        return (freq_mhz - 2407) // 5
    if 5955 <= freq_mhz <= 7115:
        return (freq_mhz - 5950) // 5
    if 5000 <= freq_mhz <= 5895:
        return (freq_mhz - 5000) // 5
    return 0
