"""The operator's live status: vehicles (mode, battery, mission progress, lost) and people found.

One renderer, two outputs: on a terminal the view is redrawn in place with ANSI escapes a few
times a second; into a file or log it becomes one plain status line every ``period_s`` seconds
(events are always printed as they happen, one line each, in both modes).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable, Sequence, TextIO


@dataclass(frozen=True)
class VehicleStatus:
    vehicle: int
    phase: str  # connecting, uploading, waiting for operator, scanning, localizing, returning, landed, lost
    mode: str = "?"
    battery_pct: float | None = None
    mission_seq: int | None = None
    mission_total: int | None = None
    lost: bool = False
    note: str = ""  # lost in the air: where and when it was last heard (service/lost.py)


@dataclass(frozen=True)
class PersonStatusView:
    """One person as the views show it; positions in the local frame [m] (NaN when unknown).
    ``mirror_*``: the other candidate while the estimate is ambiguous."""

    emitter_id: int
    radius95_m: float
    located: bool
    reason: str = ""
    east_m: float = math.nan
    north_m: float = math.nan
    t_ref_s: float = math.nan
    vel_east_m_s: float = math.nan
    vel_north_m_s: float = math.nan
    ambiguous: bool = False
    mirror_east_m: float = math.nan
    mirror_north_m: float = math.nan
    mirror_radius95_m: float = math.nan


def person_view(status) -> PersonStatusView:
    """The view of a ``search.policy.PersonStatus`` (the believed candidate, and the other one
    while the estimate is ambiguous)."""
    def num(x) -> float:
        try:
            v = float(x)
        except (TypeError, ValueError):
            return math.nan
        return v

    xy = status.xy_m if status.xy_m is not None else (math.nan, math.nan)
    vel = status.velocity_m_s if getattr(status, "velocity_m_s", None) is not None else (math.nan, math.nan)
    est = status.estimate
    ambiguous = bool(getattr(est, "ambiguous", False)) and not status.located
    mxy, mr = (math.nan, math.nan), math.nan
    mirror = getattr(est, "mirror", None) if ambiguous else None
    if mirror is not None:
        primary = tuple(float(v) for v in getattr(est, "position_xy_m", (math.nan, math.nan)))
        cand = tuple(float(v) for v in mirror.position_xy_m)
        # show the candidate that is not the believed one (the policy may believe the mirror)
        if math.dist(cand, (num(xy[0]), num(xy[1]))) < 1e-6:  # the primary's own radius, when known
            mxy, mr = primary, num(getattr(est, "mode_radius95_m", math.nan))
        else:
            mxy, mr = cand, num(getattr(mirror, "radius95_m", math.nan))
    return PersonStatusView(int(status.emitter_id), num(status.radius95_m), bool(status.located), status.reason or "",
                            num(xy[0]), num(xy[1]), num(status.t_ref_s), num(vel[0]), num(vel[1]), ambiguous,
                            mxy[0], mxy[1], mr)


@dataclass(frozen=True)
class StatusSnapshot:
    """What the view shows at one moment. ``elapsed_s`` is mission time since the search began."""

    elapsed_s: float
    vehicles: Sequence[VehicleStatus]
    people: Sequence[PersonStatusView]
    slots: int
    required_accuracy_m: float
    replans: int = 0
    note: str = ""
    extra: dict = field(default_factory=dict)


def _vehicle_text(v: VehicleStatus) -> str:
    batt = "--" if v.battery_pct is None else f"{v.battery_pct:3.0f}%"
    prog = ""
    if v.mission_seq is not None and v.mission_total:
        prog = f" item {v.mission_seq}/{v.mission_total}"
    state = "LOST" if v.lost else v.phase
    return f"UAV{v.vehicle} {v.mode:<6} {batt} {state}{prog}"


def render_lines(s: StatusSnapshot, labels=None, frame=None) -> list[str]:
    """The multi-line view (terminal mode). ``labels``: a ``service.labels.PersonLabels``;
    ``frame``: the scenario's ``geo.LocalFrame``, to show each located person's latitude and
    longitude (one per line; the others three to a line)."""
    located = sum(p.located for p in s.people)
    lines = [f"uavloc  mission t = {s.elapsed_s:7.1f} s   slots {s.slots:>7}   replans {s.replans:>3}   "
             f"people located {located}/{len(s.people)} (within {s.required_accuracy_m:g} m)"]
    if s.note:
        lines.append(s.note)
    lines.append("")
    for v in s.vehicles:
        lines.append("  " + _vehicle_text(v))
    lines.append("")
    row = []
    name = labels.name if labels is not None else (lambda eid: f"#{eid}")
    if labels is not None:  # people linked from addresses are labelled as they appear
        labels.add(p.emitter_id for p in sorted(s.people, key=lambda p: p.emitter_id))

    def order(p):
        lab = labels.get(p.emitter_id) if labels is not None else ""
        return (not lab, len(lab), lab, p.emitter_id)

    for p in sorted(s.people, key=order):
        r = "  ?  " if not math.isfinite(p.radius95_m) else f"{p.radius95_m:5.1f}"
        cell = f"{name(p.emitter_id):<15} {r} m {'ok' if p.located else '..'}"
        if frame is not None and p.located and math.isfinite(p.east_m) and math.isfinite(p.north_m):
            lat, lon = frame.to_wgs84(p.east_m, p.north_m)
            lines.append(f"  {cell}  {float(lat):.6f}, {float(lon):.6f}")
            continue
        row.append(cell)
        if len(row) == 3:
            lines.append("  " + "   ".join(row))
            row = []
    if row:
        lines.append("  " + "   ".join(row))
    return lines


def render_line(s: StatusSnapshot) -> str:
    """The one-line view (log mode)."""
    located = sum(p.located for p in s.people)
    vs = " | ".join(_vehicle_text(v) for v in s.vehicles)
    return (f"mission_t={s.elapsed_s:7.1f}s slots={s.slots} located={located}/{len(s.people)} "
            f"replans={s.replans} | {vs}")


class LiveView:
    """Feed it snapshots (``update``) and events (``event``); it decides when and how to draw."""

    def __init__(self, stream: TextIO, *, tty: bool | None = None, period_s: float = 5.0,
                 redraw_s: float = 0.25, clock: Callable[[], float] = time.monotonic):
        self.stream = stream
        self.tty = stream.isatty() if tty is None else tty
        self.period_s = period_s if not self.tty else redraw_s
        self.clock = clock
        self._last_draw = -math.inf
        self._drawn_lines = 0
        self.labels = None  # a service.labels.PersonLabels: people shown as "P01 #17"
        self.report_follows = False  # the final statement is printed after the results table
        self.frame = None  # the scenario's geo.LocalFrame: located people shown with lat/lon

    def update(self, snapshot: StatusSnapshot, *, force: bool = False) -> None:
        now = self.clock()
        if not force and now - self._last_draw < self.period_s:
            return
        self._last_draw = now
        if self.tty:
            if self.labels is not None:
                self.labels.refresh()
            lines = render_lines(snapshot, self.labels, self.frame)
            # move to the top of the previous drawing and clear to the end of the screen
            up = f"\x1b[{self._drawn_lines}F" if self._drawn_lines else ""
            self.stream.write(up + "\x1b[J" + "\n".join(lines) + "\n")
            self._drawn_lines = len(lines)
        else:
            self.stream.write(render_line(snapshot) + "\n")
        self.stream.flush()

    def event(self, text: str, elapsed_s: float | None = None) -> None:
        # mission seconds: the vehicles' clock since the search began (a simulator's speed-up runs it
        # faster than the wall clock), said as such (issue 42 item 7)
        stamp = "" if elapsed_s is None else f"[mission {elapsed_s:7.1f} s] "
        if self.tty and self._drawn_lines:
            # print above the status block: clear it, print, and let the next update redraw it
            self.stream.write(f"\x1b[{self._drawn_lines}F\x1b[J")
            self._drawn_lines = 0
            self._last_draw = -math.inf
        self.stream.write(stamp + text + "\n")
        self.stream.flush()
