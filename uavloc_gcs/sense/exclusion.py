"""The team's own devices: addresses, OUIs and fingerprints the sensor must not report.

File format (text, one entry a line, ``#`` starts a comment)::

    mac aa:bb:cc:dd:ee:ff     # one address
    oui aa:bb:cc              # every address whose first three octets are these (a vendor's block)
    fp  0x1a2b3c4d            # a content fingerprint (every frame of that phone model/OS: use with care)

A bare six-octet address or three-octet OUI is accepted without its keyword. ``uavloc sense
--learn-team`` writes such a file from what is heard on the ground before take-off (the team's
phones, tablets, the drone's own Wi-Fi): addresses heard at least ``min_frames`` times, and the
fingerprints of the non-randomized ones only when asked (a fingerprint excludes every phone of the
same model, which may include the people being searched for).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import FileFormatError
from .aggregate import format_mac
from .frames import RADIO_BLE, Frames


@dataclass
class Exclusion:
    addresses: set[int] = field(default_factory=set)
    ouis: set[int] = field(default_factory=set)  # 24-bit
    fingerprints: set[int] = field(default_factory=set)

    def __len__(self) -> int:
        return len(self.addresses) + len(self.ouis) + len(self.fingerprints)

    def mask(self, frames: Frames) -> np.ndarray:
        """(N,) bool: True where the frame is the team's."""
        a = frames.address
        out = np.isin(a, np.fromiter(self.addresses, dtype=np.int64, count=len(self.addresses)))
        # an OUI names a vendor only in a public address: not in a BLE random one (TxAdd set)
        vendor = np.isin(a >> 24, np.fromiter(self.ouis, dtype=np.int64, count=len(self.ouis)))
        out |= vendor & ~((frames.radio == RADIO_BLE) & (frames.random == 1))
        fp = np.isin(frames.fingerprint, np.fromiter(self.fingerprints, dtype=np.int64, count=len(self.fingerprints)))
        out |= fp & (frames.fingerprint != 0)  # 0: no fingerprint (BLE without a Find My key)
        return out


def _octets(text: str, n: int) -> int | None:
    parts = text.replace("-", ":").split(":")
    if len(parts) != n or any(len(p) != 2 for p in parts):
        return None
    try:
        return int("".join(parts), 16)
    except ValueError:
        return None


def loads_exclusion(text: str, *, path: str = "<string>") -> Exclusion:
    ex = Exclusion()
    for lineno, raw in enumerate(text.splitlines(), start=1):
        words = raw.split("#", 1)[0].split()
        if not words:
            continue
        kind, value = (words[0].lower(), words[1]) if len(words) == 2 else ("", words[0])
        if len(words) > 2 or kind not in ("", "mac", "oui", "fp"):
            raise FileFormatError(f"expected 'mac ADDRESS', 'oui AA:BB:CC' or 'fp FINGERPRINT', got {raw.strip()!r}",
                                  path=path, line=lineno)
        if kind == "fp":
            try:
                fp = int(value, 16) if value.lower().startswith("0x") else int(value)
            except ValueError:
                fp = -1
            if not 0 < fp < 2**32:
                raise FileFormatError(f"fingerprint must be a 32-bit number, got {value!r}", path=path, line=lineno)
            ex.fingerprints.add(fp)
            continue
        mac, oui = _octets(value, 6), _octets(value, 3)
        if mac is not None and kind in ("", "mac"):
            ex.addresses.add(mac)
        elif oui is not None and kind in ("", "oui"):
            ex.ouis.add(oui)
        else:
            raise FileFormatError(f"expected an address (aa:bb:cc:dd:ee:ff) or an OUI (aa:bb:cc), got {value!r}",
                                  path=path, line=lineno)
    return ex


def read_exclusion(path: str | Path) -> Exclusion:
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise FileFormatError(f"cannot read the exclusion list ({err.__class__.__name__})", path=str(p)) from None
    return loads_exclusion(text, path=str(p))


def learn_team(frames: Frames, *, min_frames: int = 3, fingerprints: bool = False) -> str:
    """An exclusion file (text) of what ``frames`` (heard on the ground before take-off) hold."""
    lines = ["# uavloc sense --learn-team: the team's own devices, heard before take-off"]
    addrs, counts = np.unique(frames.address, return_counts=True)
    for a, c in zip(addrs.tolist(), counts.tolist()):
        if c >= min_frames:
            lines.append(f"mac {format_mac(a)}  # {c} frames")
    if fingerprints:
        # a burned-in address: Wi-Fi with bit 1 of the first octet clear, BLE public (TxAdd clear)
        ble = frames.radio == RADIO_BLE
        fixed = np.where(ble, frames.random == 0, (frames.address >> 41) & 1 == 0) & (frames.fingerprint != 0)
        for fp in np.unique(frames.fingerprint[fixed]).tolist():
            lines.append(f"fp 0x{fp:08x}")
    return "\n".join(lines) + "\n"
