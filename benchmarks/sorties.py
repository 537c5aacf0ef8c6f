"""``uavloc bench sorties``: the POD the scan planner reaches with 1, 2, 3 ... packs per vehicle.

Issue 38 item 4 (the planning half): for a scenario (default ``examples/field.toml``: the paper's
area and fleet in the field world) and a target (default 0.95, for one and for two heard bursts),
plan the scan (``search.pod_plan.plan_for_pod``, best effort, all of every pack's usable energy)
with each number of packs and swaps of ``--swap-s`` seconds, and print what it reaches on the fine
grid and how long it takes from the first take-off to the last landing, swaps included. The model
is ``search/pod.py``'s (steady-state phones with long silences; docs/science/pod.md), the flight
Zeng's power at cruise speed with take-off, landing and turns not counted.

The anchor is the phones' own floor: the listening a search needs to reach the target even if
every burst of every phone were heard from the first second (``BurstTiming.window_for``). Phones
are silent a share of the time in silences of half an hour and more, so no fleet, however large,
reaches the target sooner; each row's time is printed as a ratio to it.
"""

from __future__ import annotations

import argparse
import time

from uavloc_gcs.cli._inputs import number


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scenario", default="field", metavar="FILE.toml",
                        help="scenario file or a shipped one by name (default: field)")
    parser.add_argument("--packs", default="1,2,3", help="pack counts per vehicle, comma-separated (default 1,2,3)")
    parser.add_argument("--swap-s", type=number(float, min=0, max=3600, unit="s"), default=120.0,
                        help="time on the ground per swap [s] (default 120)")
    parser.add_argument("--target", type=number(float, above=0, max=0.999), default=0.95,
                        help="POD to plan for, one and two heard bursts (default 0.95)")
    parser.add_argument("--time-limit", type=number(float, above=0, unit="s"), metavar="S",
                        help="the search's time limit [s] (search.time_limit_s; default the scenario's)")


def _packs(text: str) -> list[int]:
    from uavloc_gcs.errors import ConfigError

    try:
        packs = [int(p) for p in text.split(",") if p.strip()]
    except ValueError:
        raise ConfigError(f"--packs must be whole numbers separated by commas, got {text!r}") from None
    if not packs or any(p < 1 or p > 50 for p in packs):
        raise ConfigError(f"--packs must list 1-50 packs per vehicle, got {text!r}")
    return packs


def main(args: argparse.Namespace) -> int:
    from uavloc_gcs.render.terminal import format_table
    from uavloc_gcs.scenario import load_scenario
    from uavloc_gcs.search.burst_timing import BurstTiming
    from uavloc_gcs.search.pod_plan import plan_for_pod
    from uavloc_gcs.sorties import _mmss

    sc = load_scenario(args.scenario)
    if args.time_limit is not None:
        sc = sc.replace(search={"time_limit_s": args.time_limit})
    f = sc.fleet
    limit = sc.search.time_limit_s
    print(f"uavloc bench sorties: {sc.name}, {f.vehicles} vehicles, {sc.usable_energy_j / 1000:.1f} kJ usable per pack, "
          f"{args.swap_s:g} s per swap, target POD {args.target:g} (one and two heard bursts)"
          + (f", search time limit {limit:g} s" if limit is not None else ""), flush=True)
    bt = BurstTiming.from_scenario(sc)
    floor_s = max(bt.window_for(1, args.target), bt.window_for(2, args.target))
    print(f"  the phones' floor: POD {args.target:g} needs {_mmss(floor_s)} of listening even with every burst of "
          f"every phone heard from the first second (silent {float(bt.silence_share().mean()):.0%} of the time in "
          f"long silences; search/burst_timing.py)", flush=True)
    rows, lines = [], []
    for packs in _packs(args.packs):
        t0 = time.perf_counter()
        pp = plan_for_pod(sc.replace(fleet={"batteries": packs, "battery_swap_s": args.swap_s}), args.target,
                          best_effort=True)
        c = pp.chosen
        rows.append([packs, "yes" if pp.met else "no", f"{pp.grid.overall(1):.3f}", f"{pp.grid.overall(2):.3f}",
                     _mmss(c.time_s), f"{c.spacing_m:.0f}", f"{c.speed_m_s:g}", c.passes, c.packs,
                     f"{c.energy_j / 1000:.1f}", f"{c.time_s / floor_s:.2f}" if pp.met else "-",
                     f"{time.perf_counter() - t0:.0f}"])
        lines.append(f"{packs} pack{'s' if packs > 1 else ''}: {pp.statement()}"
                     + ("" if pp.met else f" (target {args.target:g} not reached)"))
        print(f"  {lines[-1]}", flush=True)
    print()
    print(format_table(["packs", "met", "POD1", "POD2", "time m:s", "lanes m", "speed m/s", "passes", "packs used",
                        "kJ/vehicle", "/ floor", "planned in s"], rows))
    print("POD on the fine grid of search/pod.py; time from the first take-off to the last landing, swaps included "
          "(take-off, landing and turns not counted); / floor: that time over the phones' floor (rows that reach "
          "the target).")
    return 0
