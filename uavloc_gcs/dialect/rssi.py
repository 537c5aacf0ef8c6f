"""UAVLOC_RSSI_BATCH2 / UAVLOC_RSSI_BATCH <-> SlotBatch: the RSSI dialect's codec.

One message carries up to 12 (slot, source) entries heard by one vehicle within 255 ms. The
vehicle position is sent once (lat/lon degE7, height above home in mm, velocity NED in cm/s at
``time_usec``); the position of entry i is reconstructed as ``position + velocity * dt_ms[i]``.
The encoder picks the reference as the first entry's slot and the velocity as the least-squares
slope of the entries' positions over time, which is exact for straight, constant-speed flight and
off by a few centimetres in a 5 m/s^2 turn (a t^2 / 8 over 0.2 s).

Two messages (``RSSI_DIALECT.md``):

- ``UAVLOC_RSSI_BATCH2`` (54101) carries per entry what a sensor knows: the 48-bit source
  address, a 32-bit content fingerprint, the channel, the frame count, the mean RSSI and the radio
  (extension field ``radio``: 0 Wi-Fi, 1 Bluetooth LE; 0 from senders that predate it). The
  ground's ``emitter_id`` of a decoded entry is its address (a sensor knows no person).
- ``UAVLOC_RSSI_BATCH`` (54100, the first version) carries a uint32 emitter id, the RSSI and the
  sample count; decoded entries get ``address = emitter_id``, fingerprint 0 and channel 0
  (unknown). Old ``.tlog`` files and old companions speak it.

The encoders take ``message``: :data:`BATCH2`, :data:`BATCH` or :data:`AUTO` (the default), which
sends the old message when it carries the slots losslessly (every address equal to its emitter id
and within uint32, no fingerprint, no channel, all Wi-Fi: the paper's continuous world), so that a ground
station older than UAVLOC_RSSI_BATCH2 still understands it, and UAVLOC_RSSI_BATCH2 otherwise. Both
cost the same bytes then: BATCH2's address-high, channel, fingerprint and radio arrays are
extension fields, last on the wire, and MAVLink 2 trims them when they are zero (a Wi-Fi-only
message costs what it did before the radio field; one with a BLE entry carries all 12 radio bytes).

A message with ``count`` 0 is a *keepalive* (:func:`keepalive_message`): the receiver listened and
everything it heard before ``time_usec`` has been sent. A companion sends one whenever a second
(:data:`KEEPALIVE_S`) has passed without a message, so that the ground can tell "heard nothing"
from "has not heard from the receiver yet" (:func:`message_time_s`; issue 42: a look was judged
missed while its slots were still on their way). Ground stations that predate it decode it as no
entries.

Time: ``time_usec`` is UNIX time in microseconds. A :class:`SlotBatch` time ``t_s`` is seconds on
the mission clock, ``t_s = unix_s - epoch_unix_s``; both directions take ``epoch_unix_s``.

Quantisation (what a round trip loses): time 1 ms (entries relative to the reference; slot
starts that are whole milliseconds apart come back exactly), position ~1 cm, RSSI 0.01 dB; a
fingerprint wider than 32 bits travels as its low 32 bits (:func:`wire_fingerprint`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable, Sequence

import numpy as np

from ..geo import LocalFrame
from ..observations import SlotBatch
from . import RSSI_BATCH_MAX_ENTRIES, RSSI_MESSAGE_TYPES, mavlink

MAX_ENTRIES = RSSI_BATCH_MAX_ENTRIES
MAX_SPAN_MS = 255  # dt_ms is uint8
DEFAULT_WINDOW_S = 0.2  # a companion flushes 200 ms after the first entry at the latest
KEEPALIVE_S = 1.0  # a receiver with nothing to send says so at least this often (a count-0 message)
COMPANION_COMPONENT_ID = 191  # MAV_COMP_ID_ONBOARD_COMPUTER

BATCH = "UAVLOC_RSSI_BATCH"
BATCH2 = "UAVLOC_RSSI_BATCH2"
AUTO = "auto"
MESSAGES = (AUTO, BATCH2, BATCH)

ADDRESS_BITS = 48
FINGERPRINT_BITS = 32
_UINT32_MAX = 2**32 - 1
_ADDRESS_MAX = 2**ADDRESS_BITS - 1


def is_rssi_message(msg) -> bool:
    """Whether ``msg`` carries heard slots (either version of the batch)."""
    return msg.get_type() in RSSI_MESSAGE_TYPES


def wire_fingerprint(fingerprint) -> np.ndarray:
    """The fingerprint as the wire carries it: its low 32 bits (int64 array); a nonzero fingerprint
    whose low 32 bits are 0 becomes 1, since 0 means unknown."""
    fp = np.asarray(fingerprint, dtype=np.int64)
    low = fp & np.int64(_UINT32_MAX)
    return np.where((low == 0) & (fp != 0), np.int64(1), low)


def split_address(address) -> tuple[np.ndarray, np.ndarray]:
    """48-bit addresses -> (high 16 bits, low 32 bits): 0x123456789abc -> (0x1234, 0x56789abc)."""
    a = np.asarray(address, dtype=np.int64)
    return a >> 32, a & np.int64(_UINT32_MAX)


def join_address(hi, lo) -> np.ndarray:
    """(high 16 bits, low 32 bits) -> 48-bit addresses (int64)."""
    return (np.asarray(hi, dtype=np.int64) << 32) | np.asarray(lo, dtype=np.int64)


def fits_batch(slots: SlotBatch) -> bool:
    """Whether the old UAVLOC_RSSI_BATCH carries ``slots`` without losing a column."""
    return bool(np.array_equal(slots.address, slots.emitter_id)
                and np.all((slots.emitter_id >= 0) & (slots.emitter_id <= _UINT32_MAX))
                and not np.any(slots.fingerprint) and not np.any(slots.channel) and not np.any(slots.radio))


def encode_rssi_batches(
    slots: SlotBatch,
    frame: LocalFrame,
    *,
    epoch_unix_s: float = 0.0,
    slot_s: float = 0.025,
    window_s: float = DEFAULT_WINDOW_S,
    message: str = AUTO,
) -> list:
    """Pack the slots of ONE vehicle into RSSI messages (``message``: BATCH2, BATCH or AUTO), in
    time order.

    ``frame`` is the scenario's local frame (``xyz_m`` east/north/up about the launch point);
    ``window_s`` (<= 0.255 s) bounds how far an entry may lie after its message's reference slot.
    Raises ValueError when the slots span several vehicles or a value does not fit the wire type.
    """
    if message not in MESSAGES:
        raise ValueError(f"encode_rssi_batches: message must be one of {', '.join(MESSAGES)}, got {message!r}")
    if len(slots) == 0:
        return []
    if len(np.unique(slots.vehicle)) > 1:
        raise ValueError("encode_rssi_batches: slots of several vehicles; encode each vehicle separately")
    if not 0.0 < window_s <= MAX_SPAN_MS / 1000.0:
        raise ValueError(f"encode_rssi_batches: window_s must be in (0, {MAX_SPAN_MS / 1000}] s, got {window_s}")
    if message == AUTO:
        message = BATCH if fits_batch(slots) else BATCH2
    _check_wire_ranges(slots, message)
    s = slots.sorted_by_time()
    t_ms = np.round((s.t_s - s.t_s[0]) * 1000.0).astype(np.int64)  # ms after the first slot
    window_ms = int(round(window_s * 1000.0))
    out = []
    start = 0
    n = len(s)
    while start < n:
        stop = start + 1
        while stop < n and stop - start < MAX_ENTRIES and t_ms[stop] - t_ms[start] <= window_ms:
            stop += 1
        out.append(_encode_one(s, start, stop, t_ms, frame, epoch_unix_s, slot_s, message))
        start = stop
    return out


def _check_wire_ranges(s: SlotBatch, message: str) -> None:
    if message == BATCH:
        if np.any(s.emitter_id < 0) or np.any(s.emitter_id > _UINT32_MAX):
            raise ValueError("UAVLOC_RSSI_BATCH: emitter_id must fit uint32 (0 .. 4294967295)")
    else:
        if np.any(s.address < 0) or np.any(s.address > _ADDRESS_MAX):
            raise ValueError("UAVLOC_RSSI_BATCH2: address must fit 48 bits (0 .. 0xffffffffffff)")
        if np.any(s.channel < 0) or np.any(s.channel > 255):
            raise ValueError("UAVLOC_RSSI_BATCH2: channel must be 0 .. 255")
        if np.any(s.radio < 0) or np.any(s.radio > 255):
            raise ValueError("UAVLOC_RSSI_BATCH2: radio must be 0 .. 255")
    if np.any(s.n_samples < 1) or np.any(s.n_samples > 255):
        raise ValueError(f"{message}: n_samples must be 1 .. 255")
    if not np.all(np.isfinite(s.rssi_dbm)) or np.any(np.abs(s.rssi_dbm) > 327.0):
        raise ValueError(f"{message}: rssi_dbm must be finite and within +-327 dBm")
    if not np.all(np.isfinite(s.xyz_m)) or not np.all(np.isfinite(s.t_s)):
        raise ValueError(f"{message}: times and positions must be finite")


def _encode_one(s: SlotBatch, start: int, stop: int, t_ms: np.ndarray, frame: LocalFrame,
                epoch_unix_s: float, slot_s: float, message: str):
    dt_ms = t_ms[start:stop] - t_ms[start]
    xyz = s.xyz_m[start:stop]
    vel = _slope(dt_ms / 1000.0, xyz)
    ref = xyz[0]
    lat, lon = frame.to_wgs84(ref[0], ref[1])
    k = stop - start
    pad = [0] * (MAX_ENTRIES - k)
    head = dict(
        time_usec=int(round((epoch_unix_s + float(s.t_s[start])) * 1e6)),
        lat=int(round(float(lat) * 1e7)),
        lon=int(round(float(lon) * 1e7)),
        relative_alt=int(round(float(ref[2]) * 1000.0)),
        vx=_clip_i16(vel[1] * 100.0),  # north
        vy=_clip_i16(vel[0] * 100.0),  # east
        vz=_clip_i16(-vel[2] * 100.0),  # down
        slot_us=int(min(65535, round(slot_s * 1e6))),
        count=k,
        dt_ms=[int(v) for v in dt_ms] + pad,
    )
    rssi_cdbm = [int(round(float(v) * 100.0)) for v in s.rssi_dbm[start:stop]] + pad
    counts = [int(v) for v in s.n_samples[start:stop]] + pad
    if message == BATCH:
        return mavlink.MAVLink_uavloc_rssi_batch_message(
            **head, emitter_id=[int(v) for v in s.emitter_id[start:stop]] + pad, rssi_cdbm=rssi_cdbm,
            n_samples=counts)
    hi, lo = split_address(s.address[start:stop])
    return mavlink.MAVLink_uavloc_rssi_batch2_message(
        **head,
        addr_lo=[int(v) for v in lo] + pad,
        addr_hi=[int(v) for v in hi] + pad,
        fingerprint=[int(v) for v in wire_fingerprint(s.fingerprint[start:stop])] + pad,
        channel=[int(v) for v in s.channel[start:stop]] + pad,
        radio=[int(v) for v in s.radio[start:stop]] + pad,
        n_frames=counts,
        rssi_cdbm=rssi_cdbm,
    )


def _slope(t_s: np.ndarray, xyz: np.ndarray) -> np.ndarray:
    """Least-squares velocity (3,) of positions over time; zero when all entries share one time."""
    dt = t_s - t_s.mean()
    den = float(np.sum(dt * dt))
    if den <= 0.0:
        return np.zeros(3)
    return (dt[:, None] * (xyz - xyz.mean(axis=0))).sum(axis=0) / den


def _clip_i16(v: float) -> int:
    return int(max(-32768, min(32767, round(float(v)))))


def keepalive_message(until_s: float, *, epoch_unix_s: float = 0.0, slot_s: float = 0.025, message: str = BATCH2):
    """A count-0 message: everything heard before mission time ``until_s`` has been sent. No
    position (zeros): it carries no entry to place."""
    msg = mavlink.MAVLink_uavloc_rssi_batch_message if message == BATCH else mavlink.MAVLink_uavloc_rssi_batch2_message
    zeros = [0] * MAX_ENTRIES
    head = dict(time_usec=int(round((epoch_unix_s + float(until_s)) * 1e6)), lat=0, lon=0, relative_alt=0,
                vx=0, vy=0, vz=0, slot_us=int(min(65535, round(slot_s * 1e6))), count=0, dt_ms=zeros,
                rssi_cdbm=zeros)
    if message == BATCH:
        return msg(**head, emitter_id=zeros, n_samples=zeros)
    return msg(**head, addr_lo=zeros, addr_hi=zeros, fingerprint=zeros, channel=zeros, radio=zeros, n_frames=zeros)


def message_time_s(msg, *, epoch_unix_s: float = 0.0) -> float:
    """Mission time up to which an RSSI message says its receiver's reports are complete: its
    ``time_usec`` (a keepalive's "until", a batch's first entry: entries are sent in time order)."""
    return (int(msg.time_usec) - int(round(epoch_unix_s * 1e6))) / 1e6


def decode_rssi_batch(
    msg, frame: LocalFrame, *, vehicle: int | None = None, epoch_unix_s: float = 0.0
) -> SlotBatch:
    """Decode one UAVLOC_RSSI_BATCH2 or UAVLOC_RSSI_BATCH into a SlotBatch (``vehicle`` defaults to
    the sender's system id).

    UAVLOC_RSSI_BATCH2: ``emitter_id`` = ``address``, ``radio`` as sent (0, Wi-Fi, when the sender
    predates the field). UAVLOC_RSSI_BATCH: ``address`` = ``emitter_id``, fingerprint and channel 0
    (unknown), radio 0 (Wi-Fi). Entries beyond ``count`` are ignored; a
    ``count`` above 12 is clipped to 12. Raises ValueError for any other message.
    """
    kind = msg.get_type()
    if kind not in RSSI_MESSAGE_TYPES:
        raise ValueError(f"decode_rssi_batch: {kind} is not an RSSI message ({', '.join(RSSI_MESSAGE_TYPES)})")
    k = min(int(msg.count), MAX_ENTRIES)
    if k == 0:
        return SlotBatch.empty()
    if vehicle is None:
        vehicle = msg.get_srcSystem()
    dt_s = np.asarray(msg.dt_ms[:k], dtype=float) / 1000.0
    e0, n0 = frame.to_local(msg.lat / 1e7, msg.lon / 1e7)
    ref = np.array([float(e0), float(n0), msg.relative_alt / 1000.0])
    vel = np.array([msg.vy, msg.vx, -msg.vz], dtype=float) / 100.0  # ENU from NED
    xyz = ref[None, :] + dt_s[:, None] * vel[None, :]
    epoch_us = int(round(epoch_unix_s * 1e6))
    t0_s = (int(msg.time_usec) - epoch_us) / 1e6
    rssi = np.asarray(msg.rssi_cdbm[:k], dtype=float) / 100.0
    if kind == BATCH:
        return SlotBatch.from_columns(t0_s + dt_s, np.full(k, int(vehicle)), xyz,
                                      np.asarray(msg.emitter_id[:k], dtype=np.int64), rssi,
                                      np.asarray(msg.n_samples[:k], dtype=int))
    address = join_address(msg.addr_hi[:k], msg.addr_lo[:k])
    return SlotBatch.from_columns(t0_s + dt_s, np.full(k, int(vehicle)), xyz, address, rssi,
                                  np.asarray(msg.n_frames[:k], dtype=int), address=address,
                                  fingerprint=np.asarray(msg.fingerprint[:k], dtype=np.int64),
                                  channel=np.asarray(msg.channel[:k], dtype=int),
                                  radio=np.asarray(getattr(msg, "radio", [0] * k)[:k], dtype=int))


def decode_rssi_batches(msgs: Iterable, frame: LocalFrame, *, epoch_unix_s: float = 0.0) -> SlotBatch:
    """Decode many messages of either version (each attributed to its sender's system id) into one
    SlotBatch."""
    return SlotBatch.concat([decode_rssi_batch(m, frame, epoch_unix_s=epoch_unix_s) for m in msgs])


@dataclass
class RssiBatcher:
    """Streaming encoder for a vehicle or companion: add slots as they are heard, get messages.

    A message is emitted when it holds 12 entries or when the next slot is more than
    ``window_s`` after its first entry; :meth:`flush` (call it on a timer, e.g. every 50 ms of
    mission time) also emits a pending message once ``window_s`` has passed, and a keepalive when
    nothing was sent for ``keepalive_s``. ``message`` as in
    :func:`encode_rssi_batches` (a companion sends BATCH2).
    """

    frame: LocalFrame
    epoch_unix_s: float = 0.0
    slot_s: float = 0.025
    window_s: float = DEFAULT_WINDOW_S
    message: str = AUTO
    keepalive_s: float | None = KEEPALIVE_S  # None: no keepalives (a receiver that predates them)
    _pending: list = field(default_factory=list)
    _last_sent_s: float = -float("inf")

    def __post_init__(self) -> None:
        if self.message not in MESSAGES:
            raise ValueError(f"RssiBatcher: message must be one of {', '.join(MESSAGES)}, got {self.message!r}")

    def add(self, slots: SlotBatch) -> list:
        """Queue the slots (time-ordered, one vehicle); return the messages that are complete."""
        if len(slots):
            self._pending.append(slots)
        return self.flush(now_s=None)

    def flush(self, now_s: float | None = None, *, force: bool = False, complete_until_s: float | None = None) -> list:
        """Messages that are complete at mission time ``now_s`` (all pending ones if ``force``),
        and a keepalive (:func:`keepalive_message`) when ``keepalive_s`` has passed since the last
        message: every slot before ``complete_until_s`` (default ``now_s``) must have been added."""
        msgs = self._complete(now_s, force)
        if msgs:
            sent = now_s if now_s is not None else message_time_s(msgs[-1], epoch_unix_s=self.epoch_unix_s)
            self._last_sent_s = max(self._last_sent_s, sent)
        if now_s is None or self.keepalive_s is None or msgs:
            return msgs
        if now_s - self._last_sent_s >= self.keepalive_s:
            until = now_s if complete_until_s is None else min(now_s, complete_until_s)
            if self._pending:
                until = min(until, min(float(b.t_s.min()) for b in self._pending))
            msgs = [keepalive_message(until, epoch_unix_s=self.epoch_unix_s, slot_s=self.slot_s,
                                      message=BATCH if self.message in (BATCH, AUTO) else BATCH2)]
            self._last_sent_s = now_s
        return msgs

    def _complete(self, now_s: float | None, force: bool) -> list:
        if not self._pending:
            return []
        if not force:  # cheap test first: nothing can be complete yet
            n = sum(len(b) for b in self._pending)
            t_first = min(float(b.t_s.min()) for b in self._pending)
            t_last = max(float(b.t_s.max()) for b in self._pending)
            if (n < MAX_ENTRIES and t_last - t_first <= self.window_s
                    and (now_s is None or now_s - t_first <= self.window_s)):
                return []
        pending = SlotBatch.concat(self._pending)
        msgs = encode_rssi_batches(pending, self.frame, epoch_unix_s=self.epoch_unix_s,
                                   slot_s=self.slot_s, window_s=self.window_s, message=self.message)
        if force:
            self._pending = []
            return msgs
        # Keep the last message back unless it is full or its window has closed.
        last = msgs[-1]
        first_t = (last.time_usec / 1e6) - self.epoch_unix_s
        closed = last.count >= MAX_ENTRIES or (now_s is not None and now_s - first_t > self.window_s)
        if closed:
            self._pending = []
            return msgs
        kept = sum(m.count for m in msgs[:-1])
        rest = pending.sorted_by_time().take(np.arange(kept, len(pending)))
        self._pending = [rest]
        return msgs[:-1]


def entries_per_message(msgs: Sequence) -> float:
    """Mean number of entries per message (a bandwidth figure of merit)."""
    return float(np.mean([m.count for m in msgs])) if msgs else 0.0
