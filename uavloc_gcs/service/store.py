"""The daemon's state in SQLite (WAL): slots, telemetry, estimates, plans, missions, events.

Writes are queued and committed by one writer thread in small batches: a row handed to the
store is committed at most ``commit_interval_s`` (plus the time of one commit) later, so a crash
(kill -9) loses at most that window. WAL with ``synchronous=NORMAL`` keeps every committed
transaction across a process crash. Reads (for resuming after a restart, and for the results)
open their own connection and see everything committed so far.

Times (``t_s``) are mission-clock seconds (the vehicles' SYSTEM_TIME, UNIX seconds); ``wall_s``
is the daemon's wall clock when it recorded an event.
"""

from __future__ import annotations

import json
import logging
import queue
import sqlite3
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

from ..errors import ConfigError
from ..mission import WireItem
from ..observations import SlotBatch

log = logging.getLogger(__name__)

DEFAULT_COMMIT_INTERVAL_S = 0.1  # bounded commit delay: the worst-case loss window on a crash

_SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS slots (
    t_s REAL NOT NULL, vehicle INTEGER NOT NULL, x_m REAL NOT NULL, y_m REAL NOT NULL,
    z_m REAL NOT NULL, emitter_id INTEGER NOT NULL, rssi_dbm REAL NOT NULL,
    n_samples INTEGER NOT NULL, address INTEGER, fingerprint INTEGER NOT NULL DEFAULT 0,
    channel INTEGER NOT NULL DEFAULT 0, radio INTEGER NOT NULL DEFAULT 0);
CREATE TABLE IF NOT EXISTS telemetry (
    t_s REAL NOT NULL, vehicle INTEGER NOT NULL, lat_deg REAL, lon_deg REAL, alt_m REAL,
    battery_pct REAL, mode TEXT, mission_seq INTEGER, lost INTEGER NOT NULL DEFAULT 0);
CREATE TABLE IF NOT EXISTS estimates (
    t_s REAL NOT NULL, emitter_id INTEGER NOT NULL, x_m REAL, y_m REAL, vx_m_s REAL,
    vy_m_s REAL, radius95_m REAL, bound_m REAL, located INTEGER NOT NULL,
    ambiguous INTEGER NOT NULL, reason TEXT);
CREATE TABLE IF NOT EXISTS plans (t_s REAL NOT NULL, plan_json TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS missions (
    t_s REAL NOT NULL, vehicle INTEGER NOT NULL, purpose TEXT NOT NULL,
    items_json TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS events (
    t_s REAL, wall_s REAL NOT NULL, vehicle INTEGER, kind TEXT NOT NULL, text TEXT NOT NULL);
CREATE INDEX IF NOT EXISTS telemetry_vehicle ON telemetry (vehicle, t_s);
CREATE INDEX IF NOT EXISTS missions_vehicle ON missions (vehicle, t_s);
"""

# Columns added to ``slots`` after the first schema, with the definition ALTER TABLE adds them by:
# a store written before them opens (and migrates) with address NULL (read as the emitter id),
# fingerprint 0, channel 0 (unknown) and radio 0 (Wi-Fi: the only radio before the column).
_SLOT_COLUMNS_ADDED = (
    ("address", "INTEGER"),  # 48-bit 802.11 source address; NULL: the emitter id
    ("fingerprint", "INTEGER NOT NULL DEFAULT 0"),  # content fingerprint, 0 unknown
    ("channel", "INTEGER NOT NULL DEFAULT 0"),  # 802.11 channel, 0 unknown
    ("radio", "INTEGER NOT NULL DEFAULT 0"),  # 0 Wi-Fi, 1 Bluetooth LE (observations.SlotBatch.radio)
)

_INSERT = {
    "slots": "INSERT INTO slots (t_s, vehicle, x_m, y_m, z_m, emitter_id, rssi_dbm, n_samples, address, "
             "fingerprint, channel, radio) VALUES (?,?,?,?,?,?,?,?,?,?,?,?)",
    "telemetry": "INSERT INTO telemetry VALUES (?,?,?,?,?,?,?,?,?)",
    "estimates": "INSERT INTO estimates VALUES (?,?,?,?,?,?,?,?,?,?,?)",
    "plans": "INSERT INTO plans VALUES (?,?)",
    "missions": "INSERT INTO missions VALUES (?,?,?,?)",
    "events": "INSERT INTO events VALUES (?,?,?,?,?)",
    "meta": "INSERT OR REPLACE INTO meta VALUES (?,?)",
}


@dataclass(frozen=True)
class TelemetryRow:
    t_s: float
    vehicle: int
    lat_deg: float
    lon_deg: float
    alt_m: float
    battery_pct: float | None
    mode: str
    mission_seq: int | None
    lost: bool


@dataclass(frozen=True)
class EstimateRow:
    t_s: float
    emitter_id: int
    x_m: float
    y_m: float
    vx_m_s: float
    vy_m_s: float
    radius95_m: float
    bound_m: float
    located: bool
    ambiguous: bool
    reason: str


@dataclass(frozen=True)
class EventRow:
    t_s: float | None
    wall_s: float
    vehicle: int | None
    kind: str
    text: str


@dataclass(frozen=True)
class StoreStats:
    rows_written: int
    commits: int
    max_commit_delay_s: float  # longest observed time from a row's arrival to its commit
    queued: int


def wire_items_to_json(items: Sequence[WireItem]) -> str:
    return json.dumps([[it.seq, it.frame, it.command, it.current, it.autocontinue, it.param1,
                        it.param2, it.param3, it.param4, it.x, it.y, it.z, it.mission_type]
                       for it in items], allow_nan=True)


def wire_items_from_json(text: str) -> list[WireItem]:
    return [WireItem(*row) for row in json.loads(text)]


class Store:
    """SQLite store with a batching writer thread. Use as a context manager or call close()."""

    def __init__(self, path: str | Path, *, commit_interval_s: float = DEFAULT_COMMIT_INTERVAL_S):
        self.path = Path(path)
        self.commit_interval_s = commit_interval_s
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            conn = sqlite3.connect(self.path)
            conn.execute("PRAGMA journal_mode=WAL")
            conn.executescript(_SCHEMA)
            _migrate_slots(conn)
            conn.commit()
            conn.close()
        except sqlite3.DatabaseError as exc:
            raise ConfigError(f"cannot use {self.path} as the daemon's store ({exc})") from None
        except OSError as exc:
            raise ConfigError(f"cannot create the store {self.path} ({exc.strerror})") from None
        self._queue: queue.Queue = queue.Queue()
        self._rows_written = 0
        self._commits = 0
        self._max_delay_s = 0.0
        self._closed = False
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._writer, name="uavloc-store", daemon=True)
        self._thread.start()

    # -- writing (any thread) -----------------------------------------------------------------
    def _put(self, table: str, rows: list[tuple]) -> None:
        if self._error is not None:
            raise ConfigError(f"the store {self.path} failed: {self._error}")
        if rows:
            self._queue.put((table, rows, time.monotonic()))

    def add_slots(self, batch: SlotBatch) -> None:
        if not len(batch):
            return
        rows = list(zip(batch.t_s.tolist(), batch.vehicle.tolist(), batch.xyz_m[:, 0].tolist(),
                        batch.xyz_m[:, 1].tolist(), batch.xyz_m[:, 2].tolist(),
                        batch.emitter_id.tolist(), batch.rssi_dbm.tolist(),
                        batch.n_samples.tolist(), batch.address.tolist(), batch.fingerprint.tolist(),
                        batch.channel.tolist(), batch.radio.tolist()))
        self._put("slots", rows)

    def add_telemetry(self, rows: Iterable[TelemetryRow]) -> None:
        self._put("telemetry", [(r.t_s, r.vehicle, r.lat_deg, r.lon_deg, r.alt_m, r.battery_pct,
                                 r.mode, r.mission_seq, int(r.lost)) for r in rows])

    def add_estimates(self, rows: Iterable[EstimateRow]) -> None:
        self._put("estimates", [(r.t_s, r.emitter_id, r.x_m, r.y_m, r.vx_m_s, r.vy_m_s,
                                 r.radius95_m, r.bound_m, int(r.located), int(r.ambiguous),
                                 r.reason) for r in rows])

    def add_plan(self, t_s: float, plan: dict) -> None:
        self._put("plans", [(t_s, json.dumps(plan, allow_nan=True))])

    def add_mission(self, t_s: float, vehicle: int, purpose: str, items: Sequence[WireItem]) -> None:
        """Record a mission the vehicle acknowledged (``purpose``: scan, replan, resume, ...)."""
        self._put("missions", [(t_s, vehicle, purpose, wire_items_to_json(items))])

    def add_event(self, kind: str, text: str, *, t_s: float | None = None, vehicle: int | None = None) -> None:
        self._put("events", [(t_s, time.time(), vehicle, kind, text)])

    def set_meta(self, key: str, value: Any) -> None:
        self._put("meta", [(key, json.dumps(value))])

    def flush(self, timeout_s: float = 10.0) -> None:
        """Block until everything queued so far is committed."""
        done = threading.Event()
        self._queue.put(("__flush__", done, time.monotonic()))
        if not done.wait(timeout_s) and self._error is None:
            raise ConfigError(f"the store {self.path} did not commit within {timeout_s} s")

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._queue.put(None)
        self._thread.join(timeout=30)

    def __enter__(self) -> "Store":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def stats(self) -> StoreStats:
        return StoreStats(self._rows_written, self._commits, self._max_delay_s, self._queue.qsize())

    # -- the writer thread ------------------------------------------------------------------------
    def _writer(self) -> None:
        conn = sqlite3.connect(self.path, check_same_thread=False)
        conn.execute("PRAGMA journal_mode=WAL")
        conn.execute("PRAGMA synchronous=NORMAL")
        pending: dict[str, list[tuple]] = {}
        oldest: float | None = None
        waiters: list[threading.Event] = []
        stop = False
        try:
            while not stop:
                timeout = None if oldest is None else max(0.0, oldest + self.commit_interval_s - time.monotonic())
                try:
                    item = self._queue.get(timeout=timeout)
                except queue.Empty:
                    item = "__deadline__"
                if item is None:
                    stop = True
                elif item == "__deadline__":
                    pass
                elif item[0] == "__flush__":
                    waiters.append(item[1])
                else:
                    table, rows, t_arrived = item
                    pending.setdefault(table, []).extend(rows)
                    oldest = t_arrived if oldest is None else min(oldest, t_arrived)
                due = oldest is not None and time.monotonic() >= oldest + self.commit_interval_s
                if pending and (due or stop or waiters):
                    n = 0
                    with conn:
                        for table, rows in pending.items():
                            conn.executemany(_INSERT[table], rows)
                            n += len(rows)
                    self._rows_written += n
                    self._commits += 1
                    self._max_delay_s = max(self._max_delay_s, time.monotonic() - oldest)
                    pending.clear()
                    oldest = None
                if not pending:
                    for w in waiters:
                        w.set()
                    waiters.clear()
        except BaseException as exc:  # keep the reason; producers see it on their next write
            log.exception("store writer failed")
            self._error = exc
            for w in waiters:
                w.set()
        finally:
            conn.close()


def _slot_columns(conn: sqlite3.Connection) -> set[str]:
    return {row[1] for row in conn.execute("PRAGMA table_info(slots)")}


def _migrate_slots(conn: sqlite3.Connection) -> None:
    """Add the slot columns a store of an older schema lacks (see ``_SLOT_COLUMNS_ADDED``)."""
    have = _slot_columns(conn)
    for name, definition in _SLOT_COLUMNS_ADDED:
        if name not in have:
            conn.execute(f"ALTER TABLE slots ADD COLUMN {name} {definition}")
            log.info("store: added the slots column %s", name)


# ---------------------------------------------------------------------------------------------
# Reading (resume after a restart, results)


PACK_FRESH_REQUEST = "pack fresh request"  # an operator's word from another process (uavloc pack-fresh)


def request_pack_fresh(path: str | Path, vehicle: int) -> None:
    """Record, in the running search's store, that the operator says ``vehicle`` has a fresh pack
    (the daemon reads it while the vehicle waits: service/swaps.py). Another process writes it:
    the store is in WAL mode, so this waits briefly for the daemon's writer, never for its lock."""
    path = Path(path)
    if not path.exists():
        raise ConfigError(f"no store at {path}: give the --out directory of the running daemon")
    with sqlite3.connect(path, timeout=10.0) as conn:
        conn.execute("INSERT INTO events (t_s, wall_s, vehicle, kind, text) VALUES (NULL, ?, ?, ?, ?)",
                     (time.time(), int(vehicle), PACK_FRESH_REQUEST,
                      f"the operator says vehicle {vehicle} has a fresh pack"))
    conn.close()


class StoreReader:
    """Read-only view of a store file (what was committed)."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        if not self.path.exists():
            raise ConfigError(f"no store at {self.path}")
        self._conn = sqlite3.connect(f"file:{self.path}?mode=ro", uri=True)

    def close(self) -> None:
        self._conn.close()

    def __enter__(self) -> "StoreReader":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def meta(self) -> dict[str, Any]:
        return {k: json.loads(v) for k, v in self._conn.execute("SELECT key, value FROM meta")}

    def slots(self) -> SlotBatch:
        """Every slot in arrival order. A store of the older schema (read-only here, so not
        migrated) reads with address = emitter id, fingerprint 0, channel 0 and radio 0 (Wi-Fi)."""
        have = _slot_columns(self._conn)
        extra = [("COALESCE(address, emitter_id)" if name == "address" else name) if name in have
                 else ("emitter_id" if name == "address" else "0") for name, _ in _SLOT_COLUMNS_ADDED]
        rows = self._conn.execute(
            "SELECT t_s, x_m, y_m, z_m, rssi_dbm, vehicle, emitter_id, n_samples, " + ", ".join(extra)
            + " FROM slots ORDER BY rowid").fetchall()
        if not rows:
            return SlotBatch.empty()
        real = np.array([r[:5] for r in rows], dtype=float)
        ints = np.array([r[5:] for r in rows], dtype=np.int64)  # exact: addresses are 48 bits
        return SlotBatch.from_columns(real[:, 0], ints[:, 0], real[:, 1:4], ints[:, 1], real[:, 4], ints[:, 2],
                                      address=ints[:, 3], fingerprint=ints[:, 4], channel=ints[:, 5],
                                      radio=ints[:, 6])

    def slot_count(self) -> int:
        return int(self._conn.execute("SELECT COUNT(*) FROM slots").fetchone()[0])

    def last_slot_time_s(self) -> float | None:
        return self._conn.execute("SELECT MAX(t_s) FROM slots").fetchone()[0]

    def latest_missions(self) -> dict[int, tuple[str, list[WireItem]]]:
        """The last acknowledged mission per vehicle: {vehicle: (purpose, items)}."""
        out = {}
        for vehicle, purpose, items in self._conn.execute(
            "SELECT vehicle, purpose, items_json FROM missions ORDER BY rowid"
        ):
            out[int(vehicle)] = (purpose, wire_items_from_json(items))
        return out

    def last_mission_seq(self) -> dict[int, int]:
        """The last mission item each vehicle was reported flying to: {vehicle: seq}."""
        rows = self._conn.execute(
            "SELECT vehicle, mission_seq FROM telemetry WHERE mission_seq IS NOT NULL ORDER BY rowid").fetchall()
        return {int(v): int(seq) for v, seq in rows}

    def tracks(self) -> dict[int, np.ndarray]:
        """Flown track per vehicle: {vehicle: (N, 2) lat/lon degrees} from telemetry."""
        out: dict[int, list] = {}
        for vehicle, lat, lon in self._conn.execute(
            "SELECT vehicle, lat_deg, lon_deg FROM telemetry WHERE lat_deg IS NOT NULL ORDER BY rowid"
        ):
            out.setdefault(int(vehicle), []).append((lat, lon))
        return {v: np.array(p, dtype=float) for v, p in out.items()}

    def latest_estimates(self) -> dict[int, EstimateRow]:
        out = {}
        for row in self._conn.execute("SELECT * FROM estimates ORDER BY rowid"):
            r = EstimateRow(row[0], int(row[1]), *row[2:8], bool(row[8]), bool(row[9]), row[10] or "")
            out[r.emitter_id] = r
        return out

    def latest_plan(self) -> dict | None:
        row = self._conn.execute("SELECT plan_json FROM plans ORDER BY rowid DESC LIMIT 1").fetchone()
        return json.loads(row[0]) if row else None

    def events(self, kind: str | None = None) -> list[EventRow]:
        sql = "SELECT t_s, wall_s, vehicle, kind, text FROM events"
        args: tuple = ()
        if kind is not None:
            sql += " WHERE kind = ?"
            args = (kind,)
        return [EventRow(*r) for r in self._conn.execute(sql + " ORDER BY rowid", args)]

    def counts(self) -> dict[str, int]:
        return {t: int(self._conn.execute(f"SELECT COUNT(*) FROM {t}").fetchone()[0])
                for t in ("slots", "telemetry", "estimates", "plans", "missions", "events")}
