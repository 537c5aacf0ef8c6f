"""The scan planned for a probability of detection (``uavloc plan --pod P``, ``[search] pod_target``).

A scan is a set of parallel lanes over every vehicle's share of the area (``scan.plan_scan``),
flown ``passes`` times (each pass the previous one reversed, so the vehicle never flies back empty)
at one speed. For every lane spacing and speed among a few candidates this module finds the fewest
passes whose POD (``search.pod.pod_from_tracks`` on the tracks the missions fly, on a coarse grid)
reaches the target for one and for two heard bursts, within every vehicle's usable energy (Zeng's
power curve, ``energy.RotorcraftPower``: 10-18 m/s fly a metre cheapest, ~10 m/s stays aloft
longest). The option with the shortest search time wins; the chosen plan's POD is then computed
on the fine grid (``search.pod.grid_for``), the one the map and the GeoJSON show.

Lane spacings are multiples of the *burst hearing radius*: the ground distance at which a burst
of a typical phone is heard with probability 1/2 (``pod.p_burst_heard``), which with many frames
per burst is well beyond the per-frame ``fleet.comm_range_m``. The lanes are laid out in the scan's
``single`` mode (outer lanes half a spacing inside the edge) with that radius as R.

When no option reaches the target, the plan with the highest POD for two heard bursts (then one)
is the fleet's best; :class:`PodPlan` says by how much it falls short, and the CLI refuses it
unless told to fly the best it can.

Sorties (issue 38): with ``fleet.batteries`` > 1 every vehicle flies its passes as a sequence of
sorties, one pack each, home and a swap of ``fleet.battery_swap_s`` in between (``uavloc_gcs.sorties``:
each sortie goes as far as its pack allows while keeping the way home). An option then fits when no
vehicle needs more packs than it has and, with ``[search] time_limit_s``, the search (flights and
swaps) ends within it; its time counts the swaps, its POD the sorties' tracks (the time on the
ground hears nothing). With one pack the plans are the same as before sorties, bit for bit.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .. import sorties as sortie_mod
from ..energy import route_cost
from ..errors import InfeasibleError
from . import pod

SPACING_FACTORS = (0.75, 1.0, 1.5, 2.0)  # lane spacings, in burst hearing radii
PLAN_SPEEDS_M_S = (10.0, 12.0, 15.0, 18.0)  # candidate speeds (plus the scenario's own)
MAX_PASSES = 24  # per pack
SEARCH_CELLS = 160  # the coarse grid of the option search has about this many cells
ADVICE_MAX_PACKS = 12  # when the scenario's packs fall short: how many would do, up to this many
# After the choice on the coarse grid, the fewest passes (down to TRIM_SPAN fewer) at which the fine
# grid still meets the target (the coarse grid errs both ways; it only ever added passes before).
# False: the coarse choice stands.
TRIM_ON_FINE_GRID = True
TRIM_SPAN = 6


@dataclass(frozen=True)
class PodOption:
    """One scan: lane spacing, speed, passes, and what it achieves and costs."""

    spacing_m: float
    speed_m_s: float
    passes: int
    pod1: float
    pod2: float
    time_s: float  # makespan: the longest vehicle's flight (with sorties: flights and swaps)
    energy_j: float  # the most any vehicle uses (with sorties: over all its packs)
    packs: int = 1  # the most packs any vehicle uses (one per sortie)

    def meets(self, target: float) -> bool:
        return self.pod1 >= target and self.pod2 >= target


@dataclass
class PodPlan:
    target: float
    scenario: object  # the scenario as planned (fleet.speed_m_s = the chosen speed)
    plan: object  # scan.ScanPlan with the passes in every vehicle's waypoints
    grid: pod.PodGrid  # fine-grid POD of the chosen plan
    chosen: PodOption
    options: list  # the trade-off: the best option per speed
    met: bool
    burst_radius_m: float
    sorties: tuple = ()  # sorties.SortiePlan per planned vehicle (one sortie each with one pack)
    advice: "PodPlan | None" = None  # out of reach: the plan with the packs that would reach it (plan_for_pod advise)

    def shortfall_sentence(self) -> str:
        c, f = self.chosen, self.scenario.fleet
        short = self.target - min(c.pod1, c.pod2)
        packs = "energy" if f.batteries == 1 else f"{f.batteries} packs each"
        limit = self.scenario.search.time_limit_s
        within = "" if limit is None else f" within the search's {sortie_mod.minutes(limit)} (search.time_limit_s)"
        text = (f"The {f.vehicles} vehicles' {packs} cannot reach POD {self.target:g}{within}: the best scan "
                f"({self.lanes_text()} at {c.speed_m_s:g} m/s, {c.passes} pass{'es' if c.passes > 1 else ''}, "
                f"{_mmss(c.time_s)}{self._packs_words(c)}) reaches POD {c.pod1:.2f} for one heard burst and "
                f"{c.pod2:.2f} for two, {short:.2f} short of the target")
        a = self.advice
        if a is not None and a.met:
            text += (f"; {a.statement()}, so set fleet.batteries = {a.chosen.packs}")
        elif a is not None:
            text += f"; not even {a.scenario.fleet.batteries} packs per vehicle would reach it"
        return text + " (use --best-effort to plan it anyway)."

    def lanes_text(self) -> str:
        """The chosen scan's lanes as flown: "lanes 128 m apart" (the option's spacing is the widest
        allowed; the area's width is split into whole lanes, so the flown ones are as close or closer,
        as preview.png says)."""
        flown = float(getattr(self.plan, "lane_spacing_m", self.chosen.spacing_m))
        text = f"lanes {flown:.0f} m apart"
        if abs(flown - self.chosen.spacing_m) >= 1.0:
            text += f" (at most {self.chosen.spacing_m:.0f} m, narrowed to whole lanes across the area)"
        return text

    def _packs_words(self, o: "PodOption") -> str:
        if self.scenario.fleet.batteries == 1:
            return ""
        return f" with {o.packs} pack{'s' if o.packs > 1 else ''} per vehicle"

    def statement(self) -> str:
        """What the chosen scan achieves in a sentence: "POD 0.95 in 41 min with 3 packs per vehicle
        (2-min swaps)" (the POD the fine grid gives; with one pack, without the packs)."""
        c, f = self.chosen, self.scenario.fleet
        reached = min(self.grid.overall(1), self.grid.overall(2))
        # short of the target: rounded down, so that 0.946 is not called the 0.95 it missed
        head = f"POD {self.target:g}" if self.met else f"POD {math.floor(reached * 100 + 1e-9) / 100:.2f}"
        if f.batteries == 1:
            return f"{head} in {sortie_mod.minutes(c.time_s)} with one pack per vehicle"
        swap = f.battery_swap_s
        swaps = f"{swap / 60:g}-min swaps" if swap % 60 == 0 else f"{swap:g}-s swaps"
        return (f"{head} in {sortie_mod.minutes(c.time_s)} with {c.packs} pack{'s' if c.packs > 1 else ''} "
                f"per vehicle ({swaps})")

    def table(self) -> str:
        from ..render.terminal import format_table

        usable = self.scenario.usable_energy_j
        rows = []
        for o in self.options:
            mark = "*" if (o.spacing_m, o.speed_m_s) == (self.chosen.spacing_m, self.chosen.speed_m_s) else ""
            row = [mark, f"{o.spacing_m:.0f}", f"{o.speed_m_s:g}", o.passes, f"{o.pod1:.2f}", f"{o.pod2:.2f}",
                   _mmss(o.time_s), f"{o.energy_j / 1000:.1f}", f"{100 * o.energy_j / usable:.0f}"]
            rows.append(row + ([o.packs] if self.scenario.fleet.batteries > 1 else []))
        packs = self.scenario.fleet.batteries > 1
        return format_table(["", "max spacing m", "speed m/s", "passes", "POD1", "POD2", "time m:s", "kJ/vehicle",
                             "% of a pack" if packs else "% budget"] + (["packs"] if packs else []), rows)

    def write(self, out_dir) -> list[str]:
        """pod.geojson (the fine grid, pod1/pod2 per cell) and pod.png in ``out_dir``; the names written."""
        import json
        from pathlib import Path

        from ..atomicfile import atomic_write_text
        from ..render.maps import save_figure

        out = Path(out_dir)
        fc = self.grid.to_geojson(self.scenario)
        c = self.chosen
        fc["properties"].update({"target": self.target, "met": bool(self.met), "lane_spacing_m": round(c.spacing_m, 1),
                                 "speed_m_s": c.speed_m_s, "passes": c.passes, "search_time_s": round(c.time_s, 1)})
        if self.scenario.fleet.batteries > 1:
            fc["properties"].update({"packs": c.packs, "battery_swap_s": self.scenario.fleet.battery_swap_s,
                                     "sorties": [sp.packs for sp in self.sorties]})
        atomic_write_text(out / "pod.geojson", json.dumps(fc, separators=(",", ":")) + "\n")
        fig = pod_figure(self.scenario, self.grid, self.plan, target=self.target,
                         title=f"Planned POD {self.grid.overall(1):.2f} / {self.grid.overall(2):.2f} "
                               f"(target {self.target:g}): {self.scenario.name}")
        save_figure(fig, out / "pod.png")
        return ["pod.geojson", "pod.png"]

    def summary(self) -> str:
        c = self.chosen
        head = (f"Planned for POD {self.target:g} (one and two heard bursts) under the scenario's emission model "
                f"({self.scenario.emission.model}; a burst is heard with probability 1/2 out to "
                f"{self.burst_radius_m:.0f} m on the ground).")
        rows = "Best scan per speed (POD on a coarse grid; * = chosen, the shortest search that reaches the target"
        rows += ")" if self.met else "; none does, * = the highest POD)"
        tail = (f"Chosen: {self.lanes_text()} at {c.speed_m_s:g} m/s, {c.passes} pass{'es' if c.passes > 1 else ''}: "
                f"POD {self.grid.overall(1):.3f} for one heard burst and {self.grid.overall(2):.3f} for two over the "
                f"area ({int(self.grid.inside.sum())} cells of {self.grid.cell_m:.0f} m), search time {_mmss(c.time_s)}.")
        lines = [head, rows, self.table(), tail]
        if self.scenario.fleet.batteries > 1:
            lines.append(f"Sorties: {sortie_mod.packs_sentence(self.sorties, self.scenario.fleet.battery_swap_s)}; "
                         f"{self.statement()}.")
        return "\n".join(lines)


def _mmss(t: float) -> str:
    m, s = divmod(int(round(t)), 60)
    return f"{m}:{s:02d}"


def burst_radius_m(sc) -> float:
    """Ground distance at which a typical phone's burst is heard with probability 1/2."""
    h = np.arange(0.0, 3000.0, 1.0)
    p = pod.p_burst_heard(sc, h, sc.fleet.altitude_m, tx_offset_db=None)
    below = np.flatnonzero(p < 0.5)
    return float(h[below[0]]) if len(below) else float(h[-1])


def _layout(sc, spacing_m: float, radius_m: float):
    """The one-pass scan with lanes ``spacing_m`` apart (single coverage, R = max(radius, spacing / 2))."""
    from ..scan import plan_scan

    r = max(radius_m, spacing_m / 2.0 + 1.0)
    lay = sc.replace(fleet={"comm_range_m": math.hypot(r, sc.fleet.altitude_m), "energy_budget_j": 1e12},
                     scan={"coverage": "single", "lane_spacing_m": spacing_m})
    return plan_scan(lay)


def _repeat(sc, v, n: int, speed_m_s: float):
    wps = v.waypoints_xy_m
    seq = [wps] + [(wps[::-1] if k % 2 else wps)[1:] for k in range(1, n)]
    all_wps = np.vstack(seq)
    route = np.vstack([np.zeros((1, 2)), all_wps, np.zeros((1, 2))])
    rc = route_cost(route, speed_m_s, sc.power_model)
    return dataclasses.replace(v, waypoints_xy_m=all_wps, lanes_xy_m=v.lanes_xy_m * n,
                               length_m=rc.length_m, duration_s=rc.duration_s, energy_j=rc.energy_j)


def with_passes(sc, one_pass, passes: int, speed_m_s: float):
    """``one_pass`` flown ``passes`` times (alternately reversed) at ``speed_m_s`` by the vehicle
    whose flight is longest; every other vehicle flies as many passes of its own share as end by
    then (a share near the launch point fits more). A ScanPlan. With ``fleet.batteries`` > 1 the
    flights are timed as sorties (swaps included) and the others' passes also stay within the packs."""
    return _Fleet(sc, speed_m_s).passes(one_pass, passes).plan


def tracks_of(plan, speed_m_s: float, altitude_m: float) -> list:
    """The (times, positions) every vehicle flies along ``plan`` from t = 0 at constant speed."""
    out = []
    for v in plan.vehicles:
        r = v.route_xy_m()
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(r, axis=0), axis=1))])
        out.append((s / speed_m_s, np.column_stack([r, np.full(len(r), altitude_m)])))
    return out


@dataclass(frozen=True)
class _Flight:
    """One vehicle's repeated share: its time (swaps included), energy, packs, and whether it fits."""

    scan: object  # scan.VehicleScan with the passes in its waypoints
    sorties: object  # sorties.SortiePlan, or None with one pack
    duration_s: float
    energy_j: float
    packs: int
    fits: bool


@dataclass(frozen=True)
class _Passes:
    """A whole fleet's scan of some passes: the plan, each vehicle's sorties, and its figures."""

    plan: object  # scan.ScanPlan
    sorties: tuple  # sorties.SortiePlan per vehicle (empty with one pack)
    time_s: float
    energy_j: float  # the most any vehicle uses
    packs: int  # the most packs any vehicle uses
    fits: bool

    def tracks(self, speed_m_s: float, altitude_m: float) -> list:
        if self.sorties:
            return sortie_mod.sortie_tracks(self.sorties, speed_m_s, altitude_m)
        return tracks_of(self.plan, speed_m_s, altitude_m)


class _Fleet:
    """Flights of repeated shares at one speed within a scenario's packs, energy share and time
    limit (memoized: the option search asks for the same ones often). With one pack and no time
    limit this is the planner of before sorties, to the bit."""

    def __init__(self, sc, speed_m_s: float, energy_share: float = 1.0):
        self.sc = sc
        self.speed = float(speed_m_s)
        self.packs = int(sc.fleet.batteries)
        self.usable = sc.usable_energy_j * float(energy_share)  # one pack's (with one pack: the scan's cap)
        self.limit = getattr(sc.search, "time_limit_s", None)
        self.max_passes = MAX_PASSES * self.packs
        self._memo: dict = {}

    def flight(self, v, n: int) -> _Flight:
        key = (v.index, n)
        hit = self._memo.get(key)
        if hit is not None:
            return hit
        rep = _repeat(self.sc, v, n, self.speed)
        if self.packs == 1:
            out = _Flight(rep, None, rep.duration_s, rep.energy_j, 1, rep.energy_j <= self.usable)
        else:
            try:
                sp = sortie_mod.vehicle_sorties(self.sc, rep.waypoints_xy_m, speed_m_s=self.speed,
                                                max_sorties=self.packs + 1)
                fits = sp.complete and sp.packs <= self.packs and sp.energy_j <= self.usable * self.packs + 1e-6
                out = _Flight(rep, sp, sp.duration_s if sp.complete else math.inf, sp.energy_j, sp.packs, fits)
            except InfeasibleError:  # not even one pack makes progress: never fits
                out = _Flight(rep, None, math.inf, math.inf, self.packs + 1, False)
        if self.limit is not None and out.duration_s > self.limit:
            out = dataclasses.replace(out, fits=False)
        self._memo[key] = out
        return out

    def passes(self, one_pass, passes: int) -> _Passes:
        base = [self.flight(v, passes) for v in one_pass.vehicles]
        end = max((b.duration_s for b in base), default=0.0) + 1e-6
        flights = []
        for v, b in zip(one_pass.vehicles, base):
            if self.packs == 1:
                n = passes
                while n < 4 * MAX_PASSES:
                    more = self.flight(v, n + 1)
                    if more.duration_s > end:
                        break
                    b, n = more, n + 1
            else:  # the most passes that end by then within the packs (monotone in n: doubling, then bisection)
                ok = lambda k: (f := self.flight(v, k)).duration_s <= end and (f.fits or not b.fits)  # noqa: E731
                hi, step = passes, 1
                while hi + step <= 4 * self.max_passes and ok(hi + step):
                    hi, step = hi + step, 2 * step
                lo_bad = min(hi + step, 4 * self.max_passes + 1)
                while lo_bad - hi > 1:
                    mid = (hi + lo_bad) // 2
                    hi, lo_bad = (mid, lo_bad) if ok(mid) else (hi, mid)
                b = self.flight(v, hi)
            flights.append(b)
        plan = dataclasses.replace(one_pass, vehicles=tuple(f.scan for f in flights))
        sorties = tuple(f.sorties for f in flights) if self.packs > 1 else ()
        fits = all(f.fits for f in flights)
        time_s = max((f.duration_s for f in flights), default=0.0) if self.packs > 1 else plan.makespan_s
        return _Passes(plan, sorties, time_s, max((f.energy_j for f in flights), default=0.0),
                       max((f.packs for f in flights), default=0), fits)

    def most_passes(self, one_pass) -> int:
        """The most passes whose flights fit (0 when not one does); they fit fewer as passes grow."""
        if self.packs == 1 and self.limit is None:  # as before sorties: one pass at a time
            n_max = 0
            for n in range(1, MAX_PASSES + 1):
                if max(ve.energy_j for ve in self.passes(one_pass, n).plan.vehicles) > self.usable:
                    break
                n_max = n
            return n_max
        if not self.passes(one_pass, 1).fits:
            return 0
        good, step = 1, 1
        while good + step <= self.max_passes and self.passes(one_pass, good + step).fits:
            good, step = good + step, 2 * step
        bad = min(good + step, self.max_passes + 1)
        while bad - good > 1:
            mid = (good + bad) // 2
            good, bad = (mid, bad) if self.passes(one_pass, mid).fits else (good, mid)
        return good


def _evaluate(fleet: _Fleet, one_pass, spacing, passes, grid) -> PodOption:
    run = fleet.passes(one_pass, passes)
    sc = fleet.sc
    g = pod.pod_from_tracks(sc, run.tracks(fleet.speed, sc.fleet.altitude_m), grid, coarse=True)
    return PodOption(float(spacing), float(fleet.speed), int(passes), g.overall(1), g.overall(2), run.time_s,
                     run.energy_j, run.packs)


def plan_for_pod(sc, target: float, *, best_effort: bool = False, speeds=None, spacing_factors=None,
                 energy_share: float = 1.0, max_speed_m_s: float | None = None, advise: bool = False,
                 fine: bool = True) -> PodPlan:
    """Choose lane spacing, speed and passes for ``target`` (see the module docstring). Raises
    InfeasibleError (one sentence) when the target is out of reach and ``best_effort`` is False, or
    when not even one pass fits in the energy. ``energy_share``: the part of every vehicle's usable
    energy the scan may use (the rest is kept for the looks after it). ``max_speed_m_s``: the
    fastest the vehicles will fly (their WPNAV_SPEED / MPC_XY_VEL_MAX, read by the daemon): only
    speeds up to it are candidates, and it is one. ``advise``: when the target is out of reach of
    the scenario's packs, plan it again with one pack more at a time, up to ADVICE_MAX_PACKS per
    vehicle (the result's ``advice``: the first that reaches it, on the coarse grid), so that the
    sentence says how many packs and how long it would take. ``fine``: False keeps the coarse grid's
    figures for the chosen scan (the advice's)."""
    if not 0.0 < target < 1.0:
        raise InfeasibleError(f"--pod must be a probability between 0 and 1 (exclusive), got {target:g}")
    radius = burst_radius_m(sc)
    usable = sc.usable_energy_j * float(energy_share)
    speeds = sorted(set(PLAN_SPEEDS_M_S if speeds is None else speeds) | {float(sc.fleet.speed_m_s)})
    if max_speed_m_s is not None:
        speeds = sorted({v for v in speeds if v <= max_speed_m_s} | {float(max_speed_m_s)})
    speeds = [v for v in speeds if v > sc.people.max_speed_m_s]
    area = abs(pod.grid_for(sc, 10.0).inside.sum()) * 100.0
    coarse = pod.grid_for(sc, max(20.0, math.sqrt(area / SEARCH_CELLS)))
    per_speed: dict[float, PodOption] = {}
    layouts = {}
    fleets = {v: None for v in speeds}
    for f in (SPACING_FACTORS if spacing_factors is None else spacing_factors):
        spacing = f * radius
        one = _layout(sc, spacing, radius)
        layouts[round(spacing, 6)] = one
        for v in speeds:
            fleet = _Fleet(sc, v, energy_share)
            n_max = fleet.most_passes(one)  # energy (packs, time) grows with n: the most passes that fit
            if n_max == 0:
                continue
            top = _evaluate(fleet, one, spacing, n_max, coarse)
            best = top
            if top.meets(target):
                lo, hi = 0, n_max  # hi meets, lo does not (0 passes hear nothing)
                while hi - lo > 1:
                    mid = (lo + hi) // 2
                    o = _evaluate(fleet, one, spacing, mid, coarse)
                    if o.meets(target):
                        hi, best = mid, o
                    else:
                        lo = mid
            cur = per_speed.get(v)
            if cur is None or _better(best, cur, target):
                per_speed[v] = best
                fleets[v] = fleet
    if not per_speed:
        f = sc.fleet
        within = "" if sc.search.time_limit_s is None else f" within {sortie_mod.minutes(sc.search.time_limit_s)} (search.time_limit_s)"
        packs = f"a vehicle's usable {usable / 1000:.1f} kJ" if f.batteries == 1 else f"{f.batteries} packs of {usable / 1000:.1f} kJ"
        raise InfeasibleError(f"not one pass of any scan fits in {packs}{within}; add vehicles (fleet.vehicles = "
                              f"{f.vehicles}) or raise fleet.energy_budget_j")
    options = [per_speed[v] for v in sorted(per_speed)]
    chosen = min(options, key=lambda o: _rank(o, target))
    one = layouts[round(chosen.spacing_m, 6)]
    fleet = fleets[chosen.speed_m_s]
    # the fine grid: add passes while the coarse figure was optimistic and energy allows
    final_grid = pod.grid_for(sc) if fine else coarse
    while True:
        run = fleet.passes(one, chosen.passes)
        grid = pod.pod_from_tracks(sc, run.tracks(chosen.speed_m_s, sc.fleet.altitude_m), final_grid,
                                   coarse=not fine)
        met = grid.overall(1) >= target and grid.overall(2) >= target
        nxt = fleet.passes(one, chosen.passes + 1)
        if met or not chosen.meets(target) or not nxt.fits:
            break
        chosen = dataclasses.replace(chosen, passes=chosen.passes + 1, time_s=nxt.time_s, energy_j=nxt.energy_j,
                                     packs=nxt.packs)
    if fine and met and TRIM_ON_FINE_GRID:
        chosen, run, grid = _trimmed(sc, fleet, one, chosen, final_grid, target, run, grid)
    chosen = dataclasses.replace(chosen, pod1=grid.overall(1), pod2=grid.overall(2))
    planned = sc.replace(fleet={"speed_m_s": chosen.speed_m_s})
    result = PodPlan(target, planned, run.plan, grid, chosen, options, met, radius, sorties=run.sorties)
    if not met and advise:
        result.advice = _advice(sc, target, min(result.chosen.pod1, result.chosen.pod2), speeds=speeds,
                                spacing_factors=spacing_factors, energy_share=energy_share,
                                max_speed_m_s=max_speed_m_s)
    if not met and not best_effort:
        raise InfeasibleError(result.shortfall_sentence())
    return result


def _trimmed(sc, fleet: _Fleet, one, chosen: PodOption, final_grid, target: float, run, grid):
    """The fewest passes, down to TRIM_SPAN fewer, at which the fine grid still meets ``target``:
    the coarse grid can also be pessimistic (the field world, 3 packs: the coarse choice of 33
    passes met 0.97 / 0.96 on the fine grid where 0.95 was asked; 31 met it 3.6 minutes sooner).
    Every count of the span is tried: the POD is not monotone in the passes (how they fall into
    sorties matters: 31 passes met the target where 32 did not). (chosen, run, grid) of the count
    kept."""
    best = chosen.passes
    for n in range(chosen.passes - 1, max(chosen.passes - TRIM_SPAN, 1) - 1, -1):
        r = fleet.passes(one, n)
        g = pod.pod_from_tracks(sc, r.tracks(chosen.speed_m_s, sc.fleet.altitude_m), final_grid)
        if g.overall(1) >= target and g.overall(2) >= target:
            best, run, grid = n, r, g
    chosen = dataclasses.replace(chosen, passes=best, time_s=run.time_s, energy_j=run.energy_j, packs=run.packs)
    return chosen, run, grid


def _advice(sc, target: float, reached: float, **kw) -> "PodPlan | None":
    """The plan with the fewest packs (one more at a time, up to ADVICE_MAX_PACKS) that reaches
    ``target``: searched on the coarse grid, and the one that reaches it there planned again on the
    fine grid, so that the sentence names the plan ``uavloc plan`` then makes with those packs (the
    coarse grid said 67 min for 3 packs in the field world where the plan is 63); else the last
    tried (not met), or None when more packs stop helping (the time limit binds) or nothing fits."""
    last = None
    for packs in range(sc.fleet.batteries + 1, ADVICE_MAX_PACKS + 1):
        more = sc.replace(fleet={"batteries": packs})
        try:
            last = plan_for_pod(more, target, best_effort=True, fine=False, **kw)
            if last.met:
                last = plan_for_pod(more, target, best_effort=True, **kw)
        except InfeasibleError:
            return None
        now = min(last.chosen.pod1, last.chosen.pod2)
        if last.met or now <= reached + 1e-3:  # reached, or another pack adds nothing (the time limit)
            return last
        reached = now
    return last


# A search that flies the scan planned for its POD target (``search.pod_target``) keeps this part of
# every vehicle's usable energy for the looks at the people the scan hears: a best-effort scan
# would otherwise spend it all on passes and nobody heard could be looked at
SEARCH_SCAN_SHARE = 0.6
_SCANS: dict = {}


def scan_for(sc, max_speed_m_s: float | None = None):
    """``(scenario as flown, scan.ScanPlan)`` of a search: the scan planned for ``search.pod_target``
    (best effort within SEARCH_SCAN_SHARE of the energy, at most ``max_speed_m_s``; the scenario's
    ``fleet.speed_m_s`` is the chosen speed) when the scenario gives one, else ``[scan]``'s layout
    at the scenario's speed. The same scenario gets the same plan (cached: the daemon, the
    simulator and the coverage all ask)."""
    from ..scan import plan_scan

    target = getattr(getattr(sc, "search", None), "pod_target", None)
    if target is None:
        return sc, plan_scan(sc)
    key = _key(sc, max_speed_m_s)
    hit = _SCANS.get(key)
    if hit is None:
        pp = plan_for_pod(sc, float(target), best_effort=True, energy_share=SEARCH_SCAN_SHARE,
                          max_speed_m_s=max_speed_m_s)
        hit = _SCANS[key] = (pp.scenario, pp.plan, pp)
        if len(_SCANS) > 16:
            _SCANS.pop(next(iter(_SCANS)))
    return hit[0], hit[1]


def scan_pod_plan(sc, max_speed_m_s: float | None = None) -> "PodPlan | None":
    """The PodPlan :func:`scan_for` flies for ``sc`` (None without a POD target)."""
    if getattr(getattr(sc, "search", None), "pod_target", None) is None:
        return None
    scan_for(sc, max_speed_m_s)
    return _SCANS[_key(sc, max_speed_m_s)][2]


def _key(sc, max_speed_m_s: float | None = None) -> str:
    # the plan depends on the area, fleet, radio and emission, not on the simulated world's seed
    sim = getattr(sc, "simulation", None)
    return (f"{SEARCH_SCAN_SHARE}:{max_speed_m_s}:"
            + repr(sc.replace(simulation={"seed": 0}) if sim is not None and hasattr(sim, "seed") else sc))


def _rank(o: PodOption, target: float):
    """Meeting the target first, then the shortest time (least energy); else the highest POD."""
    if o.meets(target):
        return (0, o.time_s, o.energy_j)
    return (1, -o.pod2, -o.pod1, o.time_s)


def _better(a: PodOption, b: PodOption, target: float) -> bool:
    return _rank(a, target) < _rank(b, target)


def pod_figure(sc, grid: pod.PodGrid, plan=None, *, title: str | None = None, target: float | None = None):
    """Map of a POD grid: the POD for one heard burst per cell (colour), the POD for two as contours
    (at the target when given), the routes thin on top."""
    from matplotlib import colormaps

    from ..render import maps

    ny, nx = grid.shape
    area = sc.area_xy_m()
    routes = [v.route_xy_m() for v in plan.vehicles] if plan is not None else []
    everything = np.vstack([area, np.zeros((1, 2))] + routes)
    sub = (f"colour: P(at least one probe burst heard), lines: P(at least two); {sc.emission.model} emission\n"
           f"area POD {grid.overall(1):.3f} / {grid.overall(2):.3f}, cells {grid.cell_m:.0f} m; "
           f"{maps.origin_caption(*sc.launch_latlon_deg)}")
    fig, ax = maps.new_map(title or f"Probability of detection: {sc.name}", subtitle=sub,
                           extent_m=tuple(np.ptp(everything, axis=0)))
    x = grid.x_m.reshape(ny, nx)
    y = grid.y_m.reshape(ny, nx)
    inside = grid.inside.reshape(ny, nx)
    p1 = np.ma.masked_where(~inside, grid.pod1.reshape(ny, nx))
    p2 = np.ma.masked_where(~inside, grid.pod2.reshape(ny, nx))
    mesh = ax.pcolormesh(x, y, p1, cmap=colormaps["viridis"], vmin=0.0, vmax=1.0, shading="nearest", zorder=1)
    fig.colorbar(mesh, ax=ax, location="bottom", shrink=0.5, aspect=40, label="POD, at least one burst heard")
    inner = grid.pod2[grid.inside]
    levels = sorted({round(float(v), 3) for v in ([target] if target else []) + [0.25, 0.5, 0.75, 0.9]
                     if len(inner) and inner.min() < v < inner.max()})
    if nx > 1 and ny > 1 and levels:
        cs = ax.contour(x, y, p2, levels=levels, colors="white", linewidths=1.0, zorder=2)
        ax.clabel(cs, fmt=lambda v: f"POD2 {v:g}", fontsize=7)
    maps.draw_area(ax, area, label="search area")
    for r, col in zip(routes, maps.vehicle_colors(max(len(routes), 1))):
        ax.plot(r[:, 0], r[:, 1], color=col, linewidth=0.6, alpha=0.7, zorder=3)
    maps.draw_launch(ax)
    maps.add_scale_bar(ax)
    maps.add_north_arrow(ax)
    maps.add_legend(ax)
    ax.margins(0.04)
    return fig

