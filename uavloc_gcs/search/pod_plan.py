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
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..energy import route_cost
from ..errors import InfeasibleError
from . import pod

SPACING_FACTORS = (0.75, 1.0, 1.5, 2.0)  # lane spacings, in burst hearing radii
PLAN_SPEEDS_M_S = (10.0, 12.0, 15.0, 18.0)  # candidate speeds (plus the scenario's own)
MAX_PASSES = 24
SEARCH_CELLS = 160  # the coarse grid of the option search has about this many cells


@dataclass(frozen=True)
class PodOption:
    """One scan: lane spacing, speed, passes, and what it achieves and costs."""

    spacing_m: float
    speed_m_s: float
    passes: int
    pod1: float
    pod2: float
    time_s: float  # makespan: the longest vehicle's flight
    energy_j: float  # the most any vehicle uses

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

    def shortfall_sentence(self) -> str:
        c, f = self.chosen, self.scenario.fleet
        short = self.target - min(c.pod1, c.pod2)
        return (f"The {f.vehicles} vehicles' energy cannot reach POD {self.target:g}: the best scan "
                f"({c.spacing_m:.0f} m lanes at {c.speed_m_s:g} m/s, {c.passes} pass{'es' if c.passes > 1 else ''}, "
                f"{_mmss(c.time_s)}) reaches POD {c.pod1:.2f} for one heard burst and {c.pod2:.2f} for two, "
                f"{short:.2f} short of the target (use --best-effort to plan it anyway).")

    def table(self) -> str:
        from ..render.terminal import format_table

        usable = self.scenario.usable_energy_j
        rows = []
        for o in self.options:
            mark = "*" if (o.spacing_m, o.speed_m_s) == (self.chosen.spacing_m, self.chosen.speed_m_s) else ""
            rows.append([mark, f"{o.spacing_m:.0f}", f"{o.speed_m_s:g}", o.passes, f"{o.pod1:.2f}", f"{o.pod2:.2f}",
                         _mmss(o.time_s), f"{o.energy_j / 1000:.1f}", f"{100 * o.energy_j / usable:.0f}"])
        return format_table(["", "spacing m", "speed m/s", "passes", "POD1", "POD2", "time m:s", "kJ/vehicle",
                             "% budget"], rows)

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
        tail = (f"Chosen: {c.spacing_m:.0f} m lanes at {c.speed_m_s:g} m/s, {c.passes} pass{'es' if c.passes > 1 else ''}: "
                f"POD {self.grid.overall(1):.3f} for one heard burst and {self.grid.overall(2):.3f} for two over the "
                f"area ({int(self.grid.inside.sum())} cells of {self.grid.cell_m:.0f} m), search time {_mmss(c.time_s)}.")
        return "\n".join([head, rows, self.table(), tail])


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
    then (a share near the launch point fits more). A ScanPlan."""
    base = [_repeat(sc, v, passes, speed_m_s) for v in one_pass.vehicles]
    end = max((v.duration_s for v in base), default=0.0) + 1e-6
    vehicles = []
    for v, b in zip(one_pass.vehicles, base):
        n = passes
        while n < 4 * MAX_PASSES:
            more = _repeat(sc, v, n + 1, speed_m_s)
            if more.duration_s > end:
                break
            b, n = more, n + 1
        vehicles.append(b)
    return dataclasses.replace(one_pass, vehicles=tuple(vehicles))


def tracks_of(plan, speed_m_s: float, altitude_m: float) -> list:
    """The (times, positions) every vehicle flies along ``plan`` from t = 0 at constant speed."""
    out = []
    for v in plan.vehicles:
        r = v.route_xy_m()
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(r, axis=0), axis=1))])
        out.append((s / speed_m_s, np.column_stack([r, np.full(len(r), altitude_m)])))
    return out


def _evaluate(sc, one_pass, spacing, speed, passes, grid) -> PodOption:
    plan = with_passes(sc, one_pass, passes, speed)
    g = pod.pod_from_tracks(sc, tracks_of(plan, speed, sc.fleet.altitude_m), grid, coarse=True)
    return PodOption(float(spacing), float(speed), int(passes), g.overall(1), g.overall(2), plan.makespan_s,
                     max(v.energy_j for v in plan.vehicles))


def plan_for_pod(sc, target: float, *, best_effort: bool = False, speeds=None, spacing_factors=None,
                 energy_share: float = 1.0, max_speed_m_s: float | None = None) -> PodPlan:
    """Choose lane spacing, speed and passes for ``target`` (see the module docstring). Raises
    InfeasibleError (one sentence) when the target is out of reach and ``best_effort`` is False, or
    when not even one pass fits in the energy. ``energy_share``: the part of every vehicle's usable
    energy the scan may use (the rest is kept for the looks after it). ``max_speed_m_s``: the
    fastest the vehicles will fly (their WPNAV_SPEED / MPC_XY_VEL_MAX, read by the daemon): only
    speeds up to it are candidates, and it is one."""
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
    for f in (SPACING_FACTORS if spacing_factors is None else spacing_factors):
        spacing = f * radius
        one = _layout(sc, spacing, radius)
        layouts[round(spacing, 6)] = one
        for v in speeds:
            n_max = 0
            for n in range(1, MAX_PASSES + 1):  # energy grows with n: the most passes that fit
                if max(ve.energy_j for ve in with_passes(sc, one, n, v).vehicles) > usable:
                    break
                n_max = n
            if n_max == 0:
                continue
            top = _evaluate(sc, one, spacing, v, n_max, coarse)
            best = top
            if top.meets(target):
                lo, hi = 0, n_max  # hi meets, lo does not (0 passes hear nothing)
                while hi - lo > 1:
                    mid = (lo + hi) // 2
                    o = _evaluate(sc, one, spacing, v, mid, coarse)
                    if o.meets(target):
                        hi, best = mid, o
                    else:
                        lo = mid
            cur = per_speed.get(v)
            if cur is None or _better(best, cur, target):
                per_speed[v] = best
    if not per_speed:
        raise InfeasibleError(f"not one pass of any scan fits in a vehicle's usable {usable / 1000:.1f} kJ; add "
                              f"vehicles (fleet.vehicles = {sc.fleet.vehicles}) or raise fleet.energy_budget_j")
    options = [per_speed[v] for v in sorted(per_speed)]
    chosen = min(options, key=lambda o: _rank(o, target))
    one = layouts[round(chosen.spacing_m, 6)]
    # the fine grid: add passes while the coarse figure was optimistic and energy allows
    fine = pod.grid_for(sc)
    while True:
        plan = with_passes(sc, one, chosen.passes, chosen.speed_m_s)
        grid = pod.pod_from_tracks(sc, tracks_of(plan, chosen.speed_m_s, sc.fleet.altitude_m), fine)
        met = grid.overall(1) >= target and grid.overall(2) >= target
        nxt = with_passes(sc, one, chosen.passes + 1, chosen.speed_m_s)
        if met or not chosen.meets(target) or max(v.energy_j for v in nxt.vehicles) > usable:
            break
        chosen = dataclasses.replace(chosen, passes=chosen.passes + 1, time_s=nxt.makespan_s,
                                     energy_j=max(v.energy_j for v in nxt.vehicles))
    chosen = dataclasses.replace(chosen, pod1=grid.overall(1), pod2=grid.overall(2))
    planned = sc.replace(fleet={"speed_m_s": chosen.speed_m_s})
    result = PodPlan(target, planned, plan, grid, chosen, options, met, radius)
    if not met and not best_effort:
        raise InfeasibleError(result.shortfall_sentence())
    return result


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

