"""Frames -> what the sensor reports: an emitter id per frame and one entry per (slot, address).

Emitter ids (``frames.csv``'s ``emitter_id``): frames share an id when they come from one radio
(Wi-Fi or BLE), one source address AND carry one content fingerprint. That is deliberately
conservative: two devices never share an id when their content differs (a fingerprint is part of the key), and a phone that
changes its random address gets a new id, which the ground's identity stage links into people
with the flight's geometry (the sensor alone cannot tell a new address of one phone from a second
phone of the same model). Ids count from 1 in order of first frame.

Slots: time is cut into slots of ``slot_s`` on the UNIX clock (starts at multiples of ``slot_s``),
and all frames of one address on one radio in one slot make one entry with the mean of their dBm values, the
frame count (capped at 255, the wire's limit: the rest starts a second entry is not needed, the
count saturates and the mean stays the mean of all), and the channel and fingerprint of the
slot's first frame (RSSI_DIALECT.md, "Several frames, one entry").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .ble import PDU_NAMES
from .ble_ad import apple_type_name
from .frames import RADIO_NAMES, Frames

MAX_FRAMES_PER_ENTRY = 255


def emitter_ids(frames: Frames) -> np.ndarray:
    """(N,) int ids, one per distinct (radio, address, fingerprint), numbered by first appearance."""
    if len(frames) == 0:
        return np.zeros(0, dtype=np.int64)
    key = np.stack([frames.radio.astype(np.int64), frames.address, frames.fingerprint], axis=1)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")  # unique key k appears rank[k]-th
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return rank[inverse.reshape(-1)].astype(np.int64) + 1


@dataclass(frozen=True)
class Entries:
    """K (slot, radio, address) entries, in time order."""

    t_s: np.ndarray  # (K,) slot start, UNIX [s]
    address: np.ndarray  # (K,) int64
    rssi_dbm: np.ndarray  # (K,) mean dBm
    n_frames: np.ndarray  # (K,) int, 1..255
    channel: np.ndarray  # (K,) int
    fingerprint: np.ndarray  # (K,) int64
    radio: np.ndarray  # (K,) int8, frames.RADIO_WIFI / RADIO_BLE

    def __len__(self) -> int:
        return len(self.t_s)


def slot_entries(frames: Frames, slot_s: float) -> Entries:
    """One entry per (slot, address); see the module doc."""
    if slot_s <= 0:
        raise ValueError(f"slot_s must be positive, got {slot_s}")
    if len(frames) == 0:
        z = np.zeros(0)
        return Entries(z, z.astype(np.int64), z, z.astype(int), z.astype(int), z.astype(np.int64), z.astype(np.int8))
    slot = np.floor(frames.t_s / slot_s).astype(np.int64)
    order = np.lexsort((frames.t_s, frames.address, frames.radio, slot))  # by slot, radio, address, time
    s, a, r = slot[order], frames.address[order], frames.radio[order]
    new = np.ones(len(order), dtype=bool)
    new[1:] = (s[1:] != s[:-1]) | (a[1:] != a[:-1]) | (r[1:] != r[:-1])
    starts = np.flatnonzero(new)
    group = np.cumsum(new) - 1
    counts = np.bincount(group)
    mean = np.bincount(group, weights=frames.rssi_dbm[order].astype(float)) / counts
    first = order[starts]
    t = s[starts] * slot_s
    tie = np.lexsort((a[starts], r[starts], t))
    return Entries(t[tie], a[starts][tie], mean[tie], np.minimum(counts, MAX_FRAMES_PER_ENTRY)[tie],
                   frames.channel[first][tie], frames.fingerprint[first][tie], r[starts][tie])


def format_mac(address: int) -> str:
    d = f"{int(address):012x}"
    return ":".join(d[i:i + 2] for i in range(0, 12, 2))


def frames_csv(frames: Frames, ids: np.ndarray) -> str:
    """``frames.csv``: one row per frame used, in time order. Columns: time_unix_s, source_mac,
    channel (802.11 channel, or BLE channel index), rssi_dbm, emitter_id, fingerprint (8 hex
    digits), seq, antennas_dbm (per-antenna signals separated by ';', empty when the radio gives
    only one), radio (``wifi`` or ``ble``), and for BLE frames ble_random (1 random address, 0
    public), ble_pdu (ADV_IND, SCAN_RSP, ...; empty when the source does not say) and apple_type
    (findmy, nearby_info, ...; empty when there is no Apple Continuity message)."""
    lines = ["time_unix_s,source_mac,channel,rssi_dbm,emitter_id,fingerprint,seq,antennas_dbm,radio,ble_random,"
             "ble_pdu,apple_type"]
    for i in np.argsort(frames.t_s, kind="stable").tolist():
        ant = frames.antennas_dbm[i]
        radio = int(frames.radio[i])
        ble = (f"{frames.random[i]},{PDU_NAMES.get(int(frames.pdu[i]), '')},{apple_type_name(int(frames.apple[i]))}"
               if radio else ",,")
        lines.append(f"{frames.t_s[i]:.6f},{format_mac(frames.address[i])},{frames.channel[i]},{frames.rssi_dbm[i]},"
                     f"{ids[i]},{int(frames.fingerprint[i]):08x},{frames.seq[i]},"
                     f"{';'.join(str(v) for v in ant) if len(ant) > 1 else ''},{RADIO_NAMES[radio]},{ble}")
    return "\n".join(lines) + "\n"
