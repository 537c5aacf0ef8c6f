"""``uavloc plan SCENARIO.toml --out DIR``: scan missions per vehicle, GeoJSON, KML and a picture."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from ._inputs import number

log = logging.getLogger(__name__)

HELP = "plan the initial scan: .plan/.waypoints per vehicle, scan.geojson, scan.kml, preview.png"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("plan", help=HELP, description=HELP + ". Writes nothing if anything fails.")
    p.add_argument("scenario", metavar="SCENARIO.toml",
                   help="scenario file, or a shipped one by name: paper, small, polygon, field (see examples/)")
    p.add_argument("--out", metavar="DIR", default="plans", help="output directory (default: plans)")
    p.add_argument("--coverage", choices=["double", "single"],
                   help="override scan.coverage: 'double' (lanes <= R apart, every point heard from two "
                        "lanes; default) or 'single' (the paper's sqrt(2) R spacing)")
    p.add_argument("--lane-spacing", type=number(float, above=0, unit="m"), metavar="M",
                   help="override scan.lane_spacing_m (metres)")
    p.add_argument("--pod", type=number(float, above=0, max=0.999), metavar="P",
                   help="plan lane spacing, speed and passes for this probability of detection (one and two "
                        "heard bursts) under the scenario's emission model and energy (overrides "
                        "search.pod_target), over the scenario's packs (fleet.batteries: one mission per sortie); "
                        "writes pod.png and pod.geojson; exit 2 if out of reach, naming the packs that would reach it")
    p.add_argument("--best-effort", action="store_true",
                   help="with --pod: when the target is out of reach, plan the highest POD the energy allows")
    p.add_argument("--svg", action="store_true", help="also write preview.svg")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from mission_io import geojson, kml
    from mission_io import plan as plan_file
    from mission_io import waypoints as wpl_file

    from ..render.maps import save_figure
    from ..render.scan_plot import scan_figure
    from ..scan import plan_scan, scan_missions
    from ..scenario import load_scenario
    from ._inputs import blaming, fleet_note, override
    from ._output import atomic_output_dir, check_output_dir

    check_output_dir(args.out, "--out")  # before any work: a directory that cannot be written
    sc = load_scenario(args.scenario)
    if args.coverage:
        sc = override(sc, "--coverage", scan={"coverage": args.coverage})
    target = args.pod if args.pod is not None else sc.search.pod_target
    podplan = None
    if args.best_effort and target is None:
        from ..errors import ConfigError
        raise ConfigError("--best-effort applies only to a scan planned for a POD (--pod or search.pod_target)")
    if target is not None:  # the scan planned for a probability of detection (search/pod_plan.py)
        from ..errors import ConfigError
        from ..search.pod_plan import SEARCH_SCAN_SHARE, plan_for_pod
        if args.lane_spacing is not None or args.coverage:
            raise ConfigError("a scan planned for a POD chooses its own lanes: drop --lane-spacing and --coverage, "
                              "or plan without --pod / search.pod_target")
        # from the scenario key: the scan `uavloc daemon` flies, which keeps energy for the looks
        share = 1.0 if args.pod is not None else SEARCH_SCAN_SHARE
        # --pod: when the scenario's packs fall short, also say how many would do (planning it again
        # with one pack more at a time); the scenario key plans what the daemon flies, as it is
        podplan = plan_for_pod(sc, target, best_effort=args.best_effort, energy_share=share,
                               advise=args.pod is not None)
        sc, plan = podplan.scenario, podplan.plan
    elif args.lane_spacing is not None:
        sc = override(sc, "--lane-spacing", scan={"lane_spacing_m": args.lane_spacing})
        with blaming("--lane-spacing", "scan.lane_spacing_m"):
            plan = plan_scan(sc)
    else:
        plan = plan_scan(sc)
    from ..terrain_missions import terrain_safe  # over the DEM's ground when terrain.dem is given
    sorties = None
    if sc.fleet.batteries > 1:  # one mission per sortie (issue 38): uavK-sortieJ
        from ..sorties import scan_sorties, sortie_missions
        sorties = podplan.sorties if podplan is not None else scan_sorties(sc, plan)
        files = [(f"uav{v.index + 1}-sortie{j + 1}", terrain_safe(m, sc, name=f"uav{v.index + 1} sortie {j + 1}"))
                 for v, per in zip(plan.vehicles, sortie_missions(sc, plan, sorties)) for j, m in enumerate(per)]
        missions = [m for _, m in files]
        capacity_notes = []  # each sortie is a part of the vehicle's scan
    else:
        missions = scan_missions(sc, plan)
        missions = [terrain_safe(m, sc, name=f"uav{v.index + 1}") for m, v in zip(missions, plan.vehicles)]
        capacity_notes = _check_lengths(sc, plan, missions)
        files = [(f"uav{v.index + 1}", m) for v, m in zip(plan.vehicles, missions)]
    fc = geojson.scan_feature_collection(sc, plan)
    written = []
    with atomic_output_dir(args.out) as tmp:
        for stem, mission in files:
            plan_file.write(tmp / f"{stem}.plan", mission)
            wpl_file.write(tmp / f"{stem}.waypoints", mission)
            written += [f"{stem}.plan", f"{stem}.waypoints"]
        geojson.write(tmp / "scan.geojson", fc)
        kml.write(tmp / "scan.kml", kml.from_feature_collection(fc))
        fig = scan_figure(sc, plan)
        save_figure(fig, tmp / "preview.png")
        written += ["scan.geojson", "scan.kml", "preview.png"]
        if args.svg:
            save_figure(fig, tmp / "preview.svg")
            written.append("preview.svg")
        if podplan is not None:
            written += podplan.write(tmp)
    print(summary(sc, plan, missions) if sorties is None else sortie_summary(sc, plan, sorties, files))
    if podplan is not None:
        print("\n" + podplan.summary())
        if args.pod is None:
            print(f"As `uavloc daemon` flies it (search.pod_target): the scan uses at most {SEARCH_SCAN_SHARE:.0%} of "
                  f"each vehicle's usable energy and keeps the rest for the looks at the people it hears "
                  f"(--pod plans with all of it).")
        if not podplan.met:
            print("Best effort: " + podplan.shortfall_sentence().replace(" (use --best-effort to plan it anyway)", ""))
    if note := fleet_note(sc):
        print(note)
    for note in capacity_notes:
        print(note)
    from .. import geofence  # noqa: PLC0415

    print(geofence.describe(sc, plan))  # which fence the daemon's looks and passes stay inside
    print(f"\nWrote {len(written)} files to {Path(args.out)}/: {', '.join(written)}")
    stale = sorted(p.name for p in Path(args.out).glob("uav*.*")
                   if p.suffix in (".plan", ".waypoints") and p.name not in written)
    if stale:
        print(f"Note: {', '.join(stale)} in {Path(args.out)}/ are from an earlier run, not from this plan.")
    print(f"Look at them: uavloc preview {Path(args.out) / ((files[0][0] if files else 'uav1') + '.plan')}   (or open preview.png; "
          "scan.kml opens in Google Earth)")
    return 0


def _check_lengths(sc, plan, missions) -> list[str]:
    """Refuse a scan whose mission no vehicle of the fleet's autopilot could hold; the notes for
    missions that common boards refuse (link/mission_capacity.py)."""
    from ..errors import InfeasibleError
    from ..link.mission_capacity import many_note, too_long
    from ..mission import to_wire

    notes = []
    for v, m in zip(plan.vehicles, missions):
        n = len(to_wire(m, sc.fleet.autopilot))
        if reason := too_long(n, sc.fleet.autopilot):
            raise InfeasibleError(f"uav{v.index + 1}'s scan: {reason} (more vehicles or wider lanes)")
        if note := many_note(n, sc.fleet.autopilot):
            notes.append(f"Note: uav{v.index + 1}'s scan has {note}; check the vehicle's capacity before flying it.")
    return notes


def sortie_summary(sc, plan, sorties, files) -> str:
    """The text printed after planning a scan flown in sorties: one row per sortie of each vehicle."""
    from ..render.terminal import format_table
    from ..sorties import _mmss, packs_sentence, search_time_s

    f = sc.fleet
    usable = sc.usable_energy_j
    head = (f"Scan plan '{sc.name}' ({sc.source}): {f.vehicles} {'ArduPilot' if f.autopilot == 'ardupilot' else 'PX4'} "
            f"vehicles at {f.altitude_m:g} m and {f.speed_m_s:g} m/s, launch {sc.launch_latlon_deg[0]:.6f}, "
            f"{sc.launch_latlon_deg[1]:.6f}; {f.batteries} packs per vehicle, {f.battery_swap_s:g} s per swap\n"
            f"Lanes {plan.lane_spacing_m:.1f} m apart at bearing {plan.lane_heading_deg:.0f} deg, {plan.coverage} coverage.")
    rows = []
    missions = iter(m for _, m in files)
    for v, sp in zip(plan.vehicles, sorties):
        for j, (s, t0) in enumerate(zip(sp.sorties, sp.start_times_s())):
            m = next(missions)
            rows.append([f"uav{v.index + 1}", j + 1, _mmss(t0), len(m.waypoints()), len(m.items),
                         f"{s.length_m / 1000:.2f}", _mmss(s.duration_s), f"{s.energy_j / 1000:.1f}",
                         f"{100 * s.energy_j / usable:.1f}"])
    table = format_table(["vehicle", "sortie", "takes off m:s", "waypoints", "items", "length km", "time m:s",
                          "energy kJ", "% of a pack"], rows)
    foot = (f"% of a pack = share of the usable {usable / 1000:.1f} kJ of one pack ({f.energy_budget_j / 1000:g} kJ "
            f"minus {f.energy_reserve_fraction:.0%} reserve); each sortie ends with RTL, the next takes off from home "
            f"{f.battery_swap_s:g} s after it lands; times at cruise speed, take-off, landing, climb and turns not "
            f"included. Sorties: {packs_sentence(sorties, f.battery_swap_s)}; the scan takes "
            f"{_mmss(search_time_s(sorties))} from the first take-off to the last landing.")
    return head + "\n\n" + table + "\n" + foot


def summary(sc, plan, missions) -> str:
    """The text printed after planning: the scan layout and one row per vehicle."""
    from ..render.terminal import format_table

    f = sc.fleet
    usable = sc.usable_energy_j
    idle = f.vehicles - len(plan.vehicles)
    head = [
        f"Scan plan '{sc.name}' ({sc.source}): {f.vehicles} {'ArduPilot' if f.autopilot == 'ardupilot' else 'PX4'} "
        f"vehicles at {f.altitude_m:g} m and {f.speed_m_s:g} m/s, launch {sc.launch_latlon_deg[0]:.6f}, "
        f"{sc.launch_latlon_deg[1]:.6f}",
        f"Lanes {plan.lane_spacing_m:.1f} m apart at bearing {plan.lane_heading_deg:.0f} deg, "
        f"{plan.coverage} coverage (every point within R = {plan.range_m:.1f} m of "
        f"{'two lanes' if plan.coverage == 'double' else 'a lane'}).",
    ]
    from ..terrain import describe as describe_terrain
    head.append(describe_terrain(sc))
    if idle:
        head.append(f"{idle} vehicle(s) have nothing to scan (more vehicles than lanes) and get no mission.")
    rows = []
    climbs = [0.0] * len(missions)
    if sc.dem is not None:  # the climbs over the terrain (energy.RotorcraftPower.climb_energy_j)
        from ..terrain_missions import check_climb_energy
        climbs = check_climb_energy(sc, plan.vehicles, missions)
    for v, m, c in zip(plan.vehicles, missions, climbs):
        mins, secs = divmod(int(round(v.duration_s)), 60)
        rows.append([f"uav{v.index + 1}", len(m.waypoints()), len(m.items), f"{v.length_m / 1000:.2f}",
                     f"{mins}:{secs:02d}", f"{(v.energy_j + c) / 1000:.1f}", f"{100 * (v.energy_j + c) / usable:.1f}"]
                    + ([f"{c / 1000:.1f}"] if sc.dem is not None else []))
    table = format_table(["vehicle", "waypoints", "items", "length km", "time m:s", "energy kJ", "% budget"]
                         + (["of it climbing kJ"] if sc.dem is not None else []), rows)
    foot = (f"% budget = share of the usable {usable / 1000:.1f} kJ per vehicle ({f.energy_budget_j / 1000:g} kJ "
            f"minus {f.energy_reserve_fraction:.0%} reserve); times at cruise speed, climb and turns not included."
            + (" Energy includes the climbs over the terrain (the vehicle's weight times the metres climbed)."
               if sc.dem is not None else ""))
    return "\n".join(head) + "\n\n" + table + "\n" + foot
