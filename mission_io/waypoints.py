"""QGC WPL 110 ``.waypoints`` files (Mission Planner, QGroundControl, MAVProxy).

Format (MAVLink devguide ``file_formats``): first line ``QGC WPL 110``, then one item per line,
12 tab-separated columns::

    INDEX  CURRENT  FRAME  COMMAND  PARAM1  PARAM2  PARAM3  PARAM4  LAT/X  LON/Y  ALT/Z  AUTOCONTINUE

Line 0 is the planned home (written like Mission Planner: ``0 1 0 16 0 0 0 0 lat lon alt 1``),
items follow from index 1 (reading is more lenient: see :func:`loads`). Numbers are written with full precision (shortest exact decimal, no
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
from uavloc_gcs.mission import (
    DO_JUMP,
    FENCE_COMMANDS,
    FRAME_GLOBAL,
    GLOBAL_FRAMES,
    NAV_WAYPOINT,
    POSITIONAL_COMMANDS,
    RALLY_COMMANDS,
    Autopilot,
    MissionItem,
    MissionPlan,
)

from ._common import fmt_float, read_text, write_text

__all__ = ["loads", "dumps", "read", "write", "HEADER"]

HEADER = "QGC WPL 110"
HEADER_OLD_QGC = "QGC WPL 120"  # old QGroundControl: no home line (QGC still reads it)
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
    """Parse WPL 110 text. Raises FileFormatError naming file, line and column.

    Read like pymavlink's ``mavwp`` and MAVSDK's importer: items are taken in file order and
    renumbered (index gaps or all-zero indices are accepted), a header-only file is an empty
    mission, a trailing tab is ignored. The first line is the planned home only when it looks like
    one (a NAV_WAYPOINT in the absolute frame or marked current, as Mission Planner, MAVProxy and
    QGroundControl write it); anything else there -- a takeoff, say -- is the first item. A file of
    geofence or rally items is refused: it is not a mission.
    """
    lines = text.splitlines()
    header = lines[0].strip() if lines else ""
    if header not in (HEADER, HEADER_OLD_QGC):
        got = header[:40] if lines else "an empty file"
        raise FileFormatError(f"first line must be '{HEADER}', got {got!r}", path=path, line=1, field="header")
    rows = []
    for lineno, line in enumerate(lines[1:], start=2):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        body = line.strip()
        cols = body.split("\t") if "\t" in body else body.split()
        cols = [c.strip() for c in cols]
        if len(cols) != 12:
            raise FileFormatError(f"expected 12 tab-separated columns, got {len(cols)}", path=path, line=lineno)
        rows.append((lineno, _parse_row(cols, path, lineno)))
    _refuse_fence_and_rally(rows, path)
    has_home = header == HEADER and bool(rows) and _looks_like_home(rows[0][1])
    hlat = hlon = halt = math.nan
    if has_home:
        _, home = rows.pop(0)
        if not (home[8] == 0.0 and home[9] == 0.0):  # 0, 0: the "no home" placeholder
            hlat, hlon, halt = home[8], home[9], home[10]
    # Without a home line the file's index k is our item k + 1 (home is item 0): shift jump targets.
    jump_shift = 0.0 if has_home else 1.0
    items = []
    for lineno, r in rows:
        if r[2] in GLOBAL_FRAMES:
            if not (-90.0 <= r[8] <= 90.0 or math.isnan(r[8])):
                raise FileFormatError(f"latitude {r[8]} is outside -90..90 degrees", path=path, line=lineno,
                                      field="latitude/x")
            if not (-180.0 <= r[9] <= 180.0 or math.isnan(r[9])):
                raise FileFormatError(f"longitude {r[9]} is outside -180..180 degrees", path=path, line=lineno,
                                      field="longitude/y")
            if r[3] in POSITIONAL_COMMANDS and not math.isfinite(r[10]):
                raise FileFormatError(f"altitude {r[10]} is not a finite number", path=path, line=lineno,
                                      field="altitude/z")
        params = (r[4] + jump_shift if r[3] == DO_JUMP else r[4], r[5], r[6], r[7])
        items.append((lineno, MissionItem(r[3], r[2], params, r[8], r[9], r[10], bool(r[11]))))
    for lineno, it in items:
        if it.command == DO_JUMP:
            target = it.params[0]
            if not (target.is_integer() and 1 <= target <= len(items)):
                first = 1 if has_home else 0
                raise FileFormatError(
                    f"DO_JUMP target {target - jump_shift:g} is not the index of an item of this mission "
                    f"({first}..{len(items) - 1 + first})", path=path, line=lineno, field="param1")
    return MissionPlan(tuple(it for _, it in items), hlat, hlon, halt, autopilot=autopilot)


def _looks_like_home(row: list) -> bool:
    return row[3] in (0, NAV_WAYPOINT) and (row[2] == FRAME_GLOBAL or row[1] == 1)


_FENCE_NAMES = {5000: "fence return point", 5001: "inclusion polygon vertex", 5002: "exclusion polygon vertex",
                5003: "inclusion circle", 5004: "exclusion circle", 5100: "rally point"}


def _refuse_fence_and_rally(rows: list, path: str) -> None:
    kinds = [r[3] for _, r in rows]
    special = [k for k in kinds if k in FENCE_COMMANDS or k in RALLY_COMMANDS]
    if not special:
        return
    rest = [k for i, k in enumerate(kinds) if k not in FENCE_COMMANDS and k not in RALLY_COMMANDS
            and not (i == 0 and _looks_like_home(rows[0][1]))]
    if not rest:
        what = "rally-point" if all(k in RALLY_COMMANDS for k in special) else "geofence"
        names = ", ".join(sorted({_FENCE_NAMES[k] for k in special}))
        raise FileFormatError(
            f"this is a {what} file, not a mission: {len(special)} item(s) of kind {names} (a .plan carries "
            "fences and rally points next to its mission)", path=path)
    lineno, row = next((ln, r) for ln, r in rows if r[3] in FENCE_COMMANDS or r[3] in RALLY_COMMANDS)
    raise FileFormatError(f"command {row[3]} ({_FENCE_NAMES[row[3]]}) belongs to a geofence or rally list and "
                          "cannot be part of a mission", path=path, line=lineno, field="command")


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
            top = {2: 255, 3: 65535}.get(k)  # MISSION_ITEM_INT.frame is a uint8, .command a uint16
            if top is not None and v > top:
                raise FileFormatError(f"{v} does not fit MAVLink's {name} field (0..{top})", path=path, line=lineno,
                                      field=name)
        else:
            try:
                v = float(text)
            except ValueError:
                raise FileFormatError(f"must be a number, got {text!r}", path=path, line=lineno, field=name) from None
            if math.isinf(v):
                raise FileFormatError("must be finite", path=path, line=lineno, field=name)
        out.append(v)
    return out
