"""Synthetic but realistic captures: radiotap probe requests as Linux monitor-mode drivers record them.

Used by the benchmark, the tests and the simulator's frame feed. Frames are written with ``struct``
(no packet library), so 100,000 frames take well under a second; the tests check that scapy's
dissector reads the same fields back. What makes them realistic:

- the radiotap header of a two-chain Intel/Atheros adapter: TSFT, flags (FCS included), rate,
  channel, combined antenna signal, noise, then one extra radiotap namespace per antenna with its
  own signal and antenna index (three present words, fields aligned as the spec says);
- probe requests whose information elements follow real phones' (wildcard SSID, rates, extended
  rates, DS parameter set, HT capabilities, extended capabilities, interworking, vendor elements
  such as Apple's or Microsoft's WPS), one element list per phone model;
- randomized, locally administered addresses that change per burst, sequence numbers that run on
  within a burst, the channel of each frame in its DS element and radiotap channel field, and a
  4-byte FCS at the end.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass

import numpy as np

# Element lists per model, without SSID and DS (added per frame). Bodies are typical of each family.
_HT = bytes.fromhex("2d1a") + bytes.fromhex("ef0903ffff000000000000000000000000000000000000000000")[:26]
MODELS: dict[str, list[bytes]] = {
    "ios17": [b"\x01\x04\x02\x04\x0b\x16", b"\x32\x08\x0c\x12\x18\x24\x30\x48\x60\x6c", _HT,
              b"\x7f\x0a\x04\x00\x0a\x02\x01\x40\x40\x00\x01\x20", b"\xdd\x0b\x00\x17\xf2\x0a\x00\x01\x04\x00\x00\x00\x00",
              b"\xff\x03\x02\x00\x1c"],
    "android14": [b"\x01\x08\x02\x04\x0b\x16\x0c\x12\x18\x24", b"\x32\x04\x30\x48\x60\x6c", _HT,
                  b"\x7f\x08\x00\x00\x08\x00\x00\x00\x00\x40", b"\x6b\x01\x0f",
                  b"\xdd\x08\x00\x50\xf2\x08\x00\x10\x00\x00"],
    "android10": [b"\x01\x08\x02\x04\x0b\x16\x0c\x12\x18\x24", b"\x32\x04\x30\x48\x60\x6c",
                  b"\x2d\x1a\x2d\x11\x17\xff\xff\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00",
                  b"\x7f\x08\x04\x00\x00\x00\x00\x00\x00\x40"],
    "windows": [b"\x01\x08\x82\x84\x8b\x96\x0c\x12\x18\x24", b"\x32\x04\x30\x48\x60\x6c", _HT,
                b"\xdd\x0e\x00\x50\xf2\x04\x10\x4a\x00\x01\x10\x10\x3a\x00\x01\x00"],
}

RADIOTAP_PRESENT = (
    (1 << 0) | (1 << 1) | (1 << 2) | (1 << 3) | (1 << 5) | (1 << 6) | (1 << 29) | (1 << 31),  # TSFT..noise, ns, ext
    (1 << 5) | (1 << 11) | (1 << 29) | (1 << 31),  # antenna 0: signal, index
    (1 << 5) | (1 << 11),  # antenna 1
)


def channel_freq(ch: int) -> int:
    return 2484 if ch == 14 else 2407 + 5 * ch if ch <= 13 else 5000 + 5 * ch


def radiotap(tsft: int, freq: int, rssi: int, ant: tuple[int, int]) -> bytes:
    """A radiotap header with three present words: TSFT, flags (FCS at end), rate, channel, combined
    signal and noise, then two antenna namespaces (signal, antenna index). The 16-byte preamble
    (version, pad, length, 3 present words) leaves TSFT 8-aligned without padding."""
    h = struct.pack("<BBHIII", 0, 0, 0, *RADIOTAP_PRESENT)  # 16 bytes: TSFT is 8-aligned here
    h += struct.pack("<QBBHHbb", tsft, 0x10, 2, freq, 0x00a0, rssi, -95)
    h += struct.pack("<bBbB", ant[0], 0, ant[1], 1)
    return h[:2] + struct.pack("<H", len(h)) + h[4:]


def probe_request(addr: int, seq: int, ch: int, model: list[bytes], ssid: bytes = b"") -> bytes:
    body = bytes([0, len(ssid)]) + ssid + model[0] + model[1] + bytes([3, 1, ch]) + b"".join(model[2:])
    hdr = struct.pack("<BBH6s6s6sH", 0x40, 0, 0, b"\xff" * 6, addr.to_bytes(6, "big"), b"\xff" * 6, (seq & 0xFFF) << 4)
    frame = hdr + body
    return frame + struct.pack("<I", zlib.crc32(frame))


@dataclass(frozen=True)
class Truth:
    """What the synthetic capture holds, frame by frame (to compare a parser's output with)."""

    t_s: np.ndarray
    address: np.ndarray
    rssi_dbm: np.ndarray
    channel: np.ndarray
    phone: np.ndarray  # index of the phone that sent it
    model: np.ndarray  # index into MODELS


def pcap_bytes(records: list[tuple[float, bytes]], linktype: int = 127) -> bytes:
    """A classic little-endian microsecond pcap of (UNIX time, frame) records."""
    out = [struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, linktype)]
    for t, data in records:
        sec = int(t)
        out.append(struct.pack("<IIII", sec, int(round((t - sec) * 1e6)), len(data), len(data)))
        out.append(data)
    return b"".join(out)


def synthetic_capture(n_frames: int, *, n_phones: int = 20, t0_s: float = 1.7e9, rng: np.random.Generator,
                      rssi_dbm=None) -> tuple[bytes, Truth]:
    """``n_frames`` probe requests from ``n_phones`` phones in bursts of 2-8 frames on channels 1/6/11,
    each burst under a new random address; RSSI uniform in -95..-40 dBm unless ``rssi_dbm(phone, t_s)``
    gives it. Returns the pcap bytes and the truth."""
    names = list(MODELS)
    models = rng.integers(0, len(names), n_phones)
    recs: list[tuple[float, bytes]] = []
    cols: list[tuple] = []
    t = t0_s
    seqs = rng.integers(0, 4096, n_phones)
    while len(recs) < n_frames:
        p = int(rng.integers(n_phones))
        addr = (int(rng.integers(0, 2**48)) | (0x02 << 40)) & ~(0x01 << 40)  # local, unicast
        ch = int(rng.choice([1, 6, 11]))
        for _ in range(int(rng.integers(2, 9))):
            if len(recs) >= n_frames:
                break
            t += float(rng.exponential(0.004))
            r = int(round(rssi_dbm(p, t))) if rssi_dbm is not None else int(rng.integers(-95, -39))
            r = max(-127, min(0, r))
            seqs[p] = (seqs[p] + 1) % 4096
            ant = (max(-127, r - int(rng.integers(0, 4))), max(-127, r - int(rng.integers(0, 4))))
            frame = radiotap(int((t - t0_s) * 1e6), channel_freq(ch), r, ant) + probe_request(
                addr, int(seqs[p]), ch, MODELS[names[models[p]]])
            recs.append((t, frame))
            cols.append((t, addr, r, ch, p, models[p]))
    a = np.array(cols, dtype=object).reshape(-1, 6)
    truth = Truth(a[:, 0].astype(float), a[:, 1].astype(np.int64), a[:, 2].astype(int), a[:, 3].astype(int),
                  a[:, 4].astype(int), a[:, 5].astype(int))
    return pcap_bytes(recs), truth
