"""What the live map shows, gathered from the store (tracks, events, plans) and the daemon's
snapshot (phases, people with both mirror candidates), as JSON-ready dicts.

The store is read incrementally (rows after the last row id seen), in a worker thread, through
its own read-only SQLite connection, so the daemon's loop and writer are never held up. Positions
are sent in the scenario's local frame (east/north metres from the launch point) with the
frame's origin, so the page draws without any projection library.
"""

from __future__ import annotations

import json
import math
import re
import sqlite3
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ...render.estimates import STATE_COLORS
from ...render.palette import vehicle_color
from ...scenario import Scenario
from ...search.targets import inside_area
from ..labels import PersonLabels
from ..liveview import StatusSnapshot
from ..clock import MissionClock, clock_label
from ..results import located_by_text, person_state, utc_text

_LOOKS = re.compile(r"(looks at )([\d, ]+)")  # the daemon's "vehicle 2 looks at 17, 42"
_PERSON = re.compile(r"\bperson (\d+)")  # the statement's "person 17: ..."
TRACK_STEP_M = 2.0  # a new track point only after this much movement (keeps the page light)
COVERAGE_PERIOD_S = 2.0  # wall seconds between two recomputations of the achieved POD for the page
MAX_EVENTS = 500  # the newest events kept for the timeline


def _f(x, nd: int = 2):
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return round(v, nd) if math.isfinite(v) else None


@dataclass
class _Track:
    points: list = field(default_factory=list)  # [[east, north], ...] in metres
    heading_deg: float | None = None

    def add(self, e: float, n: float) -> bool:
        if self.points:
            pe, pn = self.points[-1]
            d = math.hypot(e - pe, n - pn)
            if d < TRACK_STEP_M:
                return False
            self.heading_deg = math.degrees(math.atan2(e - pe, n - pn)) % 360.0  # course over ground
        self.points.append([round(e, 1), round(n, 1)])
        return True


class MapFeed:
    """The map's state. ``poll()`` (in a thread) reads what the store committed since the last
    call; ``state()`` and ``delta()`` build what the page gets. ``snapshot``: the daemon's
    ``snapshot`` method (None: people come from the store's estimates, without mirrors)."""

    def __init__(self, scenario: Scenario, store_path: str | Path, *,
                 snapshot: Callable[[], StatusSnapshot] | None = None,
                 epoch: Callable[[], float | None] | None = None, labels: PersonLabels | None = None,
                 coverage: Callable[[], object] | None = None):
        self.sc = scenario
        self.frame = scenario.frame
        self.store_path = Path(store_path)
        self.snapshot = snapshot
        self.epoch = epoch
        self.labels = labels if labels is not None else PersonLabels(store_path)
        self.tracks: dict[int, _Track] = {}
        self.events: list[dict] = []
        self.events_dropped = 0
        self.telemetry: dict[int, dict] = {}
        self.plan: dict | None = None
        self.estimates: dict[int, dict] = {}
        self.meta: dict = {}
        self.version = 0
        self.finished = False
        self.final: list | None = None  # the search's results once written (PersonResult)
        self._cursor = {"telemetry": 0, "events": 0, "estimates": 0}
        self._plan_rowid = 0
        self.coverage = coverage  # -> search.coverage.Coverage of the running search (None: no POD layer)
        self._pod: tuple[float, dict | None] = (-math.inf, None)

    # -- reading the store (worker thread) ------------------------------------------------------
    def poll(self) -> bool:
        """Read new rows; True when anything changed. A store not created yet changes nothing."""
        if not self.store_path.exists():
            return False
        try:
            conn = sqlite3.connect(f"file:{self.store_path}?mode=ro", uri=True, timeout=1.0)
        except sqlite3.Error:
            return False
        self.labels.refresh()  # before the events, so they can name people by label
        try:
            changed = self._read(conn)
        except sqlite3.OperationalError:  # the schema is not there yet, or the store is busy
            return False
        finally:
            conn.close()
        if changed:
            self.version += 1
        return changed

    def _read(self, conn: sqlite3.Connection) -> bool:
        changed = False
        rows = conn.execute("SELECT rowid, t_s, vehicle, lat_deg, lon_deg, alt_m, battery_pct, mode, mission_seq, "
                            "lost FROM telemetry WHERE rowid > ? ORDER BY rowid", (self._cursor["telemetry"],)).fetchall()
        if rows:
            self._cursor["telemetry"] = rows[-1][0]
            rows = [r for r in rows if r[3] is not None and r[4] is not None and math.isfinite(r[3])
                    and math.isfinite(r[4])]
        local = self.frame.to_local_xy(np.array([[r[3], r[4]] for r in rows], dtype=float)) if rows else []
        for (rowid, t_s, v, lat, lon, alt, batt, mode, seq, lost), (e, n) in zip(rows, local):
            e, n = float(e), float(n)
            tr = self.tracks.setdefault(int(v), _Track())
            tr.add(e, n)
            self.telemetry[int(v)] = {"t_s": t_s, "east_m": e, "north_m": n, "alt_m": alt, "battery_pct": batt,
                                      "mode": mode, "mission_seq": seq, "lost": bool(lost)}
            changed = True
        for rowid, t_s, wall_s, v, kind, text in conn.execute(
                "SELECT rowid, t_s, wall_s, vehicle, kind, text FROM events WHERE rowid > ? ORDER BY rowid",
                (self._cursor["events"],)):
            self._cursor["events"] = rowid
            if kind == "statustext":
                text = f"vehicle {v} says: {text}"
            else:
                text = self._named(text)
            self.events.append({"t_s": _f(t_s, 1), "kind": kind, "text": text, "vehicle": v})
            changed = True
        if len(self.events) > MAX_EVENTS:
            self.events_dropped += len(self.events) - MAX_EVENTS
            del self.events[:len(self.events) - MAX_EVENTS]
        for row in conn.execute("SELECT rowid, * FROM estimates WHERE rowid > ? ORDER BY rowid",
                                (self._cursor["estimates"],)):
            self._cursor["estimates"] = row[0]
            t_s, eid, x, y, vx, vy, r95, _bound, located, ambiguous, reason = row[1:]
            self.estimates[int(eid)] = {"t_s": t_s, "east_m": x, "north_m": y, "vel": (vx, vy), "radius95_m": r95,
                                        "located": bool(located), "ambiguous": bool(ambiguous), "reason": reason or ""}
            changed = True
        plan = conn.execute("SELECT rowid, plan_json FROM plans WHERE rowid > ? ORDER BY rowid DESC LIMIT 1",
                            (self._plan_rowid,)).fetchone()
        if plan is not None:
            self._plan_rowid = plan[0]
            self.plan = json.loads(plan[1])
            changed = True
        meta = {k: json.loads(v) for k, v in conn.execute("SELECT key, value FROM meta")}
        if meta != self.meta:
            self.meta = meta
            self.finished = bool(meta.get("finished"))
            changed = True
        return changed

    def _named(self, text: str) -> str:
        """The daemon's event text with people named by label ("P03 #17") where it names them."""
        def name(eid: str) -> str:
            return self.labels.name(int(eid)) if self.labels.get(int(eid)) else eid

        text = _LOOKS.sub(lambda m: m.group(1) + ", ".join(name(e.strip()) for e in m.group(2).split(",")
                                                           if e.strip()), text)
        return _PERSON.sub(lambda m: name(m.group(1)) if self.labels.get(int(m.group(1))) else m.group(0), text)

    # -- what the page gets -------------------------------------------------------------------------
    def static(self) -> dict:
        """What never changes during a search: area, launch, frame origin, colours."""
        area = self.sc.area_xy_m()
        lat0, lon0 = (float(v) for v in self.frame.to_wgs84(0.0, 0.0))
        cells = None
        if self.coverage is not None:
            from ...search.coverage import grid_for  # noqa: PLC0415

            g = grid_for(self.sc)  # the daemon's accumulator's cells, in the same order as its POD
            cells = {"cell_m": g.cell_m, "xy_m": np.round(g.xy_m, 1).tolist()}
        terrain = None
        if self.sc.dem is not None:  # contour lines of terrain.dem under the map
            from ...render.terrain import contour_lines  # noqa: PLC0415

            terrain = contour_lines(self.sc.dem, np.vstack([area, np.zeros((1, 2))]))
        return {"name": self.sc.name, "origin_lat_deg": lat0, "origin_lon_deg": lon0, "pod_cells": cells,
                "terrain": terrain,
                "area_xy_m": np.round(np.asarray(area, dtype=float), 1).tolist(),
                "required_accuracy_m": self.sc.people.required_accuracy_m, "state_colors": STATE_COLORS,
                "vehicles": self.sc.fleet.vehicles}

    def _epoch(self):
        """The search's clock (service.clock.MissionClock, or the stored epoch: real time)."""
        e = self.epoch() if self.epoch is not None else None
        if isinstance(e, MissionClock) and e.epoch_unix_s is None:
            e = None
        return e if e is not None else self.meta.get("epoch_unix_s")

    def set_final(self, people, coverage=None) -> None:
        """Show the final results (``service.results.PersonResult``, labelled) from now on, and the
        final coverage claims (search.coverage.CoverageSummary) if given: the map then says what
        the files say."""
        self.final = list(people)
        if coverage is not None:
            self._pod = (math.inf, {**coverage.to_dict(), "pod": np.round(coverage.pod1, 2).tolist(),
                                    "statement": coverage.sentence()})
        self.finished = True
        self.version += 1

    def _people(self, snap: StatusSnapshot | None) -> list[dict]:
        epoch = self._epoch()
        out = []
        if self.final is not None:
            rows = [(p.emitter_id, p.east_m, p.north_m, p.radius95_m, p.located, p.reason, p.t_ref_s,
                     (p.vel_east_m_s, p.vel_north_m_s), not p.ambiguity_resolved, (math.nan, math.nan), math.nan)
                    for p in self.final if p.reason != "never heard"]
        elif snap is not None:
            views = {p.emitter_id: p for p in snap.people}
            rows = [(eid, v.east_m, v.north_m, v.radius95_m, v.located, v.reason, v.t_ref_s,
                     (v.vel_east_m_s, v.vel_north_m_s), v.ambiguous, (v.mirror_east_m, v.mirror_north_m),
                     v.mirror_radius95_m) for eid, v in views.items()]
        else:
            rows = [(eid, r["east_m"], r["north_m"], r["radius95_m"], r["located"], r["reason"], r["t_s"], r["vel"],
                     r["ambiguous"], (math.nan, math.nan), math.nan) for eid, r in self.estimates.items()]
        area, margin = self.sc.area_xy_m(), self.sc.people.required_accuracy_m
        self.labels.add(sorted(r[0] for r in rows))  # people linked from addresses, labelled as they appear
        for eid, e, n, r95, located, reason, t_ref, vel, ambiguous, mirror, mirror_r in rows:
            if ambiguous and all(math.isfinite(v) for v in (e, n, *mirror)) and \
                    inside_area(area, (e, n), margin) != inside_area(area, mirror, margin):
                # as the policy does: the area rules out the candidate outside it
                ambiguous, mirror, mirror_r = False, (math.nan, math.nan), math.nan
            state = person_state(located, reason)
            label = self.labels.get(eid)
            vx, vy = (_f(v, 3) for v in vel)
            item = {"id": eid, "label": label, "name": f"{label} #{eid}" if label else f"#{eid}", "state": state,
                    "east_m": _f(e, 1), "north_m": _f(n, 1), "radius95_m": _f(r95, 1), "reason": reason,
                    "t_ref_s": _f(t_ref, 1), "time_utc": utc_text(epoch, t_ref) if t_ref is not None else "",
                    "vel_east_m_s": vx, "vel_north_m_s": vy, "ambiguous": bool(ambiguous),
                    "mirror_east_m": _f(mirror[0], 1), "mirror_north_m": _f(mirror[1], 1),
                    "mirror_radius95_m": _f(mirror_r, 1)}
            if item["east_m"] is not None:
                lat, lon = self.frame.to_wgs84(e, n)
                item["lat_deg"], item["lon_deg"] = _f(lat, 7), _f(lon, 7)
            out.append(item)
        out.sort(key=lambda p: (not p["label"], len(p["label"]), p["label"], p["id"]))
        return out

    def _vehicles(self, snap: StatusSnapshot | None) -> list[dict]:
        status = {v.vehicle: v for v in snap.vehicles} if snap is not None else {}
        ids = sorted(set(status) | set(self.telemetry))
        out = []
        for vid in ids:
            tel, st, tr = self.telemetry.get(vid, {}), status.get(vid), self.tracks.get(vid)
            batt = st.battery_pct if st is not None and st.battery_pct is not None else tel.get("battery_pct")
            out.append({"id": vid, "color": vehicle_color(vid - 1), "east_m": _f(tel.get("east_m"), 1),
                        "north_m": _f(tel.get("north_m"), 1), "alt_m": _f(tel.get("alt_m"), 1),
                        "heading_deg": _f(tr.heading_deg if tr else None, 0),
                        "mode": st.mode if st is not None else tel.get("mode", "?"),
                        "battery_pct": _f(batt, 0), "phase": st.phase if st is not None else "",
                        "lost": bool(st.lost if st is not None else tel.get("lost", False)),
                        "note": getattr(st, "note", "") if st is not None else "",  # lost in the air: last heard
                        "mission_seq": st.mission_seq if st is not None else tel.get("mission_seq"),
                        "mission_total": st.mission_total if st is not None else None})
        return out

    def _plan(self) -> dict | None:
        if not self.plan:
            return None
        tasks = []
        for task in self.plan.get("tasks", []):
            pts = np.asarray(task.get("waypoints_xy_m", []), dtype=float).reshape(-1, 2)[:-1]  # last: home
            targets = [int(t) for t in task.get("targets", [])]
            tasks.append({"vehicle": int(task["vehicle"]), "looks_xy_m": np.round(pts, 1).tolist(),
                          "targets": targets, "labels": [self.labels.name(t) for t in targets]})
        return {"t_s": _f(self.plan.get("t_s"), 1), "tasks": tasks}

    def _coverage(self) -> dict | None:
        """The achieved POD now (per cell, in ``static()["pod_cells"]`` order, and the area's figures
        with the statement), recomputed at most every COVERAGE_PERIOD_S."""
        cov = self.coverage() if self.coverage is not None else None
        if cov is None:
            return None
        now = time.monotonic()
        if now - self._pod[0] >= COVERAGE_PERIOD_S or self._pod[1] is None:
            s = cov.summary()
            self._pod = (now, {**s.to_dict(), "pod": np.round(s.pod1, 2).tolist(), "statement": s.sentence()})
        return self._pod[1]

    def live(self) -> dict:
        """The part that changes: clock, vehicles, people, plan (without tracks and events)."""
        snap = self.snapshot() if self.snapshot is not None else None
        t_s = snap.elapsed_s if snap is not None else max(
            (t["t_s"] for t in self.telemetry.values() if t.get("t_s") is not None), default=0.0)
        clock = self._epoch()
        epoch = clock.epoch_unix_s if isinstance(clock, MissionClock) else clock
        vehicles = self._vehicles(snap)
        return {"t_s": _f(t_s, 1), "epoch_unix_s": epoch, "clock_utc": utc_text(clock, t_s) if clock is not None else "",
                "clock_label": clock_label(clock), "slots": snap.slots if snap is not None else None,
                "replans": snap.replans if snap is not None else None, "finished": self.finished,
                "wall_unix_s": round(time.time(), 1), "vehicles": vehicles, "people": self._people(snap),
                # what the operator must see first: a vehicle lost in the air (service/lost.py)
                "alert": " ".join(v["note"] for v in vehicles if v.get("note")),
                "plan": self._plan(), "coverage": self._coverage(),
                # the end's figure, as results.txt and result.png say it (issue 38 item 4)
                "located_by": located_by_text(self.final) if self.final is not None else ""}

    def state(self) -> dict:
        """Everything, for a page that just connected."""
        return {"static": self.static(), **self.live(),
                "tracks": {str(v): tr.points for v, tr in self.tracks.items()},
                "events": self.events, "events_seen": self.events_dropped + len(self.events)}

    def delta(self, sent: "Cursor") -> dict:
        """What a page that has ``sent`` needs now (and advance ``sent``)."""
        tracks = {}
        for v, tr in self.tracks.items():
            k = sent.tracks.get(v, 0)
            if len(tr.points) > k:
                tracks[str(v)] = tr.points[k:]
                sent.tracks[v] = len(tr.points)
        total = self.events_dropped + len(self.events)
        new = self.events[max(0, len(self.events) - (total - sent.events)):] if total > sent.events else []
        sent.events = total
        return {**self.live(), "tracks_append": tracks, "events_append": new}

    def cursor(self) -> "Cursor":
        """The cursor of a page that just got ``state()``."""
        return Cursor({v: len(tr.points) for v, tr in self.tracks.items()}, self.events_dropped + len(self.events))


@dataclass
class Cursor:
    tracks: dict
    events: int
