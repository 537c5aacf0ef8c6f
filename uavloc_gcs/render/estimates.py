"""The localization picture: area, where each vehicle heard phones, estimates with their 95 %
circles, mirror candidates of ambiguous estimates (dashed), and the truth when simulated."""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np
from matplotlib.figure import Figure

from . import maps


def estimates_figure(estimates: Mapping, *, area_xy_m: np.ndarray | None = None,
                     tracks_xy_m: Mapping[int, list] | None = None, truth_xy_m: Mapping[int, np.ndarray] | None = None,
                     title: str = "Localization", subtitle: str | None = None) -> Figure:
    """``estimates`` {emitter_id: Estimate}; ``tracks_xy_m`` {vehicle: [segment (N, 2), ...]}."""
    ok = [e for _, e in sorted(estimates.items()) if e.ok]
    fig, ax = maps.new_map(f"{title}: {len(ok)} estimate(s)", subtitle=subtitle)
    if area_xy_m is not None:
        maps.draw_area(ax, area_xy_m)
    tracks = tracks_xy_m or {}
    colors = maps.vehicle_colors(max(tracks, default=0) + 1)
    for v, segments in sorted(tracks.items()):
        maps.draw_polylines(ax, segments, [f"vehicle {v} (heard)"] + [None] * (len(segments) - 1),
                            [colors[v]] * len(segments), linewidth=1.0, arrows=False)
    if ok:
        xy = np.array([e.position_xy_m for e in ok])
        maps.draw_circles(ax, xy, [e.radius95_m for e in ok], "95 % radius", color="#d62728")
        maps.draw_points(ax, xy, "estimate", color="#d62728", marker="P", size=60)
        mirrors = [e for e in ok if e.ambiguous and e.mirror is not None]
        if mirrors:
            mxy = np.array([e.mirror.position_xy_m for e in mirrors])
            maps.draw_points(ax, mxy, "mirror candidate", color="#ff7f0e", marker="X", size=50)
            maps.draw_circles(ax, mxy, [e.mirror.radius95_m for e in mirrors], None, color="#ff7f0e",
                              linestyle="--", fill=False)
    if truth_xy_m:
        maps.draw_points(ax, np.array(list(truth_xy_m.values())), "true position", color="#222222", marker="x")
    maps.draw_launch(ax)
    maps.add_scale_bar(ax)
    maps.add_north_arrow(ax)
    maps.add_legend(ax)
    if ok:  # short, non-overlapping labels (E1, E2, ... as in the table's 'map' column), not 10-digit ids
        maps.place_labels(ax, np.array([e.position_xy_m for e in ok]), estimate_labels(estimates),
                          "#d62728")
    return fig


def estimate_labels(estimates: Mapping) -> list[str]:
    """Map labels of the located estimates, in emitter order: E1, E2, ..."""
    return [f"E{k}" for k, (_, e) in enumerate(((i, e) for i, e in sorted(estimates.items()) if e.ok), start=1)]


# One colour per person state, shared by result.png and the live map.
STATE_COLORS = {"located": "#2ca02c", "heard": "#ff7f0e", "given up": "#d62728", "never heard": "#7f7f7f"}
STATE_LEGEND = {"located": "located (95 % circle)", "heard": "heard, not located (95 % circle)",
                "given up": "given up (95 % circle)"}


def result_figure(people, *, area_xy_m: np.ndarray, tracks_xy_m: Mapping[int, np.ndarray],
                  truth_xy_m: Mapping[int, np.ndarray] | None = None, title: str = "Result",
                  subtitle: str | None = None, coverage=None, terrain=None, fence_xy_m=None) -> Figure:
    """The end-of-search map: area, flown tracks, each person's reported position with its 95 %
    circle coloured by state and its label (P01 ...; labels never overlap), the true positions
    joined to their estimates when simulated, launch point, legend, scale bar and north arrow.

    ``people``: objects with ``east_m``, ``north_m``, ``radius95_m``, ``state``, ``label`` and
    ``emitter_id`` (``service.results.PersonResult``). ``coverage`` (search.coverage.CoverageSummary):
    the achieved POD of every cell under it all, red (0: unsearched) to green (the target).
    ``terrain`` (uavloc_gcs.terrain.Terrain): hillshade and contours underneath. ``fence_xy_m``:
    the scenario's geofence (uavloc_gcs/geofence.py), drawn as a dashed red outline."""
    import math  # noqa: PLC0415
    import textwrap  # noqa: PLC0415

    if subtitle:
        subtitle = "\n".join(textwrap.fill(line, 120) for line in subtitle.split("\n"))

    area = np.asarray(area_xy_m, dtype=float)
    span = area.max(axis=0) - area.min(axis=0)
    n_ok = sum(p.state == "located" for p in people)
    fig, ax = maps.new_map(f"{title}: {n_ok} of {len(people)} people located", subtitle=subtitle,
                           extent_m=tuple(span))
    if terrain is not None:
        from .terrain import draw_terrain  # noqa: PLC0415
        draw_terrain(ax, terrain, np.vstack([area, np.zeros((1, 2))]
                                            + [np.asarray(t).reshape(-1, 2) for t in tracks_xy_m.values()]))
    if coverage is not None:
        draw_pod(fig, ax, coverage)
    maps.draw_area(ax, area)
    if fence_xy_m is not None and len(fence_xy_m):
        maps.draw_fence(ax, np.asarray(fence_xy_m, dtype=float))
    ids = sorted(tracks_xy_m)
    colors = maps.vehicle_colors(max(ids, default=0))
    maps.draw_polylines(ax, [tracks_xy_m[v] for v in ids], [f"UAV {v} flown" for v in ids],
                        [colors[v - 1] for v in ids], linewidth=1.0, arrows=False)
    maps.draw_launch(ax)
    est = [p for p in people if math.isfinite(p.east_m) and math.isfinite(p.north_m)]
    for state, label in STATE_LEGEND.items():
        group = [p for p in est if p.state == state]
        if not group:
            continue
        xy = np.array([[p.east_m, p.north_m] for p in group])
        radii = np.array([p.radius95_m for p in group], dtype=float)
        # a tinted circle wider than the area tints the whole map and hides the POD raster under
        # it (a person heard once can have a radius of kilometres): those are outlines only
        wide = radii > WIDE_CIRCLE_FRACTION * max(span)
        if (~wide).any():
            maps.draw_circles(ax, xy[~wide], radii[~wide], color=STATE_COLORS[state], alpha=0.12)
        if wide.any():
            maps.draw_circles(ax, xy[wide], radii[wide], color=STATE_COLORS[state], fill=False)
        # a circle of a few metres on a kilometre map is smaller than its marker: a ring of fixed
        # size shows where it is (its radius is in the label)
        small = np.array([p.radius95_m < SMALL_CIRCLE_FRACTION * max(span) for p in group])
        if small.any():
            ax.scatter(xy[small, 0], xy[small, 1], s=230, facecolors="none", edgecolors=STATE_COLORS[state],
                       linewidths=1.2, zorder=5.5)
        maps.draw_points(ax, xy, label, color=STATE_COLORS[state], marker="P", size=55, zorder=6)
    truth = None
    if truth_xy_m:
        truth = np.array([truth_xy_m[k][:2] for k in sorted(truth_xy_m)], dtype=float)
        # a thin cross above the estimates: both stay visible where they coincide
        ax.scatter(truth[:, 0], truth[:, 1], s=36, c="#111111", marker="x", linewidths=1.3, zorder=7,
                   label="true position (simulation)")
        ax.update_datalim(truth)
        for p in est:
            if p.emitter_id in truth_xy_m:
                tx, ty = truth_xy_m[p.emitter_id][:2]
                ax.plot([p.east_m, tx], [p.north_m, ty], color="#111111", linewidth=0.7, zorder=4)
    lo, hi = _fit_view(ax, [area, np.zeros((1, 2))]
                       + [np.asarray(t, dtype=float).reshape(-1, 2) for t in tracks_xy_m.values()]
                       + ([truth] if truth is not None else [])
                       + [np.array([[p.east_m, p.north_m]]) for p in est if _near(p, area, span)])
    far = [p for p in est if not _near(p, area, span)]
    est = [p for p in est if _near(p, area, span)]
    _mark_far(ax, far, lo, hi)
    maps.add_scale_bar(ax)
    maps.add_north_arrow(ax)
    maps.add_legend(ax)
    # people without a position (never heard, or heard without a fix) are labelled at their true
    # position when simulated, with their state: every row of the table has its name on the map
    placed = {id(p) for p in est}
    unplaced = [p for p in people if id(p) not in placed and truth_xy_m and p.emitter_id in truth_xy_m]
    anchors = ([[p.east_m, p.north_m] for p in est]
               + [list(np.asarray(truth_xy_m[p.emitter_id][:2], float)) for p in unplaced])
    if anchors:
        maps.place_labels(ax, np.array(anchors, dtype=float),
                          [person_label(p) for p in est] + [f"{p.label or f'#{p.emitter_id}'} ({p.state})"
                                                             for p in unplaced],
                          [STATE_COLORS.get(p.state, "#222222") for p in [*est, *unplaced]], avoid_xy=truth)
    return fig


def _fit_view(ax, pieces) -> tuple[np.ndarray, np.ndarray]:
    """Show the area, the tracks, the launch point and every person's centre near the area, with a
    margin; return the view's corners. A 95 % circle wider than that (a person heard once or twice
    can have one of kilometres) runs off the map instead of shrinking the search area to a dot (its
    radius is in the tables)."""
    pts = np.vstack([p for p in pieces if len(p)])
    pts = pts[np.isfinite(pts).all(axis=1)]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.08 * max(float((hi - lo).max()), 50.0)
    lo, hi = lo - pad, hi + pad
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    return lo, hi


FAR_FRACTION = 0.5  # a centre farther outside the area than this share of its span is drawn as an arrow


def _near(p, area: np.ndarray, span: np.ndarray) -> bool:
    """Whether ``p``'s centre is within FAR_FRACTION of the area's span of the area's bounding box."""
    grow = FAR_FRACTION * float(max(span))
    lo, hi = area.min(axis=0) - grow, area.max(axis=0) + grow
    return bool(lo[0] <= p.east_m <= hi[0] and lo[1] <= p.north_m <= hi[1])


def _mark_far(ax, far, lo: np.ndarray, hi: np.ndarray) -> None:
    """People whose centre lies far outside the area (a person heard once can be placed kilometres
    off): an arrow at the edge of the map pointing at them, with their name and distance from the
    launch point, instead of a map that shrinks the area to a dot to show them."""
    centre, half = (lo + hi) / 2.0, (hi - lo) / 2.0
    for p in far:
        d = np.array([p.east_m, p.north_m]) - centre
        # where the ray from the map's centre leaves a box 6 % inside the edge
        scale = min(0.94 * half[0] / abs(d[0]) if d[0] else math.inf,
                    0.94 * half[1] / abs(d[1]) if d[1] else math.inf)
        tip = centre + d * scale
        tail = tip - d / np.linalg.norm(d) * 0.08 * float(max(hi - lo))
        color = STATE_COLORS.get(p.state, "#222222")
        km = math.hypot(p.east_m, p.north_m) / 1000.0
        ax.annotate(f"{p.label or f'#{p.emitter_id}'}: {km:.1f} km from launch", xy=tip, xytext=tail,
                    fontsize=8, color=color, ha="center", va="center", zorder=8,
                    arrowprops=dict(arrowstyle="-|>", color=color, linewidth=1.3))


SMALL_CIRCLE_FRACTION = 1 / 60  # 95 % circles under this share of the map's span get a ring
WIDE_CIRCLE_FRACTION = 0.5  # 95 % circles over this share of the area's span are not tinted


def person_label(p) -> str:
    """A person's map label: the name, and for the located their 95 % radius and lat/lon (the
    numbers a rescuer goes to)."""
    import math  # noqa: PLC0415

    name = p.label or f"#{p.emitter_id}"
    lat, lon = getattr(p, "lat_deg", math.nan), getattr(p, "lon_deg", math.nan)
    if p.state != "located" or not (math.isfinite(lat) and math.isfinite(lon)):
        return name
    return f"{name} ({p.radius95_m:.0f} m)\n{lat:.6f}, {lon:.6f}"


def draw_pod(fig, ax, coverage) -> None:
    """The achieved POD per cell as a raster (red 0 .. green at the target) with a colour bar."""
    g = coverage.grid
    ny, nx = g.shape
    raster = np.full((ny, nx), np.nan)
    raster[g.index[:, 0], g.index[:, 1]] = coverage.pod1
    extent = (g.x0_m, g.x0_m + nx * g.cell_m, g.y0_m, g.y0_m + ny * g.cell_m)
    im = ax.imshow(np.ma.masked_invalid(raster), origin="lower", extent=extent, cmap="RdYlGn", vmin=0.0,
                   vmax=max(coverage.target, 1e-6), alpha=0.35, zorder=0, interpolation="nearest")
    bar = fig.colorbar(im, ax=ax, shrink=0.5, pad=0.01)
    bar.set_label(f"achieved POD (target {coverage.target:.2f})")
