"""RSSI slots as CSV: one row per slot, the offline input of ``uavloc localize``.

Header (these columns, in this order, then optionally any of ``address,fingerprint,channel,radio``)::

    t_s,vehicle_id,lat_deg,lon_deg,alt_m,emitter_id,rssi_dbm,n_samples[,address,fingerprint,channel,radio]

``t_s`` seconds on one clock for all vehicles, ``alt_m`` the vehicle's height above the launch
point, ``rssi_dbm`` the mean of the slot's ``n_samples`` RSSI samples (frames). What a Wi-Fi
sensor adds: ``address`` the 802.11 source address, as 12 hex digits (``da0a1b2c3d4e``) or six
octets (``da:0a:1b:2c:3d:4e``, ``-`` also accepted); ``fingerprint`` the content hash, a whole
number (decimal or ``0x`` hex); ``channel`` the 802.11 channel (or BLE channel index); ``radio``
``wifi`` or ``ble`` (or 0 / 1). An absent column or an empty cell reads as the default: address =
emitter_id, fingerprint 0, channel 0 (unknown) and radio wifi (files from before the column). The
writer adds the first three columns only when some slot has a value other than the default, and
``radio`` only when some slot is not Wi-Fi. Blank lines and lines
starting with ``#`` are ignored. :func:`loads_slots_csv` / :func:`dumps_slots_csv` convert
between the text and a :class:`SlotBatch` in a scenario's local frame; malformed input raises
:class:`FileFormatError` naming the line and the field.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import FileFormatError
from ..geo import LocalFrame
from ..observations import SlotBatch

COLUMNS = ("t_s", "vehicle_id", "lat_deg", "lon_deg", "alt_m", "emitter_id", "rssi_dbm", "n_samples")
OPTIONAL_COLUMNS = ("address", "fingerprint", "channel", "radio")
RADIOS = ("wifi", "ble")  # by radio code, as uavloc_gcs.sense.frames.RADIO_NAMES
_INT = {"vehicle_id", "emitter_id", "n_samples", "fingerprint", "channel", "radio"}
_RANGE = {"lat_deg": (-90.0, 90.0), "lon_deg": (-180.0, 180.0), "vehicle_id": (0, 2**31 - 1),
          "emitter_id": (0, 2**63 - 1), "n_samples": (1, 2**31 - 1), "address": (0, 2**48 - 1),
          "fingerprint": (0, 2**63 - 1), "channel": (0, 255), "radio": (0, 255)}
_HEX = set("0123456789abcdefABCDEF")


def loads_slots_csv(text: str, frame: LocalFrame, *, path: str = "<string>") -> SlotBatch:
    """Parse slot CSV text; positions are converted to ``frame`` (east, north, up) metres."""
    rows: list[list] = []
    header: tuple[str, ...] | None = None
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        fields = [f.strip() for f in line.split(",")]
        if header is None:
            header = _header(fields, line, path, lineno)
            continue
        if len(fields) != len(header):
            raise FileFormatError(f"expected {len(header)} comma-separated fields, got {len(fields)}",
                                  path=path, line=lineno)
        values = dict(zip(header, fields))
        row = [_value(values[name], name, path, lineno) for name in COLUMNS]
        row += [_value(values[name], name, path, lineno) if values.get(name, "") != "" else None
                for name in OPTIONAL_COLUMNS]
        rows.append(row)
    if header is None:
        raise FileFormatError(f"empty file: expected the header '{','.join(COLUMNS)}'", path=path, line=1)
    if not rows:
        return SlotBatch.empty()
    a = np.array(rows, dtype=object)
    lat, lon = a[:, 2].astype(float), a[:, 3].astype(float)
    e, n = frame.to_local(lat, lon)
    xyz = np.column_stack([e, n, a[:, 4].astype(float)])
    emitter_id = a[:, 5].astype(np.int64)
    address = np.array([eid if v is None else v for eid, v in zip(emitter_id, a[:, 8])], dtype=np.int64)
    fingerprint = np.array([0 if v is None else v for v in a[:, 9]], dtype=np.int64)
    channel = np.array([0 if v is None else v for v in a[:, 10]], dtype=int)
    radio = np.array([0 if v is None else v for v in a[:, 11]], dtype=int)
    return SlotBatch.from_columns(a[:, 0].astype(float), a[:, 1].astype(np.int64), xyz, emitter_id,
                                  a[:, 6].astype(float), a[:, 7].astype(np.int64), address=address,
                                  fingerprint=fingerprint, channel=channel, radio=radio)


def _header(fields: list[str], line: str, path: str, lineno: int) -> tuple[str, ...]:
    """The header's columns: COLUMNS in order, then optional columns once each, in any order."""
    extra = fields[len(COLUMNS):]
    if (tuple(fields[:len(COLUMNS)]) != COLUMNS or any(f not in OPTIONAL_COLUMNS for f in extra)
            or len(set(extra)) != len(extra)):
        raise FileFormatError(f"header must be '{','.join(COLUMNS)}' optionally followed by any of "
                              f"'{','.join(OPTIONAL_COLUMNS)}', got '{line}'", path=path, line=lineno)
    return tuple(fields)


def parse_address(text: str) -> int:
    """An 802.11 address as an integer: 12 hex digits or six octets separated by ':' or '-'
    (``da:0a:1b:2c:3d:4e`` -> 0xda0a1b2c3d4e). Raises ValueError otherwise."""
    octets = text.replace("-", ":").split(":")
    if len(octets) == 6 and all(len(o) == 2 for o in octets):
        digits = "".join(octets)
    elif len(octets) == 1:
        digits = text
    else:
        raise ValueError(text)
    if len(digits) != 12 or not set(digits) <= _HEX:
        raise ValueError(text)
    return int(digits, 16)


def format_address(address: int) -> str:
    """``0xda0a1b2c3d4e`` -> ``da:0a:1b:2c:3d:4e``. Raises ValueError beyond 48 bits."""
    if not 0 <= int(address) < 2**48:
        raise ValueError(f"address {address} does not fit 48 bits")
    digits = f"{int(address):012x}"
    return ":".join(digits[i:i + 2] for i in range(0, 12, 2))


def _value(text: str, name: str, path: str, lineno: int):
    try:
        if name == "address":
            v = parse_address(text)
        elif name == "radio" and text.lower() in RADIOS:
            v = RADIOS.index(text.lower())
        elif name == "fingerprint" and text.lower().startswith("0x"):
            v = int(text, 16)
        else:
            v = int(text) if name in _INT else float(text)
    except ValueError:
        kind = ("12 hex digits or six hex octets (aa:bb:cc:dd:ee:ff)" if name == "address"
                else f"{' or '.join(RADIOS)} (or its number)" if name == "radio"
                else "a whole number" if name in _INT else "a number")
        raise FileFormatError(f"must be {kind}, got {text!r}", path=path, line=lineno, field=name) from None
    if isinstance(v, float) and not math.isfinite(v):
        raise FileFormatError(f"must be finite, got {text!r}", path=path, line=lineno, field=name)
    if name in _RANGE:
        lo, hi = _RANGE[name]
        if not lo <= v <= hi:
            raise FileFormatError(f"{v} is outside {lo}..{hi}", path=path, line=lineno, field=name)
    return v


def dumps_slots_csv(slots: SlotBatch, frame: LocalFrame) -> str:
    """Slot CSV text (time order, deterministic; lat/lon to 1e-8 degrees, about 1 mm). The columns
    address (aa:bb:cc:dd:ee:ff), fingerprint and channel are written when some slot has a value
    other than the default (address = emitter_id, fingerprint 0, channel 0), radio when some slot
    is not Wi-Fi."""
    s = slots.sorted_by_time()
    latlon = frame.to_wgs84_latlon(s.xyz_m[:, :2]) if len(s) else np.zeros((0, 2))
    radio = bool(np.any(s.radio))
    sensor = bool(np.any(s.address != s.emitter_id) or np.any(s.fingerprint) or np.any(s.channel)) or radio
    lines = [",".join(COLUMNS + (OPTIONAL_COLUMNS[:3] if sensor else ()) + (("radio",) if radio else ()))]
    for k in range(len(s)):
        line = (f"{s.t_s[k]:.3f},{s.vehicle[k]},{latlon[k, 0]:.8f},{latlon[k, 1]:.8f},{s.xyz_m[k, 2]:.2f},"
                f"{s.emitter_id[k]},{s.rssi_dbm[k]:.2f},{s.n_samples[k]}")
        if sensor:  # an address beyond 48 bits can only be a defaulted emitter id: left empty
            a = s.address[k]
            cell = "" if a == s.emitter_id[k] and not 0 <= a < 2**48 else format_address(a)
            line += f",{cell},{s.fingerprint[k]},{s.channel[k]}"
        if radio:
            line += f",{RADIOS[s.radio[k]] if 0 <= s.radio[k] < len(RADIOS) else s.radio[k]}"
        lines.append(line)
    return "\n".join(lines) + "\n"


def read_slots_csv(path: str | Path, frame: LocalFrame) -> SlotBatch:
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8-sig")  # a spreadsheet's "CSV UTF-8" starts with a byte-order mark
    except (OSError, UnicodeDecodeError) as exc:
        raise FileFormatError(f"cannot read the file ({exc})", path=str(p)) from None
    return loads_slots_csv(text, frame, path=str(p))
