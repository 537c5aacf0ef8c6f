"""One entry point for "a mission file someone gave us": a QGroundControl ``.plan`` or a QGC WPL
``.waypoints``/``.txt``, chosen by suffix or, failing that, by content. Used by ``uavloc preview``
and ``uavloc upload`` so both accept and refuse exactly the same files.
"""

from __future__ import annotations

from pathlib import Path

from uavloc_gcs.errors import FileFormatError
from uavloc_gcs.mission import Autopilot, MissionPlan

from . import plan as plan_file
from . import waypoints as wpl_file
from ._common import read_text

__all__ = ["read", "PLAN", "WAYPOINTS"]

PLAN = "QGroundControl plan"
WAYPOINTS = "QGC WPL 110 waypoints"


def read(path: str | Path, *, autopilot: Autopilot | None = None) -> tuple[MissionPlan, str]:
    """``(mission, kind)`` for the file at ``path``. ``autopilot`` applies to WPL files (which do
    not record it; ArduPilot when None); a ``.plan`` names its own."""
    p = Path(path)
    text = read_text(p)
    suffix = p.suffix.lower()
    head = text.lstrip()[:20]
    if suffix in (".plan", ".mission") or (suffix not in (".waypoints", ".txt") and head.startswith("{")):
        return plan_file.loads(text, path=str(p)), PLAN
    if suffix in (".waypoints", ".txt") or head.startswith("QGC WPL"):
        return wpl_file.loads(text, path=str(p), autopilot=autopilot or "ardupilot"), WAYPOINTS
    raise FileFormatError("is not a mission file (.plan or .waypoints): neither QGroundControl plan JSON nor "
                          "QGC WPL 110 text", path=str(p))
