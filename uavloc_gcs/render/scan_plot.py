"""The scan-plan picture: area, sub-areas, lanes and routes per vehicle, launch point."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from . import maps

EXCLUSION_COLOR = "#d62728"


def scan_figure(scenario, plan, *, title: str | None = None) -> Figure:
    """Figure of a :class:`uavloc_gcs.scan.ScanPlan` for ``scenario`` (local metres)."""
    lat0, lon0 = scenario.launch_latlon_deg
    n = len(plan.vehicles)
    colors = maps.vehicle_colors(max(n, 1))
    head = title or f"Initial scan: {scenario.name}"
    sub = (f"{n} vehicles, lanes {plan.lane_spacing_m:.0f} m apart ({plan.coverage} coverage, "
           f"hearing radius R = {plan.range_m:.0f} m) at {scenario.fleet.altitude_m:g} m, "
           f"{scenario.fleet.speed_m_s:g} m/s\n{maps.origin_caption(lat0, lon0)}")
    from .. import geofence

    given = geofence.for_scenario(scenario)
    fence = geofence.flight_fence(scenario)  # the scenario's, else the area plus area.default_geofence_m
    fence_xy = [np.asarray(fence.polygon_xy_m, float)]
    sub += "\n" + geofence.describe(scenario, plan)
    everything = np.vstack([scenario.area_xy_m(), np.zeros((1, 2))] + fence_xy + [v.route_xy_m() for v in plan.vehicles])
    fig, ax = maps.new_map(head, subtitle=sub, extent_m=tuple(np.ptp(everything, axis=0)))
    if scenario.dem is not None:  # hillshade and contours of terrain.dem underneath
        from .terrain import draw_terrain
        draw_terrain(ax, scenario.dem, everything)
    maps.draw_area(ax, scenario.area_xy_m(), label="search area")
    for ring in fence_xy:  # the geofence every planned flight stays inside
        maps.draw_fence(ax, ring, label=f"geofence ({fence.margin_m:g} m margin kept)" if given is not None else
                        f"fence: area + {scenario.area.default_geofence_m:g} m (no geofence given)")
    for v, col in zip(plan.vehicles, colors):
        maps.draw_polygons(ax, list(v.subarea_parts_xy_m), colors=[col] * len(v.subarea_parts_xy_m))
    for v, col in zip(plan.vehicles, colors):
        label = (f"uav{v.index + 1}: {v.length_m / 1000:.2f} km, {v.duration_s / 60:.1f} min, "
                 f"{v.energy_j / 1000:.0f} kJ")
        route = v.route_xy_m()
        # Transit legs (launch -> first lane, last lane -> launch) dashed, the scan itself solid.
        maps.draw_polylines(ax, [route[:2], route[-2:]], colors=[col, col], linewidth=1.0, linestyle=":",
                            arrows=False, zorder=2.5)
        maps.draw_polylines(ax, [v.waypoints_xy_m], labels=[label], colors=[col], linewidth=2.0)
    if n:
        ax.plot([], [], color="#777777", linestyle=":", label="transit to/from launch")
    maps.draw_launch(ax)
    maps.add_scale_bar(ax)
    maps.add_north_arrow(ax)
    maps.add_legend(ax)
    ax.margins(0.04)
    return fig


def mission_figure(xy_by_vehicle: list[np.ndarray], labels: list[str], *, title: str,
                   subtitle: str | None = None, fence_xy: np.ndarray | None = None, fences=(), circles=(),
                   rally_xy: np.ndarray | None = None, home: bool = True, points_xy: np.ndarray | None = None,
                   marks: tuple = ()) -> Figure:
    """Figure of mission routes already converted to local metres (used by ``uavloc preview``).

    ``fences`` is a list of (inclusion, ring), ``circles`` of (inclusion, (x, y), radius_m);
    exclusion zones are drawn red. ``home`` False leaves out the home marker (home unknown).
    ``points_xy`` with ``marks`` ('T' takeoff, 'L' land, 'o') adds the mission's places.
    """
    fences = list(fences) + ([(True, fence_xy)] if fence_xy is not None else [])
    pts = ([np.zeros((1, 2))] if home else []) + [np.asarray(xy).reshape(-1, 2) for xy in xy_by_vehicle]
    pts += [np.asarray(ring).reshape(-1, 2) for _, ring in fences]
    pts += [np.array([[x - r, y - r], [x + r, y + r]]) for _, (x, y), r in circles]
    if rally_xy is not None:
        pts.append(np.asarray(rally_xy).reshape(-1, 2))
    allp = np.vstack([p for p in pts if len(p)] or [np.zeros((1, 2))])
    fig, ax = maps.new_map(title, subtitle=subtitle, extent_m=tuple(np.ptp(allp, axis=0)))
    seen: set = set()
    for inclusion, ring in fences:
        if len(ring) >= 3:
            label = "geofence (inclusion)" if inclusion else "exclusion zone"
            maps.draw_area(ax, ring, label=None if label in seen else label,
                           color=maps.AREA_COLOR if inclusion else EXCLUSION_COLOR)
            seen.add(label)
    for inclusion, centre, radius in circles:
        label = "geofence circle" if inclusion else "exclusion circle"
        maps.draw_circles(ax, np.array([centre]), radius, label=None if label in seen else label,
                          color=maps.AREA_COLOR if inclusion else EXCLUSION_COLOR, alpha=0.06, zorder=1.5)
        seen.add(label)
    colors = maps.vehicle_colors(len(xy_by_vehicle))
    maps.draw_polylines(ax, xy_by_vehicle, labels=labels, colors=colors, markers=True)
    if points_xy is not None and len(points_xy):
        for mark, name, marker in (("T", "takeoff", "^"), ("L", "land", "v")):
            sel = np.array([m == mark for m in marks], dtype=bool)
            if sel.any():
                maps.draw_points(ax, np.asarray(points_xy)[sel], label=name, color="#444444", marker=marker,
                                 size=50)
    elif xy_by_vehicle:
        for xy, col in zip(xy_by_vehicle, colors):
            if len(xy):
                maps.draw_points(ax, xy[:1], color=col, marker="s", size=40)
    if rally_xy is not None and len(rally_xy):
        maps.draw_points(ax, rally_xy, label="rally point", color="#2ca02c", marker="P", size=60)
    if home:
        maps.draw_launch(ax)
    maps.add_scale_bar(ax)
    maps.add_north_arrow(ax)
    maps.add_legend(ax)
    ax.margins(0.05)
    return fig
