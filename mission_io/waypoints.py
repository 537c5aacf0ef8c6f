"""QGC WPL 110 ``.waypoints`` files (Mission Planner, QGroundControl, MAVProxy).

Format (MAVLink devguide ``file_formats``): first line ``QGC WPL 110``, then one item per line,
12 tab-separated columns::

    INDEX  CURRENT  FRAME  COMMAND  PARAM1  PARAM2  PARAM3  PARAM4  LAT/X  LON/Y  ALT/Z  AUTOCONTINUE

Line 0 is the planned home (written like Mission Planner: ``0 1 0 16 0 0 0 0 lat lon alt 1``),
items follow from index 1. Numbers are written with full precision (shortest exact decimal, no
exponent; ``nan`` for NaN, e.g. "keep yaw"), not ``%f``. The format has no field for the
autopilot, the speeds or geofences, and cannot say "home altitude unknown": a NaN home altitude
is written as 0 and an all-zero home reads back as "no home" (NaN), the placeholder ArduPilot
and MAVProxy use.

Errors name the file, the line (1-based, as an editor shows it) and the column.
"""

from __future__ import annotations

import math
from pathlib import Path

from uavloc_gcs.errors import FileFormatError
from uavloc_gcs.mission import FRAME_GLOBAL, GLOBAL_FRAMES, NAV_WAYPOINT, Autopilot, MissionItem, MissionPlan

from ._common import fmt_float, read_text, write_text

__all__ = ["loads", "dumps", "read", "write", "HEADER"]

HEADER = "QGC WPL 110"
COLUMNS = ("index", "current", "frame", "command", "param1", "param2", "param3", "param4",
           "latitude/x", "longitude/y", "altitude/z", "autocontinue")


def dumps(plan: MissionPlan) -> str:
    """The WPL 110 text of ``plan`` (deterministic, ``\\n`` line ends, trailing newline)."""
    def num(v: float) -> str:
        return fmt_float(v)

    home = [plan.home_lat_deg, plan.home_lon_deg, plan.home_alt_m]
    if math.isnan(home[0]) or math.isnan(home[1]):
        home = [0.0, 0.0, 0.0]
    elif math.isnan(home[2]):
        home[2] = 0.0
    lines = [HEADER, "\t".join(["0", "1", str(FRAME_GLOBAL), str(NAV_WAYPOINT), "0", "0", "0", "0",
                                *map(num, home), "1"])]
    for seq, it in enumerate(plan.items, start=1):
        cols = [str(seq), "0", str(int(it.frame)), str(int(it.command)), *map(num, it.params),
                num(it.lat_deg), num(it.lon_deg), num(it.alt_m), "1" if it.autocontinue else "0"]
        lines.append("\t".join(cols))
    return "\n".join(lines) + "\n"


def write(path: str | Path, plan: MissionPlan) -> Path:
    """Write ``plan`` to ``path`` atomically."""
    return write_text(path, dumps(plan))


def read(path: str | Path, *, autopilot: Autopilot = "ardupilot") -> MissionPlan:
    """Read a ``.waypoints`` file. ``autopilot`` is not in the format; ArduPilot by default."""
    return loads(read_text(path), path=str(path), autopilot=autopilot)


def loads(text: str, *, path: str = "<string>", autopilot: Autopilot = "ardupilot") -> MissionPlan:
    """Parse WPL 110 text. Raises FileFormatError naming file, line and column."""
    lines = text.splitlines()
    if not lines or lines[0].strip() != HEADER:
        got = lines[0].strip()[:40] if lines else "an empty file"
        raise FileFormatError(f"first line must be '{HEADER}', got {got!r}", path=path, line=1, field="header")
    rows = []
    for lineno, line in enumerate(lines[1:], start=2):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        cols = line.split("\t") if "\t" in line else line.split()
        cols = [c.strip() for c in cols]
        if len(cols) != 12:
            raise FileFormatError(f"expected 12 tab-separated columns, got {len(cols)}", path=path, line=lineno)
        rows.append((lineno, _parse_row(cols, path, lineno)))
    if not rows:
        raise FileFormatError("no home line (line 0 of the mission) after the header", path=path, line=2)
    for expected, (lineno, row) in enumerate(rows):
        if row[0] != expected:
            raise FileFormatError(f"index is {row[0]}, expected {expected} (indices count up from 0)", path=path,
                                  line=lineno, field="index")
    _, home = rows[0]
    hlat, hlon, halt = home[8], home[9], home[10]
    if hlat == 0.0 and hlon == 0.0:
        hlat = hlon = halt = math.nan
    items = []
    for lineno, r in rows[1:]:
        if r[2] in GLOBAL_FRAMES:
            if not (-90.0 <= r[8] <= 90.0):
                raise FileFormatError(f"latitude {r[8]} is outside -90..90 degrees", path=path, line=lineno,
                                      field="latitude/x")
            if not (-180.0 <= r[9] <= 180.0):
                raise FileFormatError(f"longitude {r[9]} is outside -180..180 degrees", path=path, line=lineno,
                                      field="longitude/y")
            if not math.isfinite(r[10]):
                raise FileFormatError(f"altitude {r[10]} is not a finite number", path=path, line=lineno,
                                      field="altitude/z")
        items.append(MissionItem(r[3], r[2], (r[4], r[5], r[6], r[7]), r[8], r[9], r[10], bool(r[11])))
    return MissionPlan(tuple(items), hlat, hlon, halt, autopilot=autopilot)


def _parse_row(cols: list[str], path: str, lineno: int) -> list:
    out: list = []
    for k, (name, text) in enumerate(zip(COLUMNS, cols)):
        if k in (0, 1, 2, 3, 11):
            try:
                v = int(text)
            except ValueError:
                raise FileFormatError(f"must be a whole number, got {text!r}", path=path, line=lineno,
                                      field=name) from None
            if v < 0 or (k in (1, 11) and v > 1):
                raise FileFormatError(f"{v} is out of range", path=path, line=lineno, field=name)
        else:
            try:
                v = float(text)
            except ValueError:
                raise FileFormatError(f"must be a number, got {text!r}", path=path, line=lineno, field=name) from None
            if math.isinf(v):
                raise FileFormatError("must be finite", path=path, line=lineno, field=name)
        out.append(v)
    return out
