"""Terrain in the pictures (issue 28 item 6): a grey hillshade of the DEM under the map with
labelled contour lines, drawn beneath everything else in local metres."""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes

__all__ = ["draw_terrain", "contour_interval_m"]


def contour_interval_m(relief_m: float) -> float:
    """A round contour interval giving about 5-12 lines over ``relief_m`` of relief."""
    for step in (1, 2, 5, 10, 20, 25, 50, 100, 200, 250, 500):
        if relief_m / step <= 12:
            return float(step)
    return 1000.0


def draw_terrain(ax: Axes, dem, points_xy_m: np.ndarray, *, margin_m: float = 60.0) -> None:
    """Hillshade and contours of ``dem`` (uavloc_gcs.terrain.Terrain) over the box around
    ``points_xy_m`` (everything the map shows), at zorder 0, with a legend entry naming the source."""
    from matplotlib.colors import LightSource

    pts = np.asarray(points_xy_m, dtype=float).reshape(-1, 2)
    lo, hi = pts.min(axis=0) - margin_m, pts.max(axis=0) + margin_m
    step = max(dem.resolution_m / 2.0, float(np.max(hi - lo)) / 300.0)
    xs, ys, z = dem.grid_xy(lo, hi, step)
    dx = float(xs[1] - xs[0]) if len(xs) > 1 else 1.0
    dy = float(ys[1] - ys[0]) if len(ys) > 1 else 1.0
    # LightSource expects rows from north to south; the grid's rows go south to north
    shade = LightSource(azdeg=315, altdeg=45).hillshade(z[::-1], vert_exag=1.0, dx=dx, dy=dy)
    extent = (xs[0] - dx / 2, xs[-1] + dx / 2, ys[0] - dy / 2, ys[-1] + dy / 2)
    ax.imshow(shade, cmap="gray", extent=extent, origin="upper", vmin=0.0, vmax=1.0, alpha=0.35, zorder=0,
              interpolation="bilinear")
    relief = float(np.nanmax(z) - np.nanmin(z))
    if relief > 0:
        interval = contour_interval_m(relief)
        levels = np.arange(np.ceil(np.nanmin(z) / interval) * interval, np.nanmax(z) + 1e-9, interval)
        if len(levels):
            cs = ax.contour(xs, ys, z, levels=levels, colors="#8c6d46", linewidths=0.6, alpha=0.8, zorder=0.5)
            ax.clabel(cs, fmt=lambda v: f"{v:.0f}", fontsize=6, inline=True)
            ax.plot([], [], color="#8c6d46", linewidth=0.6,
                    label=f"ground, {interval:g} m contours above sea level")
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])


def contour_lines(dem, points_xy_m: np.ndarray, *, margin_m: float = 200.0, max_points: int = 4000) -> dict:
    """Contour polylines of ``dem`` around ``points_xy_m`` for the live map: {"interval_m",
    "lines": [{"level_m", "xy_m": [[e, n], ...]}, ...]}, rounded to 0.1 m, at most ``max_points``
    vertices in all (every line thinned alike beyond that)."""
    import contourpy

    pts = np.asarray(points_xy_m, dtype=float).reshape(-1, 2)
    lo, hi = pts.min(axis=0) - margin_m, pts.max(axis=0) + margin_m
    step = max(dem.resolution_m / 2.0, float(np.max(hi - lo)) / 200.0)
    xs, ys, z = dem.grid_xy(lo, hi, step)
    relief = float(np.nanmax(z) - np.nanmin(z))
    if not relief > 0:
        return {"interval_m": None, "lines": []}
    interval = contour_interval_m(relief)
    gen = contourpy.contour_generator(xs, ys, z)
    lines = []
    for level in np.arange(np.ceil(np.nanmin(z) / interval) * interval, np.nanmax(z) + 1e-9, interval):
        for seg in gen.lines(float(level)):
            if len(seg) >= 2:
                lines.append((float(level), np.asarray(seg, dtype=float)))
    total = sum(len(s) for _, s in lines)
    keep = max(1, int(np.ceil(total / max_points)))
    out = [{"level_m": lv, "xy_m": np.round(np.vstack([s[::keep], s[-1:]]), 1).tolist()} for lv, s in lines]
    return {"interval_m": interval, "lines": out}
