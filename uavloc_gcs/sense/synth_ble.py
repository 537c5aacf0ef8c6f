"""A synthetic Bluetooth LE sniffer capture (link type 256, as Ubertooth writes it) for the benchmark.

Written with ``struct`` (100,000 frames in about a second); the tests build theirs with scapy and
check them against tshark, and the benchmark checks uavloc's reading of this one against the truth
kept here and against scapy's dissector. The scene, per advertiser:

- offline iPhones sending Find My (Apple 0x12, full key form) every 2 s (OpenHaystack's
  ``ADV_INTERVAL``, after Heinrich et al., PETS 2021), each under the random static address its
  key gives;
- other devices nearby: Apple nearby info (0x10) or proximity pairing (0x07), and non-Apple
  devices with flags and a name, every 100 ms to 1 s;

every advertising event plus the Core spec's 0-10 ms advDelay (Vol 6 Part B 4.4.2.2.1), heard on
one of the three primary channels; ADV_IND, ADV_NONCONN_IND and SCAN_RSP PDUs with a 3-byte CRC;
RSSI uniform in -100..-40 dBm.
"""

from __future__ import annotations

import heapq
import struct
from dataclasses import dataclass

import numpy as np

from .synth import pcap_bytes

ACCESS_ADDRESS = struct.pack("<I", 0x8E89BED6)
RF_CHANNEL = {37: 0, 38: 12, 39: 39}
FLAGS = 0x0001 | 0x0002 | 0x0400 | 0x0800  # dewhitened, signal valid, CRC checked, CRC valid


@dataclass(frozen=True)
class BleTruth:
    t_s: np.ndarray
    address: np.ndarray
    rssi_dbm: np.ndarray
    channel: np.ndarray
    apple: np.ndarray  # Apple Continuity type, -1 none


def _advertiser(k: int, findmy: bool, rng: np.random.Generator) -> tuple[int, int, bytes, int, float]:
    """(address, PDU type, AdvData, Apple type, interval [s]) of advertiser k."""
    flags = bytes([2, 0x01, 0x06])
    if findmy:
        key = rng.integers(0, 256, 28, dtype=np.uint8).tobytes()
        address = int.from_bytes(bytes([key[0] | 0xC0]) + key[1:6], "big")
        msg = bytes([0x12, 25, 0x00]) + key[6:] + bytes([key[0] >> 6, 0x00])
        return address, 2, bytes([3 + len(msg), 0xFF, 0x4C, 0x00]) + msg, 0x12, 2.0
    address = int(rng.integers(0, 2**48)) | (0xC0 << 40)
    kind = k % 3
    if kind == 0:
        msg = bytes([0x10, 5, 0x07, 0x1C, *rng.integers(0, 256, 3).tolist()])
        ad, apple = flags + bytes([3 + len(msg), 0xFF, 0x4C, 0x00]) + msg, 0x10
    elif kind == 1:
        msg = bytes([0x07, 25]) + rng.integers(0, 256, 25, dtype=np.uint8).tobytes()
        ad, apple = bytes([3 + len(msg), 0xFF, 0x4C, 0x00]) + msg, 0x07
    else:
        name = f"sensor-{k:04d}".encode()
        ad, apple = flags + bytes([1 + len(name), 0x09]) + name, -1
    return address, (0, 2, 4)[kind], ad, apple, float(rng.uniform(0.1, 1.0))


def synthetic_ble_capture(n_frames: int, *, n_findmy: int = 30, n_other: int = 30, t0_s: float = 1.7e9,
                          rng: np.random.Generator) -> tuple[bytes, BleTruth]:
    """``n_frames`` advertisements of the scene above as a link-type-256 pcap, and the truth."""
    advs = [_advertiser(k, k < n_findmy, rng) for k in range(n_findmy + n_other)]
    queue = [(t0_s + float(rng.uniform(0, a[4])), k) for k, a in enumerate(advs)]
    heapq.heapify(queue)
    recs: list[tuple[float, bytes]] = []
    cols: list[tuple] = []
    channels = rng.choice((37, 38, 39), n_frames).tolist()
    rssis = rng.integers(-100, -39, n_frames).tolist()
    delays = rng.uniform(0, 0.010, n_frames).tolist()
    while len(recs) < n_frames:
        t, k = heapq.heappop(queue)
        address, pdu, ad, apple, interval = advs[k]
        i = len(recs)
        heapq.heappush(queue, (t + interval + delays[i], k))
        ch, rssi = channels[i], rssis[i]
        payload = address.to_bytes(6, "little") + ad
        ll = ACCESS_ADDRESS + bytes([pdu | 0x40, len(payload)]) + payload + b"\x55\x55\x55"
        phdr = struct.pack("<BbbBIH", RF_CHANNEL[ch], rssi, -128, 0, 0x8E89BED6, FLAGS)
        t = round(t, 6)
        recs.append((t, phdr + ll))
        cols.append((t, address, rssi, ch, apple))
    a = np.array(cols, dtype=object).reshape(-1, 5)
    truth = BleTruth(a[:, 0].astype(float), a[:, 1].astype(np.int64), a[:, 2].astype(int), a[:, 3].astype(int),
                     a[:, 4].astype(int))
    return pcap_bytes(recs, linktype=256), truth
