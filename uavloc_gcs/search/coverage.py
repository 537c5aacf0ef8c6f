"""What was really searched: the achieved probability of detection (POD) per cell of the area,
from where the vehicles flew (telemetry), not from where they were told to fly (issue 25 item 3,
issue 26 item 3).

:class:`Coverage` is fed every flown position of every vehicle (``add_position``, ``add_track``).
Every position counts at its own height (a look may fly lower than the scan: ``[search]
look_height_m``) except those below ``heights.airborne_floor_m`` above the ground under the vehicle
(the rule ``airborne_slots`` applies to the RSSI slots): a vehicle taking off, landing or on the
ground hears nothing the estimator uses. Between two consecutive positions of one vehicle the
flight is taken as straight; a gap longer than :data:`MAX_GAP_S` (a lost link) counts as not flown,
since the ground does not know where the vehicle was.

For each cell centre the accumulator keeps each vehicle's current *window*: while the vehicle is
within reach of the cell (where ``search.pod`` says one burst is heard with more than
``P_EPS``), the in-range time weighted by the probability of hearing a burst sent there (the
effective window of ``search.pod``). When the vehicle leaves, the window is folded into the
cell's distribution of emissions heard, truncated at two: P(0), P(1), P(>=2), with the window's
probabilities from :func:`window_probs` (continuous emission: any window of a slot; probe bursts:
the population's steady-state renewal model ``search.burst_timing.BurstTiming``) and windows of separate
passes taken as independent. ``pod(1)`` is then 1 - P(0), ``pod(2)`` is P(>=2). This is the live
figure (cheap per position); the final claims use ``search.pod.pod_from_tracks`` over the same
flown tracks (:meth:`Coverage.tracks`), which keeps the dependence between passes that a phone's
long silences make (:func:`final_summary`). The grid is ``search.pod.grid_for``'s cells inside the
area.

A cell is *unsearched* when no window at all covered it (POD exactly 0: no vehicle at survey
altitude came within hearing range); *below target* when its POD is under the target.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, replace

import numpy as np

POD_CACHE_S = 1.0  # wall seconds a POD asked for by the policy's every tick is reused
MIN_STEP_S = 1.0  # telemetry positions are taken at most this often [mission s]
MAX_GAP_S = 5.0  # mission seconds between two positions of a vehicle beyond which the gap is not flown
DEFAULT_POD_TARGET = 0.9  # when the scenario gives none (search.pod_target)
UNSEARCHED_POD = 1e-9  # a cell at or below this POD is unsearched: nothing came within hearing


def pod_target(sc) -> float:
    """The scenario's POD target (``search.pod_target``), else DEFAULT_POD_TARGET."""
    search = getattr(sc, "search", None)
    v = getattr(search, "pod_target", None) if search is not None else None
    return float(v) if v is not None else DEFAULT_POD_TARGET


def people_density_per_km2(sc) -> float | None:
    """People per km² the scenario expects in the area (``people.density_per_km2``), or None."""
    v = getattr(sc.people, "density_per_km2", None)
    return None if v is None else float(v)


class _Windows:
    """What one window (an effective in-range time) does to a phone's count of emissions heard,
    per phone class: continuous emission (one class) counts a window of a slot or more once, as
    ``search.pod`` counts looks; probe bursts (``search.burst_timing.BurstTiming``'s phone quantiles) hear
    >= 1 or >= 2 bursts with the renewal model's steady-state probabilities outside long silences.
    A phone in a long silence when the search starts is taken as silent for the whole search (they
    last 30-90 min), so classes end weighted by their active share (:meth:`weights`)."""

    def __init__(self, sc):
        from .burst_timing import BurstTiming, _active_tables  # noqa: PLC0415
        from .pod import elicited_stream  # noqa: PLC0415

        self.bt = BurstTiming.from_scenario(sc)
        self.continuous = self.bt.continuous or elicited_stream(sc)
        self.slot_s = sc.channel.slot_s
        self.classes = 1 if self.continuous else len(self.bt.quantiles)
        if not self.continuous:
            # built once, here (seconds on a loaded machine), never in the daemon's event loop
            self._grid, self._cdf, _ = _active_tables(self.bt)
            self._weights = (1.0 - self.bt.silence_share()) / self.classes

    def weights(self) -> np.ndarray:
        return np.ones(1) if self.continuous else self._weights

    def probs(self, w_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """P(>= 1), P(>= 2) per window (n,) and class: (n, classes) each."""
        w = np.asarray(w_s, float).reshape(-1)
        if self.continuous:
            heard = (w >= self.slot_s).astype(float)[:, None]
            return heard, np.zeros_like(heard)
        a1 = np.column_stack([np.interp(w, self._grid, row, right=row[-1]) for row in self._cdf[0]])
        a2 = np.column_stack([np.interp(w, self._grid, row, right=row[-1]) for row in self._cdf[1]])
        return np.clip(a1, 0.0, 1.0), np.clip(np.minimum(a2, a1), 0.0, 1.0)


def window_probs(sc, w_s) -> tuple[np.ndarray, np.ndarray]:
    """Population P(at least one emission heard), P(at least two) of single windows ``w_s`` [s]."""
    win = _Windows(sc)
    a1, a2 = win.probs(w_s)
    wt = win.weights()
    return a1 @ wt, a2 @ wt


class _Hearing:
    """P(one burst is heard) against the 3-D distance, for the population (``search.pod``'s table
    averaged over phone types); continuous emission: heard wherever a slot is heard more often than
    not (the paper's gate)."""

    def __init__(self, sc):
        from .pod import _hearing, elicited_stream  # noqa: PLC0415

        h = _hearing(sc)
        self.d = np.asarray(h.d_grid, float)
        self.p = np.asarray(h.table, float) @ (np.asarray(h.weights, float) / np.sum(h.weights))
        self.reach_m = float(h.max_range_m)
        self.two_d = h.z_grid is not None  # air-to-ground: over (horizontal distance, height)
        if sc.emission.model == "continuous" or elicited_stream(sc):
            self.p = (self.p > 0.5).astype(float)
            if not self.two_d:
                inside = self.d[self.p > 0]
                self.reach_m = float(inside.max()) if len(inside) else 0.0

    def at(self, d3_m: np.ndarray, horizontal_m=None, height_m=None) -> np.ndarray:
        """P(a burst heard) at 3-D distances; an air-to-ground table is looked up by the horizontal
        distance and height instead (both required then)."""
        if self.two_d:
            from .pod_a2g import lookup  # noqa: PLC0415

            return lookup(self.p, horizontal_m, height_m)
        return np.interp(d3_m, self.d, self.p, right=0.0)


@dataclass(frozen=True)
class Grid:
    """Cell centres inside the area: ``xy_m`` (N, 2) [m], cell size ``cell_m``; ``shape`` and
    ``index`` (N, 2: row, column) place them on the raster of ``x0_m``/``y0_m`` corners."""

    xy_m: np.ndarray
    cell_m: float
    index: np.ndarray
    shape: tuple[int, int]
    x0_m: float
    y0_m: float

    @property
    def cell_area_m2(self) -> float:
        return self.cell_m * self.cell_m


def grid_for(sc) -> Grid:
    """The coverage grid of ``sc``: the cells of ``search.pod.grid_for`` inside the area."""
    from .pod import grid_for as pod_grid  # noqa: PLC0415

    g = pod_grid(sc)
    x, y, inside, cell = np.asarray(g.x_m, float), np.asarray(g.y_m, float), np.asarray(g.inside, bool), float(g.cell_m)
    ny, nx = tuple(g.shape) if g.shape else (1, len(x))
    idx = np.flatnonzero(inside)
    return Grid(np.column_stack([x[idx], y[idx]]), cell, np.column_stack([idx // nx, idx % nx]), (ny, nx),
                float(x.min() - cell / 2), float(y.min() - cell / 2))


SAMPLE_STEP_M = 15.0  # a flown segment is sampled at least this often (search.pod.TRACK_STEP_M)


class Coverage:
    """The incremental achieved-POD accumulator (see module docstring)."""

    def __init__(self, sc, grid: Grid | None = None):
        from ..heights import airborne_floor_m  # noqa: PLC0415

        self.sc = sc
        self.grid = grid if grid is not None else grid_for(sc)
        self._hearing = _Hearing(sc)
        # Over terrain (terrain.dem) a position's height is above the launch point, as telemetry
        # gives it; each cell's people stand on its own ground. Taken as height above every cell,
        # the mountains demo reported 0.604 of 0.731 km^2 "unsearched" under lanes it had flown
        # (vehicles 300-400 m above the launch point, 100 m above the slope).
        self._dem = sc.dem
        self._home_m = 0.0 if self._dem is None else self._dem.height_at(0.0, 0.0, clamp=True)
        self._cell_ground_m = (None if self._dem is None
                               else self._dem.height_xy(self.grid.xy_m, clamp=True) - self._home_m)
        self.min_alt_m = airborne_floor_m(sc)  # below it: taking off or landing
        n = len(self.grid.xy_m)
        self._win = _Windows(sc)
        self._p0 = np.ones((n, self._win.classes))  # P(no emission heard) over closed windows, per phone class
        self._p1 = np.zeros((n, self._win.classes))  # P(exactly one)
        self._open: dict[int, np.ndarray] = {}  # vehicle -> open window [s] per cell
        self._last: dict[int, tuple[float, np.ndarray]] = {}  # vehicle -> (t, xy) of its last survey position
        self._tracks: list[tuple[int, list, list]] = []  # flown pieces above the airborne floor: (vehicle, t, xyz)
        self._piece: dict[int, int] = {}  # vehicle -> index of its current piece
        self.flown_s = 0.0  # vehicle-seconds at survey altitude counted
        self.pass_rounds = 0  # replans that added passes (add_passes)
        self.passes_exhausted = False  # the last round found no vehicle with the energy for a lane
        self.last_passes = None  # passes.PassPlan of the last round
        self._pod_cache: tuple[float, np.ndarray] | None = None
        self._round_end_s: float | None = None  # when the last round's passes should have been flown (ETA)
        self.positions = 0

    # -- data in ---------------------------------------------------------------------------------
    def add_position(self, vehicle: int, t_s: float, xyz_m) -> None:
        """One flown position of ``vehicle`` at mission time ``t_s`` [s]; (east, north, height above
        the launch point) [m] -- over flat ground, above the people. Positions must come in time
        order per vehicle (older ones are ignored)."""
        x, y, z = (float(v) for v in np.asarray(xyz_m, float).reshape(3))
        v = int(vehicle)
        last = self._last.get(v)
        if last is not None and t_s <= last[0]:
            return
        # survey altitude is judged above the ground under the vehicle (a valley below the launch
        # point has z < 0 at survey height)
        above = z if self._dem is None or not (math.isfinite(x) and math.isfinite(y)) else \
            z - (self._dem.height_at(x, y, clamp=True) - self._home_m)
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)) or above < self.min_alt_m:
            self._close(v)
            self._last.pop(v, None)
            return
        here = np.array([x, y])
        self.positions += 1
        if last is None or t_s - last[0] > MAX_GAP_S:
            self._tracks.append((v, [], []))  # a new flown piece
            self._piece[v] = len(self._tracks) - 1
        piece = self._tracks[self._piece[v]]
        piece[1].append(float(t_s))
        piece[2].append((x, y, z))
        if last is not None and t_s - last[0] <= MAX_GAP_S:
            dt = t_s - last[0]
            seg = float(np.hypot(*(here - last[1])))
            k = max(1, math.ceil(seg / SAMPLE_STEP_M))
            mids = last[1] + np.outer((np.arange(k) + 0.5) / k, here - last[1])  # (k, 2)
            reach = self._hearing.reach_m
            centre = 0.5 * (last[1] + here)
            cand = np.flatnonzero(np.max(np.abs(self.grid.xy_m - centre), axis=1) <= reach + seg / 2)
            d = self.grid.xy_m[cand, None, :] - mids[None, :, :]
            dz = z if self._cell_ground_m is None else (z - self._cell_ground_m[cand])[:, None]
            d3 = np.sqrt(np.einsum("ijk,ijk->ij", d, d) + dz * dz)  # (n, k)
            w = np.zeros(len(self.grid.xy_m))
            near = np.zeros(len(self.grid.xy_m), bool)
            if self._hearing.two_d:  # air-to-ground: the flight's own height above each cell
                hxy = np.sqrt(np.einsum("ijk,ijk->ij", d, d))
                p = self._hearing.at(d3, hxy, np.broadcast_to(dz, hxy.shape))
            else:
                p = self._hearing.at(d3)
            w[cand] = p.mean(axis=1) * dt  # effective window gained [s]
            near[cand] = np.any(d3 <= reach, axis=1)
            self._extend(v, w, near)
            self.flown_s += dt
        elif last is not None:
            self._close(v)  # a gap: where it was meanwhile is unknown
        self._last[v] = (float(t_s), here)

    def add_telemetry(self, vehicle: int, t_s: float, lat_deg, lon_deg, rel_alt_m) -> None:
        """A telemetry position (WGS84, height above home); every MIN_STEP_S of mission time is kept."""
        last = self._last.get(int(vehicle))
        if last is not None and t_s - last[0] < MIN_STEP_S:
            return
        if lat_deg is None or lon_deg is None or rel_alt_m is None:
            return
        e, n = self.sc.frame.to_local(lat_deg, lon_deg)
        self.add_position(vehicle, t_s, (float(e), float(n), float(rel_alt_m)))

    def add_track(self, vehicle: int, t_s, xyz_m) -> None:
        """Many positions of one vehicle (times (N,), positions (N, 3)), in time order."""
        t = np.asarray(t_s, float).reshape(-1)
        xyz = np.asarray(xyz_m, float).reshape(-1, 3)
        for ti, p in zip(t, xyz):
            self.add_position(vehicle, float(ti), p)

    def _extend(self, v: int, dwell: np.ndarray, near: np.ndarray) -> None:
        open_ = self._open.setdefault(v, np.zeros(len(self.grid.xy_m)))
        left = ~near & (open_ > 0.0)
        if np.any(left):
            self._fold(np.flatnonzero(left), open_[left])
            open_[left] = 0.0
        open_ += dwell

    def _close(self, v: int) -> None:
        open_ = self._open.get(v)
        if open_ is None:
            return
        idx = np.flatnonzero(open_ > 0.0)
        if len(idx):
            self._fold(idx, open_[idx])
            open_[idx] = 0.0

    def _fold(self, idx: np.ndarray, w: np.ndarray, p0=None, p1=None) -> None:
        q1, q2 = self._win.probs(w)  # (n, classes)
        q0, q1only = 1.0 - q1, q1 - q2
        a0 = self._p0 if p0 is None else p0
        a1 = self._p1 if p1 is None else p1
        new0 = a0[idx] * q0
        new1 = a0[idx] * q1only + a1[idx] * q0
        a0[idx], a1[idx] = new0, new1

    def tracks(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """The flown pieces at survey altitude as ``search.pod.pod_from_tracks`` takes them."""
        return [(np.asarray(t, float), np.asarray(xyz, float).reshape(-1, 3)) for _, t, xyz in self._tracks if t]

    # -- what it says ----------------------------------------------------------------------------
    def _state(self) -> tuple[np.ndarray, np.ndarray]:
        """P(0), P(1) per cell with the open windows folded in as they stand."""
        p0, p1 = self._p0.copy(), self._p1.copy()
        for open_ in self._open.values():
            idx = np.flatnonzero(open_ > 0.0)
            if len(idx):
                self._fold(idx, open_[idx], p0, p1)
        return p0, p1

    def pod_recent(self, max_age_s: float = POD_CACHE_S) -> np.ndarray:
        """``pod(1)``, recomputed at most every ``max_age_s`` wall seconds (the policy asks every tick)."""
        now = time.monotonic()
        if self._pod_cache is None or now - self._pod_cache[0] > max_age_s:
            self._pod_cache = (now, self.pod(1))
        return self._pod_cache[1]

    def pod(self, k: int = 1) -> np.ndarray:
        """Achieved POD per cell (N,): P(at least ``k`` emissions heard), k = 1 or 2."""
        p0, p1 = self._state()
        per_class = 1.0 - p0 if k == 1 else 1.0 - p0 - p1
        return np.clip(per_class @ self._win.weights(), 0.0, 1.0)

    def overall(self, k: int = 1) -> float:
        """The area's POD: the mean over its cells (equal areas)."""
        pod = self.pod(k)
        return float(np.mean(pod)) if len(pod) else 0.0

    def summary(self, target: float | None = None, density_per_km2: float | None = None) -> "CoverageSummary":
        target = pod_target(self.sc) if target is None else float(target)
        density = people_density_per_km2(self.sc) if density_per_km2 is None else density_per_km2
        return summarize(self.grid, self.pod(1), self.pod(2), target, density, flown_s=self.flown_s)


@dataclass(frozen=True)
class CoverageSummary:
    """The claims a team acts on (areas in m², POD in 0-1)."""

    grid: Grid
    pod1: np.ndarray  # per cell
    pod2: np.ndarray
    target: float
    area_m2: float
    overall1: float
    overall2: float
    unsearched_m2: float  # no vehicle came within hearing
    below_target_m2: float  # POD < target (includes the unsearched)
    expected_missed: float | None  # people expected in the area but not heard (needs a density)
    density_per_km2: float | None
    flown_s: float = 0.0
    # why the passes over the cells below the target ended ('' when none were wanted or planned)
    passes_end: str = ""

    @property
    def nothing_flown(self) -> bool:
        return not np.any(self.pod1 > UNSEARCHED_POD)

    def unsearched_where(self) -> str:
        """Where the unsearched cells are: their bounding box in local metres ('' if none)."""
        idx = self.pod1 <= UNSEARCHED_POD
        if not np.any(idx):
            return ""
        xy, h = self.grid.xy_m[idx], self.grid.cell_m / 2
        (x0, y0), (x1, y1) = xy.min(axis=0) - h, xy.max(axis=0) + h
        return f"east {x0:.0f} to {x1:.0f} m, north {y0:.0f} to {y1:.0f} m of the launch point"

    def sentence(self) -> str:
        """One or two sentences: POD reached, what was not searched, people expected missed."""
        if self.nothing_flown:
            return ("Nothing flew over the search area at survey altitude: none of its "
                    f"{self.area_m2 / 1e6:.2f} km² was searched (POD 0).")
        text = (f"Achieved probability of detection (at least one emission heard): {self.overall1:.2f} over the "
                f"area ({self.overall2:.2f} for two); {self.below_target_m2 / 1e6:.3f} km² of "
                f"{self.area_m2 / 1e6:.3f} km² below the target {self.target:.2f}.")
        if self.unsearched_m2 > 0:
            text += (f" Unsearched (no vehicle within hearing): {self.unsearched_m2 / 1e6:.3f} km², "
                     f"{self.unsearched_where()}.")
        if self.expected_missed is not None:
            text += (f" Expected people missed at {self.density_per_km2:g} per km²: "
                     f"{self.expected_missed:.1f}.")
        return text

    def to_dict(self) -> dict:
        return {"pod_target": self.target, "area_m2": round(self.area_m2, 1), "pod_overall": round(self.overall1, 4),
                "pod2_overall": round(self.overall2, 4), "unsearched_m2": round(self.unsearched_m2, 1),
                "below_target_m2": round(self.below_target_m2, 1),
                "expected_missed": None if self.expected_missed is None else round(self.expected_missed, 3),
                "density_per_km2": self.density_per_km2, "cell_m": self.grid.cell_m}

    def pod_at(self, xy_m) -> float:
        """POD (one emission) of the cell holding ``xy_m``; NaN outside the grid."""
        x, y = (float(v) for v in xy_m)
        if not (math.isfinite(x) and math.isfinite(y)):
            return math.nan
        d = np.max(np.abs(self.grid.xy_m - (x, y)), axis=1)
        i = int(np.argmin(d)) if len(d) else -1
        return float(self.pod1[i]) if i >= 0 and d[i] <= self.grid.cell_m / 2 + 1e-6 else math.nan

    def cells_geojson_features(self, frame) -> list[dict]:
        """One Polygon feature per cell (``"kind": "pod_cell"``, properties pod, pod2, below_target,
        unsearched), in WGS84."""
        h = self.grid.cell_m / 2
        feats = []
        for (x, y), p1, p2 in zip(self.grid.xy_m, self.pod1, self.pod2):
            ring = np.array([[x - h, y - h], [x + h, y - h], [x + h, y + h], [x - h, y + h], [x - h, y - h]])
            ll = frame.to_wgs84_latlon(ring)
            feats.append({"type": "Feature",
                          "geometry": {"type": "Polygon",
                                       "coordinates": [[[round(float(lo), 7), round(float(la), 7)] for la, lo in ll]]},
                          "properties": {"kind": "pod_cell", "pod": round(float(p1), 4), "pod2": round(float(p2), 4),
                                         "below_target": bool(p1 < self.target),
                                         "unsearched": bool(p1 <= UNSEARCHED_POD),
                                         "east_m": round(float(x), 1), "north_m": round(float(y), 1)}})
        return feats

    def cells_json(self) -> dict:
        """Compact form for the live map: cell size and [east, north, pod] per cell."""
        return {"cell_m": self.grid.cell_m, "target": self.target,
                "cells": [[round(float(x), 1), round(float(y), 1), round(float(p), 3)]
                          for (x, y), p in zip(self.grid.xy_m, self.pod1)],
                **{k: v for k, v in self.to_dict().items() if k != "cell_m"}}


def summarize(grid: Grid, pod1: np.ndarray, pod2: np.ndarray, target: float, density_per_km2: float | None,
              flown_s: float = 0.0) -> CoverageSummary:
    cell_a = grid.cell_area_m2
    n = len(pod1)
    area = n * cell_a
    missed = None
    if density_per_km2 is not None:
        missed = float(density_per_km2 * np.sum(1.0 - pod1) * cell_a / 1e6)
    return CoverageSummary(grid, pod1, pod2, float(target), area, float(np.mean(pod1)) if n else 0.0,
                           float(np.mean(pod2)) if n else 0.0, float(np.sum(pod1 <= UNSEARCHED_POD) * cell_a),
                           float(np.sum(pod1 < target) * cell_a), missed, density_per_km2, flown_s)


def final_summary(cov: Coverage, target: float | None = None) -> CoverageSummary:
    """The claims of a finished search: ``search.pod.pod_from_tracks`` over the flown tracks (the
    stricter model: long silences shared between passes), on the same cells; the accumulator's own
    figures when that module is missing."""
    target = pod_target(cov.sc) if target is None else float(target)
    density = people_density_per_km2(cov.sc)
    from .pod import grid_for as pod_grid, pod_from_tracks  # noqa: PLC0415

    tracks = cov.tracks()
    g = pod_from_tracks(cov.sc, tracks, pod_grid(cov.sc)) if tracks else None
    if g is None:
        out = summarize(cov.grid, np.zeros(len(cov.grid.xy_m)), np.zeros(len(cov.grid.xy_m)), target, density,
                        cov.flown_s)
    else:
        inside = np.asarray(g.inside, bool)
        out = summarize(cov.grid, np.asarray(g.pod1)[inside], np.asarray(g.pod2)[inside], target, density,
                        cov.flown_s)
    return replace(out, passes_end=passes_end(cov))


def passes_end(cov: Coverage) -> str:
    """Why no more passes were flown over the cells below the target, as a clause ('' when no
    round of passes ended for a reason: none wanted, or the search ended otherwise)."""
    if cov.passes_exhausted:
        return "no other vehicle had the energy to take it over"
    if MAX_PASS_ROUNDS <= 0:
        return "the search allows no extra passes"
    if cov.pass_rounds >= MAX_PASS_ROUNDS:
        return f"the {MAX_PASS_ROUNDS} rounds of extra passes a search allows were flown"
    return ""


def add_stored(cov: Coverage, store_path) -> int:
    """Feed ``cov`` the telemetry a store kept (a restarted daemon: what was flown before the
    restart stays searched); the number of rows read."""
    import sqlite3  # noqa: PLC0415

    conn = sqlite3.connect(f"file:{store_path}?mode=ro", uri=True)
    try:
        rows = conn.execute("SELECT t_s, vehicle, lat_deg, lon_deg, alt_m FROM telemetry "
                            "WHERE lat_deg IS NOT NULL AND t_s IS NOT NULL ORDER BY vehicle, t_s").fetchall()
    except sqlite3.OperationalError:  # no telemetry table yet
        rows = []
    finally:
        conn.close()
    for t, v, lat, lon, alt in rows:
        cov.add_telemetry(int(v), float(t), lat, lon, alt)
    return len(rows)


def coverage_from_store(sc, rows) -> Coverage:
    """The coverage of a finished (or resumed) search from its stored telemetry rows
    (``service.store.TelemetryRow``-like: t_s, vehicle, lat_deg, lon_deg, alt_m)."""
    cov = Coverage(sc)
    by_v: dict[int, list] = {}
    for r in rows:
        by_v.setdefault(int(r.vehicle), []).append(r)
    frame = sc.frame
    for v, rs in by_v.items():
        rs = [r for r in rs if r.lat_deg is not None and r.lon_deg is not None and r.alt_m is not None]
        rs.sort(key=lambda r: r.t_s)
        if not rs:
            continue
        en = frame.to_local_xy(np.array([[r.lat_deg, r.lon_deg] for r in rs], float))
        z = np.array([r.alt_m for r in rs], float)
        cov.add_track(v, [r.t_s for r in rs], np.column_stack([en, z]))
    return cov


def dumps_summary(summary: CoverageSummary) -> str:
    return json.dumps(summary.to_dict(), indent=1) + "\n"


def attach(sc, policy=None) -> Coverage:
    """A new accumulator for a search of ``sc``, given to ``policy`` (its ``coverage``: the passes
    over cells below the POD target are planned from it) when there is one."""
    cov = Coverage(sc)
    if policy is not None:
        try:
            policy.coverage = cov
        except AttributeError:
            pass
    return cov


# -- the adaptive loop: another pass over the cells below the target (search/passes.py) ---------------
MAX_PASS_ROUNDS = 3  # replans that may add passes; a pass at the scan's speed raises a burst world's
# POD by a fraction each time, and the energy left, not the target, would otherwise end the search


def scan_coverage(sc, step_s: float = 0.5) -> Coverage:
    """The accumulator fed ``sc``'s planned scan as if flown exactly (every vehicle from the launch
    point along its lanes at the fleet speed and altitude): the yardstick of what a scan reaches."""
    from .pod_plan import scan_for  # noqa: PLC0415

    flown, plan = scan_for(sc)
    cov = Coverage(sc)
    speed = flown.fleet.speed_m_s
    for vs in plan.vehicles:
        pts = np.vstack([np.zeros((1, 2)), vs.waypoints_xy_m])
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
        t = np.arange(0.0, cum[-1] / speed + step_s, step_s)
        s = np.minimum(t * speed, cum[-1])
        xy = np.column_stack([np.interp(s, cum, pts[:, 0]), np.interp(s, cum, pts[:, 1])])
        z = np.full(len(t), sc.fleet.altitude_m)
        if sc.dem is not None:  # the planned scan follows the ground as the climb and descent limits let it
            from ..terrain_missions import TerrainRefused, route_profile  # noqa: PLC0415

            home = sc.dem.height_at(0.0, 0.0, clamp=True)
            try:
                prof = route_profile(flown, np.vstack([pts, np.zeros((1, 2))]), speed_m_s=speed)
                z = np.interp(s, prof.s, prof.z) - home
            except TerrainRefused:  # a leg off the DEM: the mission planner says so; here, its aim
                z = z + sc.dem.height_xy(xy, clamp=True) - home
        cov.add_track(vs.index + 1, t, np.column_stack([xy, z]))
    return cov


def main(argv=None) -> int:
    """``python -m uavloc_gcs.search.coverage SCENARIO...``: the live and the final POD of each
    scenario's scan flown as planned."""
    import sys  # noqa: PLC0415

    from ..scenario import load_scenario  # noqa: PLC0415

    for path in (sys.argv[1:] if argv is None else argv):
        sc = load_scenario(path)
        cov = scan_coverage(sc)
        final = final_summary(cov)
        print(f"{path}: {len(cov.grid.xy_m)} cells; scan POD live {cov.overall(1):.2f} (two: {cov.overall(2):.2f}), "
              f"final {final.overall1:.2f} (two: {final.overall2:.2f}); below target {final.target:.2f}: "
              f"{final.below_target_m2 / 1e6:.3f} of {final.area_m2 / 1e6:.3f} km²")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
