"""From capture records to the frames a sensor uses: one row per frame, in columns, with its radio.

:func:`parse_records` walks records from :mod:`.capture` (or a live source). Wi-Fi: it reads the
radio header (radiotap or PPI) and the 802.11 probe request behind it, and keeps time, source
address, sequence number, signal, channel and content fingerprint. Bluetooth LE (the link types of
:mod:`.ble`): the advertisements, with time, advertiser address, signal, channel index, PDU type,
whether the address is random, Apple's Continuity type and the Find My key fingerprint. Anything it
cannot use is counted in :class:`SkipCounts` by reason, never raised: a fuzzed capture gives
counts, not a traceback.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Iterable

import numpy as np

from .ble import BLE_LINKTYPES, adverts
from .capture import LINKTYPE_IEEE802_11, LINKTYPE_PPI, LINKTYPE_RADIOTAP, ReadStats, Record
from .dot11 import probe_fields
from .radiotap import FLAG_BAD_FCS, FLAG_FCS, Malformed, freq_to_channel, parse_ppi, parse_radiotap

MIN_RSSI_DBM = -120
MAX_RSSI_DBM = 10
RADIO_WIFI = 0
RADIO_BLE = 1
RADIO_NAMES = ("wifi", "ble")  # by radio code: frames.csv, slots.csv and the dialect's ``radio``
BENIGN = frozenset({"not_probe", "no_signal", "excluded", "not_advertising", "no_address"})


@dataclass
class SkipCounts:
    """Frames not used, by reason (``not_probe`` frames are fine, just not what a sensor reads)."""

    reasons: Counter = field(default_factory=Counter)
    read: ReadStats = field(default_factory=ReadStats)

    @property
    def malformed(self) -> int:
        """Records that were broken (bad lengths, bad FCS, unknown link type), not merely unused."""
        return self.read.bad_records + sum(v for k, v in self.reasons.items() if k not in BENIGN)

    def summary(self) -> str:
        parts = [f"{k} {v}" for k, v in sorted(self.reasons.items())]
        if self.read.bad_records:
            parts.append(f"unreadable records {self.read.bad_records}")
        if self.read.trailing_bytes:
            parts.append(f"{self.read.trailing_bytes} trailing bytes")
        return ", ".join(parts) if parts else "none"


_COLUMNS = ("t_s", "address", "seq", "rssi_dbm", "channel", "fingerprint", "radio", "random", "pdu", "apple")


@dataclass(frozen=True)
class Frames:
    """N frames, column-wise, in capture order. The BLE columns (``random``, ``pdu``, ``apple``)
    are -1 for Wi-Fi frames; a Frames built without them (Wi-Fi only) gets the defaults."""

    t_s: np.ndarray  # (N,) UNIX time [s]
    address: np.ndarray  # (N,) int64, 48-bit source / advertiser address
    seq: np.ndarray  # (N,) int, 12-bit 802.11 sequence number (0 for BLE)
    rssi_dbm: np.ndarray  # (N,) int, first antenna signal [dBm]
    channel: np.ndarray  # (N,) int, 802.11 channel or BLE channel index, 0 unknown
    fingerprint: np.ndarray  # (N,) int64, 32-bit content hash (never 0 for Wi-Fi; 0 = none for BLE)
    antennas_dbm: tuple  # (N,) tuple of per-antenna signals
    radio: np.ndarray | None = None  # (N,) int8, RADIO_WIFI or RADIO_BLE; None: all Wi-Fi
    random: np.ndarray | None = None  # (N,) int8, BLE TxAdd / address type: 1 random, 0 public; -1 Wi-Fi
    pdu: np.ndarray | None = None  # (N,) int8, BLE link-layer PDU type (ble.PDU_NAMES), -1 none
    apple: np.ndarray | None = None  # (N,) int16, Apple Continuity type (ble_ad.APPLE_TYPES), -1 none

    def __post_init__(self) -> None:
        n = len(self.t_s)
        for name, dtype, fill in (("radio", np.int8, RADIO_WIFI), ("random", np.int8, -1), ("pdu", np.int8, -1),
                                  ("apple", np.int16, -1)):
            if getattr(self, name) is None:
                object.__setattr__(self, name, np.full(n, fill, dtype=dtype))

    def __len__(self) -> int:
        return len(self.t_s)

    def take(self, idx) -> "Frames":
        idx = np.asarray(idx)
        ant = (tuple(self.antennas_dbm[i] for i in idx.tolist()) if idx.dtype != bool
               else tuple(a for a, k in zip(self.antennas_dbm, idx) if k))
        cols = {c: getattr(self, c)[idx] for c in _COLUMNS}
        return Frames(antennas_dbm=ant, **cols)

    @staticmethod
    def concat(parts: list["Frames"]) -> "Frames":
        if not parts:
            return _frames([], [], [], [], [], [], [])
        cols = {c: np.concatenate([getattr(p, c) for p in parts]) for c in _COLUMNS}
        return Frames(antennas_dbm=sum((p.antennas_dbm for p in parts), ()), **cols)


def _frames(t, a, s, r, c, f, ant, radio=None, random=None, pdu=None, apple=None) -> Frames:
    return Frames(np.asarray(t, dtype=float), np.asarray(a, dtype=np.int64), np.asarray(s, dtype=int),
                  np.asarray(r, dtype=int), np.asarray(c, dtype=int), np.asarray(f, dtype=np.int64), tuple(ant),
                  None if radio is None else np.asarray(radio, dtype=np.int8),
                  None if random is None else np.asarray(random, dtype=np.int8),
                  None if pdu is None else np.asarray(pdu, dtype=np.int8),
                  None if apple is None else np.asarray(apple, dtype=np.int16))


def parse_records(records: Iterable[Record], skips: SkipCounts) -> Frames:
    """The probe requests and BLE advertisements among ``records`` that carry a signal level; the
    rest is counted (one reason per record)."""
    t_l, a_l, s_l, r_l, c_l, f_l, ant_l = [], [], [], [], [], [], []
    ble: list[tuple[int, tuple]] = []  # (row, advert): BLE rows and their extra columns
    reasons = skips.reasons
    for linktype, t, data, snapped in records:
        try:
            if linktype == LINKTYPE_RADIOTAP:
                radio = parse_radiotap(data)
            elif linktype == LINKTYPE_PPI:
                radio = parse_ppi(data)
            elif linktype in BLE_LINKTYPES:
                got = adverts(linktype, data, snapped)
                if isinstance(got, str):
                    reasons[got] += 1
                    continue
                kept = 0
                for adv in got:
                    if MIN_RSSI_DBM <= adv[2] <= MAX_RSSI_DBM:
                        ble.append((len(t_l), adv))
                        t_l.append(t)
                        a_l.append(adv[0])
                        s_l.append(0)
                        r_l.append(adv[2])
                        c_l.append(adv[3])
                        f_l.append(adv[6])
                        ant_l.append(())
                        kept += 1
                if not kept:
                    reasons["no_signal"] += 1
                continue
            elif linktype == LINKTYPE_IEEE802_11:
                reasons["no_signal"] += 1  # bare 802.11 carries no signal level
                continue
            else:
                reasons["not_80211"] += 1
                continue
            if radio.flags & FLAG_BAD_FCS:
                reasons["bad_fcs"] += 1
                continue
            end = len(data) - (4 if radio.flags & FLAG_FCS and not snapped else 0)
            got = probe_fields(data[radio.header_len:end], snapped)
        except Malformed as err:
            reasons[err.reason] += 1
            continue
        if got is None:
            reasons["not_probe"] += 1
            continue
        rssi = radio.rssi_dbm
        if rssi is None or not MIN_RSSI_DBM <= rssi <= MAX_RSSI_DBM:
            reasons["no_signal"] += 1
            continue
        address, seq, fp, ds = got
        ch = freq_to_channel(radio.freq_mhz) or radio.xchannel or ds
        t_l.append(t)
        a_l.append(address)
        s_l.append(seq)
        r_l.append(rssi)
        c_l.append(ch)
        f_l.append(fp)
        ant_l.append(radio.antennas_dbm)
    if not ble:
        return _frames(t_l, a_l, s_l, r_l, c_l, f_l, ant_l)
    n = len(t_l)
    radio_c, random_c = np.full(n, RADIO_WIFI, dtype=np.int8), np.full(n, -1, dtype=np.int8)
    pdu_c, apple_c = np.full(n, -1, dtype=np.int8), np.full(n, -1, dtype=np.int16)
    rows = np.fromiter((r for r, _ in ble), dtype=np.int64, count=len(ble))
    radio_c[rows] = RADIO_BLE
    random_c[rows] = [int(a[1]) for _, a in ble]
    pdu_c[rows] = [a[4] for _, a in ble]
    apple_c[rows] = [a[5] for _, a in ble]
    return _frames(t_l, a_l, s_l, r_l, c_l, f_l, ant_l, radio_c, random_c, pdu_c, apple_c)
