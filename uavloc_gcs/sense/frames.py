"""From capture records to the probe requests a sensor uses: one row per frame, in columns.

:func:`parse_records` walks records from :mod:`.capture` (or a live interface), reads the radio
header (radiotap or PPI) and the 802.11 probe request behind it, and keeps time, source address,
sequence number, signal, channel and content fingerprint. Anything it cannot use is counted in
:class:`SkipCounts` by reason, never raised: a fuzzed capture gives counts, not a traceback.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Iterable

import numpy as np

from .capture import LINKTYPE_IEEE802_11, LINKTYPE_PPI, LINKTYPE_RADIOTAP, ReadStats, Record
from .dot11 import probe_fields
from .radiotap import FLAG_BAD_FCS, FLAG_FCS, Malformed, freq_to_channel, parse_ppi, parse_radiotap

MIN_RSSI_DBM = -120
MAX_RSSI_DBM = 10


@dataclass
class SkipCounts:
    """Frames not used, by reason (``not_probe`` frames are fine, just not what a sensor reads)."""

    reasons: Counter = field(default_factory=Counter)
    read: ReadStats = field(default_factory=ReadStats)

    @property
    def malformed(self) -> int:
        """Records that were broken (bad lengths, bad FCS, unknown link type), not merely unused."""
        benign = {"not_probe", "no_signal", "excluded"}
        return self.read.bad_records + sum(v for k, v in self.reasons.items() if k not in benign)

    def summary(self) -> str:
        parts = [f"{k} {v}" for k, v in sorted(self.reasons.items())]
        if self.read.bad_records:
            parts.append(f"unreadable records {self.read.bad_records}")
        if self.read.trailing_bytes:
            parts.append(f"{self.read.trailing_bytes} trailing bytes")
        return ", ".join(parts) if parts else "none"


@dataclass(frozen=True)
class Frames:
    """N probe requests, column-wise, in capture order."""

    t_s: np.ndarray  # (N,) UNIX time [s]
    address: np.ndarray  # (N,) int64, 48-bit source address
    seq: np.ndarray  # (N,) int, 12-bit sequence number
    rssi_dbm: np.ndarray  # (N,) int, first antenna signal [dBm]
    channel: np.ndarray  # (N,) int, 0 unknown
    fingerprint: np.ndarray  # (N,) int64, 32-bit content hash (never 0)
    antennas_dbm: tuple  # (N,) tuple of per-antenna signals

    def __len__(self) -> int:
        return len(self.t_s)

    def take(self, idx) -> "Frames":
        idx = np.asarray(idx)
        return Frames(self.t_s[idx], self.address[idx], self.seq[idx], self.rssi_dbm[idx], self.channel[idx],
                      self.fingerprint[idx], tuple(self.antennas_dbm[i] for i in idx.tolist()) if idx.dtype != bool
                      else tuple(a for a, k in zip(self.antennas_dbm, idx) if k))

    @staticmethod
    def concat(parts: list["Frames"]) -> "Frames":
        if not parts:
            return _frames([], [], [], [], [], [], [])
        return Frames(*(np.concatenate([getattr(p, f) for p in parts]) for f in
                        ("t_s", "address", "seq", "rssi_dbm", "channel", "fingerprint")),
                      sum((p.antennas_dbm for p in parts), ()))


def _frames(t, a, s, r, c, f, ant) -> Frames:
    return Frames(np.asarray(t, dtype=float), np.asarray(a, dtype=np.int64), np.asarray(s, dtype=int),
                  np.asarray(r, dtype=int), np.asarray(c, dtype=int), np.asarray(f, dtype=np.int64), tuple(ant))


def parse_records(records: Iterable[Record], skips: SkipCounts) -> Frames:
    """The probe requests among ``records`` that carry a signal level; the rest is counted."""
    t_l, a_l, s_l, r_l, c_l, f_l, ant_l = [], [], [], [], [], [], []
    reasons = skips.reasons
    for linktype, t, data, snapped in records:
        try:
            if linktype == LINKTYPE_RADIOTAP:
                radio = parse_radiotap(data)
            elif linktype == LINKTYPE_PPI:
                radio = parse_ppi(data)
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
    return _frames(t_l, a_l, s_l, r_l, c_l, f_l, ant_l)
