"""A vehicle lost in the air (issue 42 item 2): what the operator must hear first.

A vehicle that falls silent while it is not on the ground and disarmed (by its own last word,
``VehicleAgent.landed``) is somewhere with its motors on, or down where nobody saw it land. Its
last known state -- where, how high, battery, when -- is the first sentence of the search's
statement, the first lines of results.txt and people.csv, a member and a point of people.geojson,
a placemark of people.kml, the title of result.png and a banner on the live map; and ``uavloc
daemon`` exits with EXIT_VEHICLE_LOST, whatever was located.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Sequence

from ..atomicfile import atomic_write_text

EXIT_VEHICLE_LOST = 5  # `uavloc daemon`: a vehicle was lost in the air and not heard again


@dataclass(frozen=True)
class LastHeard:
    """What a vehicle said last before it fell silent. ``t_s``: mission time of its last message
    (the vehicles' clock); ``unix_s``: this computer's UTC when that message arrived."""

    vehicle: int
    airborne: bool  # not on the ground and disarmed by its own last report
    t_s: float
    unix_s: float
    lat_deg: float
    lon_deg: float
    east_m: float
    north_m: float
    rel_alt_m: float
    battery_pct: float | None
    mode: str
    armed: bool

    def where(self) -> str:
        """Position, height and battery, as one phrase."""
        if not (math.isfinite(self.lat_deg) and math.isfinite(self.lon_deg)):
            pos = "at an unknown position (no position was received)"
        else:
            ew = f"{abs(self.east_m):.0f} m {'east' if self.east_m >= 0 else 'west'}"
            ns = f"{abs(self.north_m):.0f} m {'north' if self.north_m >= 0 else 'south'}"
            pos = (f"at {self.lat_deg:.7f}, {self.lon_deg:.7f} ({ew}, {ns} of the launch point, "
                   f"{math.hypot(self.east_m, self.north_m):.0f} m away)")
        alt = f"{self.rel_alt_m:.1f} m above home" if math.isfinite(self.rel_alt_m) else "height unknown"
        batt = f"battery {self.battery_pct:.0f} %" if self.battery_pct is not None else "battery unknown"
        return f"{pos}, {alt}, {batt}, {'armed' if self.armed else 'disarmed'} in {self.mode}"

    def when(self) -> str:
        stamp = datetime.fromtimestamp(self.unix_s, tz=timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC") \
            if math.isfinite(self.unix_s) else "an unknown time"
        return f"{stamp} (this computer's clock; mission time {self.t_s:.1f} s)"

    def sentence(self) -> str:
        """The operator's first sentence about this vehicle."""
        return (f"Vehicle {self.vehicle} was lost in the air: last heard at {self.when()}, {self.where()}; "
                "nobody has seen it land.")

    def to_dict(self) -> dict:
        d = asdict(self)
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in d.items()} | {
            "statement": self.sentence(),
            "time_utc": datetime.fromtimestamp(self.unix_s, tz=timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
            if math.isfinite(self.unix_s) else None}


def last_heard(vehicle: int, agent, frame, *, now_s: float, wall_now_s: float, unix_now_s: float,
               clock_rate: float) -> LastHeard:
    """``agent``'s (a ``VehicleAgent``) last report, timed from how long it has been silent:
    ``wall_now_s`` is the daemon's wall clock (the one ``agent.tel.wall_s`` is on), ``now_s`` the
    mission time and ``unix_now_s`` this computer's UNIX time now; ``clock_rate``: mission
    seconds per wall second."""
    t = agent.tel
    silent = max(0.0, wall_now_s - t.wall_s) if math.isfinite(t.wall_s) else math.nan
    e = n = math.nan
    if math.isfinite(t.lat_deg) and math.isfinite(t.lon_deg):
        e, n = (float(x) for x in frame.to_local(t.lat_deg, t.lon_deg))
    return LastHeard(int(vehicle), not agent.landed(), now_s - silent * clock_rate, unix_now_s - silent,
                     float(t.lat_deg), float(t.lon_deg), e, n, float(t.rel_alt_m), t.battery_pct, str(t.mode),
                     bool(t.armed))


def title_mark(lost: Sequence[LastHeard]) -> str:
    """What result.png's and people.kml's titles add."""
    if not lost:
        return ""
    return f" -- VEHICLE {', '.join(str(x.vehicle) for x in lost)} LOST IN THE AIR"


def mark_lost(files: Sequence[Path], lost: Sequence[LastHeard]) -> None:
    """Put the lost vehicles first in the written result ``files``: results.txt and people.csv begin
    with their sentences (people.csv as '#' comment lines), people.geojson gets a top-level
    ``vehicles_lost`` member and a ``vehicle_lost`` point at each last position, people.kml a
    placemark there (result.png and the KML's name carry :func:`title_mark`)."""
    if not lost:
        return
    for path in map(Path, files):
        if path.name == "results.txt":
            atomic_write_text(path, "".join(x.sentence() + "\n" for x in lost) + path.read_text())
        elif path.name == "people.csv":
            atomic_write_text(path, "".join(f"# {x.sentence()}\n" for x in lost) + path.read_text())
        elif path.name == "people.geojson":
            doc = json.loads(path.read_text())
            doc["vehicles_lost"] = [x.to_dict() for x in lost]
            doc["features"][:0] = [{"type": "Feature",
                                    "geometry": {"type": "Point",
                                                 "coordinates": [round(x.lon_deg, 7), round(x.lat_deg, 7)]},
                                    "properties": {"kind": "vehicle_lost", **x.to_dict()}}
                                   for x in lost if math.isfinite(x.lat_deg) and math.isfinite(x.lon_deg)]
            atomic_write_text(path, json.dumps(doc, indent=1) + "\n")
        elif path.name == "people.kml":
            text = path.read_text()
            marks = "".join(
                f"<Placemark><name>vehicle {x.vehicle} LOST IN THE AIR</name>"
                f"<description>{_xml(x.sentence())}</description>"
                + (f"<Point><coordinates>{x.lon_deg:.7f},{x.lat_deg:.7f},0</coordinates></Point>"
                   if math.isfinite(x.lat_deg) and math.isfinite(x.lon_deg) else "")
                + "</Placemark>" for x in lost)
            head = "<Document>"
            i = text.find("</name>", text.find(head))
            at = i + len("</name>") if i >= 0 else text.find(head) + len(head)
            atomic_write_text(path, text[:at] + marks + text[at:])


def _xml(text: str) -> str:
    from xml.sax.saxutils import escape  # noqa: PLC0415

    return escape(text)
