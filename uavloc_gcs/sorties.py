"""Sorties (issue 38): a vehicle's flight cut into one sortie per battery pack, home in between.

A rescue team does not fly one charge and stop: the vehicle lands, the pack is swapped in a minute
or two (``fleet.battery_swap_s``) and it flies again while packs last (``fleet.batteries``). Here a
vehicle's work is a pass-through path ``P`` (its scan lanes, without the launch point). It is flown
as sorties: the first leaves home, flies ``P`` from its start as far as the pack allows *while
keeping the energy to fly straight home*, and returns; after the swap the next flies straight from
home to the point where the previous one left ``P``, and so on until ``P`` is flown.

The cut is exact. Along ``P`` at arc length ``u`` (point ``X(u)``), a sortie that joined at ``u0``
can go on while ``|X(u0) - home| + (u - u0) + |X(u) - home| <= B`` (``B`` the pack's usable energy
in metres of flight). ``g(u) = u + |X(u) - home|`` never decreases (the distance home changes no
faster than the vehicle flies), so the last feasible point is found by one search over the
vertices and, on the segment after the last feasible vertex, the root of a quadratic.

Energy is Zeng's level-flight power at constant cruise speed, as in ``scan.py`` and
``search/pod_plan.py`` (``energy.RotorcraftPower.energy_per_m_j``): take-off, landing, climbs and
turns are not counted (``battery_swap_s`` is the time from landing to the next take-off). Pure
functions of arrays and scenarios; the missions are built by ``sortie_missions``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .energy import ZENG_2019, RotorcraftPower
from .errors import InfeasibleError

MIN_PROGRESS_M = 1.0  # a sortie that flies less of its path than this makes no progress
_DEDUPE_M = 0.01


@dataclass(frozen=True)
class Sortie:
    """One pack's flight: home -> ``waypoints_xy_m`` (pass-through) -> home, in local metres."""

    waypoints_xy_m: np.ndarray  # (k, 2): where it joins the path, the path's vertices, where it leaves
    path_from_m: float  # arc length along the vehicle's path where this sortie joins it ...
    path_to_m: float  # ... and where it leaves it
    length_m: float  # home -> waypoints -> home
    duration_s: float  # in the air, at cruise speed
    energy_j: float  # of one pack


@dataclass(frozen=True)
class SortiePlan:
    """A vehicle's sorties in flight order. ``complete``: the whole path is flown (False when the
    split stopped at ``max_sorties``); ``swap_s``: time on the ground between two sorties."""

    sorties: tuple[Sortie, ...]
    swap_s: float
    path_m: float  # length of the whole path
    complete: bool = True

    @property
    def packs(self) -> int:
        """Packs used: one per sortie."""
        return len(self.sorties)

    @property
    def swaps(self) -> int:
        return max(len(self.sorties) - 1, 0)

    @property
    def duration_s(self) -> float:
        """From the first take-off to the last landing: flights plus the swaps between them."""
        return float(sum(s.duration_s for s in self.sorties) + self.swaps * self.swap_s)

    @property
    def energy_j(self) -> float:
        return float(sum(s.energy_j for s in self.sorties))

    @property
    def flown_m(self) -> float:
        """Length of the path flown (all of it when ``complete``)."""
        return float(self.sorties[-1].path_to_m) if self.sorties else 0.0

    def start_times_s(self) -> np.ndarray:
        """Take-off time of every sortie from the first take-off [s]."""
        d = np.array([s.duration_s for s in self.sorties])
        return np.concatenate([[0.0], np.cumsum(d[:-1] + self.swap_s)]) if len(d) else np.zeros(0)


def split_path(path_xy_m, *, speed_m_s: float, pack_j: float, first_pack_j: float | None = None,
               swap_s: float = 0.0, power: RotorcraftPower = ZENG_2019, home_xy_m=(0.0, 0.0),
               max_sorties: int | None = None, name: str = "the vehicle") -> SortiePlan:
    """Cut ``path_xy_m`` ((N, 2) pass-through points) into sorties of one pack each (see the module
    docstring). ``pack_j``: usable energy of a fresh pack [J]; ``first_pack_j``: of the pack in the
    vehicle now (default a fresh one). ``max_sorties``: stop after that many (``complete`` False).

    Raises InfeasibleError (one sentence naming ``name``) when a fresh pack cannot fly from home to
    where the path is left off and back with any of the path flown, or the first pack cannot reach
    the path's start and return."""
    pts = np.asarray(path_xy_m, dtype=float).reshape(-1, 2)
    home = np.asarray(home_xy_m, dtype=float).reshape(2)
    if not (speed_m_s > 0 and pack_j >= 0 and swap_s >= 0):
        raise ValueError(f"speed {speed_m_s} m/s, pack {pack_j} J and swap {swap_s} s must be positive")
    if len(pts) == 0:
        return SortiePlan((), float(swap_s), 0.0)
    e_per_m = float(power.energy_per_m_j(speed_m_s))
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    d_home = np.linalg.norm(pts - home, axis=1)
    g = np.maximum.accumulate(arc + d_home)  # nondecreasing in exact arithmetic; keep it so numerically
    total = float(arc[-1])
    sorties: list[Sortie] = []
    u0 = 0.0
    budget_m = (pack_j if first_pack_j is None else first_pack_j) / e_per_m
    while True:
        x0 = _at(pts, arc, seg, u0)
        back0 = float(np.linalg.norm(x0 - home))
        reachable = 2.0 * back0 <= budget_m * (1 + 1e-12) + 1e-9  # there and straight back
        u1 = _last_feasible(pts, arc, seg, g, home, budget_m - back0 + u0, u0) if reachable else u0
        if not reachable or (u1 < total - 1e-9 and u1 - u0 < MIN_PROGRESS_M):
            which = "its first pack" if not sorties and first_pack_j is not None else "a fresh pack"
            left = max(budget_m - 2.0 * back0, 0.0)
            raise InfeasibleError(
                f"{name} cannot fly its path beyond {u0:.0f} of {total:.0f} m: {which} ({budget_m * e_per_m / 1000:.1f} kJ) "
                f"flies {budget_m:.0f} m at {speed_m_s:g} m/s, and the way from home to where the path goes on "
                f"({back0:.0f} m away) and back leaves {left:.0f} m of path per pack; raise fleet.energy_budget_j "
                "or add vehicles (fleet.vehicles)")
        x1 = _at(pts, arc, seg, u1)
        inner = pts[(arc > u0 + _DEDUPE_M) & (arc < u1 - _DEDUPE_M)]
        wps = _dedupe(np.vstack([x0[None], inner, x1[None]]))
        # the route as flown (the dedupe only drops centimetres: never longer than the cut allowed)
        route = np.vstack([home[None], wps, home[None]])
        length = float(np.sum(np.linalg.norm(np.diff(route, axis=0), axis=1)))
        sorties.append(Sortie(wps, float(u0), float(u1), float(length), float(length / speed_m_s),
                              float(length * e_per_m)))
        if u1 >= total - 1e-9:
            return SortiePlan(tuple(sorties), float(swap_s), total)
        if max_sorties is not None and len(sorties) >= max_sorties:
            return SortiePlan(tuple(sorties), float(swap_s), total, complete=False)
        u0 = u1
        budget_m = pack_j / e_per_m


def _at(pts: np.ndarray, arc: np.ndarray, seg: np.ndarray, u: float) -> np.ndarray:
    """The point at arc length ``u`` along the path."""
    if len(pts) == 1 or u <= 0.0:
        return pts[0].copy()
    i = min(int(np.searchsorted(arc, u, side="right")) - 1, len(seg) - 1)
    t = 0.0 if seg[i] <= 0 else min(max((u - arc[i]) / seg[i], 0.0), 1.0)
    return pts[i] + t * (pts[i + 1] - pts[i])


def _last_feasible(pts, arc, seg, g, home, G: float, u0: float) -> float:
    """The largest arc length ``u >= u0`` with ``u + |X(u) - home| <= G`` (``u0`` itself when even
    it is not; the caller reports that)."""
    i = int(np.searchsorted(g, G * (1 + 1e-12) + 1e-9, side="right")) - 1  # last vertex within the budget
    if i >= len(pts) - 1:
        return float(arc[-1])
    if i < 0:
        return u0
    # on segment i: |a + t d| = c - t with a = X_i - home, c = G - arc_i  =>  t = (c^2 - |a|^2) / (2 (a.d + c))
    a = pts[i] - home
    d = (pts[i + 1] - pts[i]) / seg[i] if seg[i] > 0 else np.zeros(2)
    c = G - arc[i]
    den = 2.0 * (float(a @ d) + c)
    t = float(seg[i]) if den <= 1e-12 else (c * c - float(a @ a)) / den
    u = float(arc[i] + min(max(t, 0.0), float(seg[i])))
    return max(u, u0)


def _dedupe(xy: np.ndarray) -> np.ndarray:
    keep = [0] + [k for k in range(1, len(xy)) if np.linalg.norm(xy[k] - xy[k - 1]) > _DEDUPE_M]
    return xy[keep]


# ---------------------------------------------------------------------------------------------
# Scans flown in sorties


def vehicle_sorties(sc, waypoints_xy_m, *, speed_m_s: float | None = None, first_pack_j: float | None = None,
                    max_sorties: int | None = None, name: str = "the vehicle") -> SortiePlan:
    """``waypoints_xy_m`` flown with ``sc``'s packs (usable energy ``sc.usable_energy_j`` each) at
    ``speed_m_s`` (default ``fleet.speed_m_s``), swaps of ``fleet.battery_swap_s``."""
    return split_path(waypoints_xy_m, speed_m_s=float(speed_m_s or sc.fleet.speed_m_s), pack_j=sc.usable_energy_j,
                      first_pack_j=first_pack_j, swap_s=sc.fleet.battery_swap_s, power=sc.power_model,
                      max_sorties=max_sorties, name=name)


def scan_sorties(sc, plan, *, speed_m_s: float | None = None) -> tuple[SortiePlan, ...]:
    """Every planned vehicle's scan (``scan.ScanPlan``) as sorties; InfeasibleError (naming the
    vehicle) when one needs more packs than ``fleet.batteries``."""
    out = []
    f = sc.fleet
    for v in plan.vehicles:
        name = f"vehicle uav{v.index + 1}"
        sp = vehicle_sorties(sc, v.waypoints_xy_m, speed_m_s=speed_m_s, max_sorties=f.batteries + 1, name=name)
        if sp.packs > f.batteries:
            full = vehicle_sorties(sc, v.waypoints_xy_m, speed_m_s=speed_m_s, name=name)
            raise InfeasibleError(
                f"{name} needs {full.packs} packs for its {full.path_m / 1000:.2f} km scan "
                f"({sc.usable_energy_j / 1000:.1f} kJ usable per pack: {f.energy_budget_j / 1000:.1f} kJ minus "
                f"{f.energy_reserve_fraction:.0%} reserve) but has {f.batteries} (fleet.batteries); add packs or "
                f"vehicles (fleet.vehicles = {f.vehicles})")
        out.append(sp)
    return tuple(out)


def search_time_s(sorties) -> float:
    """The last vehicle's last landing after the first take-off, swaps included [s]."""
    return max((sp.duration_s for sp in sorties), default=0.0)


def sortie_tracks(sorties, speed_m_s: float, altitude_m: float) -> list:
    """``(times, positions)`` of every sortie of every vehicle (``search.pod.pod_from_tracks``'s
    input): each sortie a track of its own, timed from the first take-off, so the time on the
    ground between two sorties hears nothing."""
    out = []
    home = np.zeros((1, 2))
    for sp in sorties:
        for s, t0 in zip(sp.sorties, sp.start_times_s()):
            r = np.vstack([home, s.waypoints_xy_m, home])
            cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(r, axis=0), axis=1))])
            out.append((t0 + cum / speed_m_s, np.column_stack([r, np.full(len(r), altitude_m)])))
    return out


def sortie_missions(sc, plan, sorties=None) -> list[list]:
    """One MAVLink mission per sortie per planned vehicle (``[[uav1's sortie 1, ...], ...]``), each
    as ``scan.scan_missions`` makes a scan's mission: take-off, speed, pass-through waypoints, RTL.
    The geofence is the one of every sortie's route (the area, or a hull around the area and the
    routes); with a scenario geofence the legs to and from the path get its corners, as the scan's
    own legs do (the few metres round a concave fence's corner are not in the sortie's energy)."""
    from . import geofence
    from .scan import scan_missions

    sorties = scan_sorties(sc, plan) if sorties is None else sorties
    fence = geofence.for_scenario(sc)
    parts = []
    for v, sp in zip(plan.vehicles, sorties):
        mine = []
        for s in sp.sorties:
            wps = s.waypoints_xy_m
            if fence is not None and len(wps):
                wps = _dedupe(fence.clip_route(wps, start_xy_m=np.zeros(2), end_xy_m=np.zeros(2)))
            mine.append(dataclasses.replace(v, waypoints_xy_m=wps))
        parts.append(mine)
    flat = dataclasses.replace(plan, vehicles=tuple(p for mine in parts for p in mine))
    missions = iter(scan_missions(sc, flat))
    return [[next(missions) for _ in mine] for mine in parts]


def packs_sentence(sorties, swap_s: float) -> str:
    """e.g. "3 packs per vehicle (uav1 3, uav2 3, uav3 2, uav4 3), 2-min swaps"."""
    packs = [sp.packs for sp in sorties]
    top = max(packs, default=0)
    swap = f"{swap_s / 60:g}-min swaps" if swap_s % 60 == 0 else f"{swap_s:g}-s swaps"
    if top <= 1:
        return "1 pack per vehicle"
    every = ", ".join(f"uav{i + 1} {p}" for i, p in enumerate(packs))
    return f"{top} packs per vehicle ({every}), {swap}"


def _mmss(t_s: float) -> str:
    m, s = divmod(int(round(t_s)), 60)
    return f"{m}:{s:02d}"


def minutes(t_s: float) -> str:
    """A search time for a sentence: "41 min" (whole minutes, rounded up: a promise, not an average)."""
    return f"{int(math.ceil(t_s / 60.0 - 1e-9))} min"
