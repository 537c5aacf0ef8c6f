"""RSSI slots as CSV: one row per slot, the offline input of ``uavloc localize``.

Header (exactly these columns, in this order)::

    t_s,vehicle_id,lat_deg,lon_deg,alt_m,emitter_id,rssi_dbm,n_samples

``t_s`` seconds on one clock for all vehicles, ``alt_m`` the vehicle's height above the launch
point, ``rssi_dbm`` the mean of the slot's ``n_samples`` RSSI samples. Blank lines and lines
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
_INT = {"vehicle_id", "emitter_id", "n_samples"}
_RANGE = {"lat_deg": (-90.0, 90.0), "lon_deg": (-180.0, 180.0), "vehicle_id": (0, 2**31 - 1),
          "emitter_id": (0, 2**63 - 1), "n_samples": (1, 2**31 - 1)}


def loads_slots_csv(text: str, frame: LocalFrame, *, path: str = "<string>") -> SlotBatch:
    """Parse slot CSV text; positions are converted to ``frame`` (east, north, up) metres."""
    rows: list[list[float]] = []
    header_seen = False
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        fields = [f.strip() for f in line.split(",")]
        if not header_seen:
            if tuple(fields) != COLUMNS:
                raise FileFormatError(f"header must be '{','.join(COLUMNS)}', got '{line}'", path=path, line=lineno)
            header_seen = True
            continue
        if len(fields) != len(COLUMNS):
            raise FileFormatError(f"expected {len(COLUMNS)} comma-separated fields, got {len(fields)}",
                                  path=path, line=lineno)
        rows.append([_value(v, name, path, lineno) for v, name in zip(fields, COLUMNS)])
    if not header_seen:
        raise FileFormatError(f"empty file: expected the header '{','.join(COLUMNS)}'", path=path, line=1)
    if not rows:
        return SlotBatch.empty()
    a = np.array(rows, dtype=object)
    lat, lon = a[:, 2].astype(float), a[:, 3].astype(float)
    e, n = frame.to_local(lat, lon)
    xyz = np.column_stack([e, n, a[:, 4].astype(float)])
    return SlotBatch.from_columns(a[:, 0].astype(float), a[:, 1].astype(np.int64), xyz, a[:, 5].astype(np.int64),
                                  a[:, 6].astype(float), a[:, 7].astype(np.int64))


def _value(text: str, name: str, path: str, lineno: int):
    try:
        v = int(text) if name in _INT else float(text)
    except ValueError:
        kind = "a whole number" if name in _INT else "a number"
        raise FileFormatError(f"must be {kind}, got {text!r}", path=path, line=lineno, field=name) from None
    if isinstance(v, float) and not math.isfinite(v):
        raise FileFormatError(f"must be finite, got {text!r}", path=path, line=lineno, field=name)
    if name in _RANGE:
        lo, hi = _RANGE[name]
        if not lo <= v <= hi:
            raise FileFormatError(f"{v} is outside {lo}..{hi}", path=path, line=lineno, field=name)
    return v


def dumps_slots_csv(slots: SlotBatch, frame: LocalFrame) -> str:
    """Slot CSV text (time order, deterministic; lat/lon to 1e-8 degrees, about 1 mm)."""
    s = slots.sorted_by_time()
    latlon = frame.to_wgs84_latlon(s.xyz_m[:, :2]) if len(s) else np.zeros((0, 2))
    lines = [",".join(COLUMNS)]
    for k in range(len(s)):
        lines.append(f"{s.t_s[k]:.3f},{s.vehicle[k]},{latlon[k, 0]:.8f},{latlon[k, 1]:.8f},{s.xyz_m[k, 2]:.2f},"
                     f"{s.emitter_id[k]},{s.rssi_dbm[k]:.2f},{s.n_samples[k]}")
    return "\n".join(lines) + "\n"


def read_slots_csv(path: str | Path, frame: LocalFrame) -> SlotBatch:
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise FileFormatError(f"cannot read the file ({exc})", path=str(p)) from None
    return loads_slots_csv(text, frame, path=str(p))
