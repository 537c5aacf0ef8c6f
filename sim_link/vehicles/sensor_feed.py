"""The simulated companion's slots, sent through the real sensor: world -> radio frames -> parser.

``uavloc sim --companion --via-sense`` makes the companion emulator build, for every slot the world
says it heard, the radiotap probe requests a monitor-mode adapter would have captured (one per
frame, at the slot's RSSI rounded to whole dBm as drivers report it, on the slot's channel, from
the slot's address), and hand them to :mod:`uavloc_gcs.sense` as a capture: the entries it sends
are then the parser's and aggregator's output, not the world's.

The world's fingerprint travels inside the frames: each phone model's probe requests carry an
Extended Capabilities element whose body holds the world's fingerprint, so the sensor's content
hash is a one-to-one function of it (equal models, equal hashes; different models, different).

Slots the BLE radio heard (the world's Find My beacons, ``SlotBatch.radio``) become the
advertisements an Ubertooth-style sniffer captures (link type 256): ADV_NONCONN_IND from the slot's
random static address carrying Apple's offline-finding message, the rest of the key a hash of the
address, on the slot's advertising channel; the sensor rebuilds the key and fingerprints it.
"""

from __future__ import annotations


import hashlib
import struct

import numpy as np

from uavloc_gcs.observations import SlotBatch
from uavloc_gcs.sense import parse_capture_bytes
from uavloc_gcs.sense.aggregate import slot_entries
from uavloc_gcs.sense.synth import channel_freq, pcap_bytes, probe_request, radiotap

_RATES = [b"\x01\x08\x02\x04\x0b\x16\x0c\x12\x18\x24", b"\x32\x04\x30\x48\x60\x6c"]


def _elements(fingerprint: int) -> list[bytes]:
    body = b"\x04\x00\x0a\x02" + int(fingerprint & 0xFFFFFFFF).to_bytes(4, "big")
    return _RATES + [b"\x7f" + bytes([len(body)]) + body]


def frames_for(heard: SlotBatch, slot_s: float, epoch_unix_s: float) -> bytes:
    """A radiotap pcap of the frames behind ``heard`` (UNIX times ``epoch_unix_s + t``)."""
    recs = []
    seq = 0
    for k in range(len(heard)):
        n = int(heard.n_samples[k])
        ch = int(heard.channel[k]) or 6
        r = int(round(float(heard.rssi_dbm[k])))
        ies = _elements(int(heard.fingerprint[k]))
        for j in range(n):
            t = epoch_unix_s + float(heard.t_s[k]) + slot_s * (j + 0.5) / (n + 1)
            seq = (seq + 1) % 4096
            frame = radiotap(0, channel_freq(ch), max(-120, min(0, r)), (r, r)) + probe_request(
                int(heard.address[k]) & 0xFFFFFFFFFFFF, seq, ch, ies)
            recs.append((t, frame))
    recs.sort(key=lambda x: x[0])
    return pcap_bytes(recs)


_RF_CHANNEL = {37: 0, 38: 12, 39: 39}  # advertising channel index -> RF channel (Core Vol 6 Part B 1.4.1)
_BLE_FLAGS = 0x0001 | 0x0002 | 0x0400 | 0x0800  # dewhitened, signal valid, CRC checked, CRC valid


def ble_frames_for(heard: SlotBatch, slot_s: float, epoch_unix_s: float) -> bytes:
    """A link-type-256 pcap of the Find My advertisements behind BLE slots ``heard``."""
    recs = []
    for k in range(len(heard)):
        addr = int(heard.address[k]) & 0xFFFFFFFFFFFF
        first = addr.to_bytes(6, "big")
        rest = hashlib.blake2b(first, digest_size=22).digest()  # the key beyond the address
        msg = bytes([0x12, 25, 0x00]) + rest + bytes([first[0] >> 6, 0x00])
        ad = bytes([3 + len(msg), 0xFF, 0x4C, 0x00]) + msg
        payload = addr.to_bytes(6, "little") + ad
        ll = struct.pack("<I", 0x8E89BED6) + bytes([0x02 | 0x40, len(payload)]) + payload + b"\x55\x55\x55"
        ch = int(heard.channel[k]) if int(heard.channel[k]) in _RF_CHANNEL else 37
        r = max(-127, min(0, int(round(float(heard.rssi_dbm[k])))))
        n = int(heard.n_samples[k])
        for j in range(n):
            t = epoch_unix_s + float(heard.t_s[k]) + slot_s * (j + 0.5) / (n + 1)
            recs.append((t, struct.pack("<BbbBIH", _RF_CHANNEL[ch], r, -128, 0, 0x8E89BED6, _BLE_FLAGS) + ll))
    recs.sort(key=lambda x: x[0])
    return pcap_bytes(recs, linktype=256)


def through_sensor(heard: SlotBatch, slot_s: float, epoch_unix_s: float) -> SlotBatch:
    """``heard`` as the real sensor reports it: addresses, whole-dBm means, counts and channels from
    the parser and the per-slot aggregator; positions and vehicles from the world's slots. Wi-Fi
    and BLE slots each through their own capture (one link type per file)."""
    if len(heard) == 0:
        return heard
    from dataclasses import replace

    from uavloc_gcs.radios import is_ble

    ble = is_ble(heard)
    parts = []
    for sel, build in ((~ble, frames_for), (ble, ble_frames_for)):
        if np.any(sel):
            f, _ = parse_capture_bytes(build(heard.take(sel), slot_s, epoch_unix_s))
            parts.append(replace(f, t_s=f.t_s - epoch_unix_s))
    frames = parts[0] if len(parts) == 1 else type(parts[0]).concat(parts)
    e = slot_entries(frames, slot_s)
    slot_of = np.round(heard.t_s / slot_s).astype(np.int64)
    row = {(int(s), int(a)): i for i, (s, a) in enumerate(zip(slot_of, heard.address & 0xFFFFFFFFFFFF))}
    idx = np.array([row[(int(round(t / slot_s)), int(a))] for t, a in zip(e.t_s, e.address)], dtype=int)
    return SlotBatch.from_columns(heard.t_s[idx], heard.vehicle[idx], heard.xyz_m[idx], e.address, e.rssi_dbm,
                                  e.n_frames, address=e.address, fingerprint=e.fingerprint, channel=e.channel,
                                  radio=e.radio)


__all__ = ["ble_frames_for", "frames_for", "through_sensor"]
