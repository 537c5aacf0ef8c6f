"""Map pictures on a local-metre axes (east/north of the scenario frame), matplotlib Agg.

Typical use::

    fig, ax = new_map("Scan plan: paper", subtitle=origin_caption(42.625, 13.283))
    draw_area(ax, area_xy)
    draw_polylines(ax, routes, labels=["uav1", "uav2"], colors=vehicle_colors(2))
    draw_circles(ax, estimates_xy, radii_m, label="95 % radius")
    draw_launch(ax)
    add_scale_bar(ax); add_north_arrow(ax); add_legend(ax)
    save_figure(fig, "preview.png")

No pyplot: figures are plain :class:`matplotlib.figure.Figure` objects, so nothing touches global
state and nothing opens a window. Output is deterministic (no timestamps, fixed SVG ids) and
written atomically.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Polygon as MplPolygon

from ..atomicfile import atomic_open
from . import palette

__all__ = [
    "new_map", "origin_caption", "vehicle_colors", "draw_area", "draw_polygons", "draw_polylines",
    "draw_points", "draw_circles", "draw_launch", "add_scale_bar", "add_north_arrow", "add_legend",
    "place_labels",
    "save_figure",
]

AREA_COLOR = "#444444"
LAUNCH_COLOR = "#d62728"


def vehicle_colors(n: int) -> list[str]:
    """``n`` distinct colours '#rrggbb', one per vehicle (vehicle k always gets the same one)."""
    return palette.vehicle_colors(n)


def origin_caption(lat_deg: float, lon_deg: float) -> str:
    """'x/y in metres from 42.62500° N, 13.28300° E' -- to put the local frame on the map."""
    ns = "N" if lat_deg >= 0 else "S"
    ew = "E" if lon_deg >= 0 else "W"
    return f"east/north in metres from the launch point {abs(lat_deg):.5f}° {ns}, {abs(lon_deg):.5f}° {ew}"


def new_map(title: str, *, subtitle: str | None = None, size_in: tuple[float, float] | None = None,
            extent_m: tuple[float, float] | None = None, dpi: int = 120) -> tuple[Figure, Axes]:
    """A new figure with one equal-aspect axes in metres (east right, north up).

    ``extent_m`` = (width, height) of what will be drawn sizes the figure to fit it (10 in wide,
    legend on the right); otherwise ``size_in`` or 10 x 7 in.
    """
    if size_in is None:
        size_in = (10.0, 7.0)
        if extent_m is not None and extent_m[0] > 0:
            size_in = (10.0, min(max(6.2 * extent_m[1] / extent_m[0] + 1.8, 4.5), 11.0))
    fig = Figure(figsize=size_in, dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.grid(True, color="#dddddd", linewidth=0.6, zorder=0)
    ax.set_axisbelow(True)
    ax.set_title(title, fontsize=13, fontweight="bold", loc="left")
    if subtitle:
        ax.text(0.0, 1.008, subtitle, transform=ax.transAxes, fontsize=8.5, color="#555555",
                ha="left", va="bottom", linespacing=1.3)
        pad = 8 + 12 * (subtitle.count("\n") + 1)
        ax.set_title(title, fontsize=13, fontweight="bold", loc="left", pad=pad)
    return fig, ax


def _closed(xy: np.ndarray) -> np.ndarray:
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    return np.vstack([xy, xy[:1]]) if len(xy) and not np.array_equal(xy[0], xy[-1]) else xy


def draw_area(ax: Axes, xy: np.ndarray, label: str | None = "search area", *, color: str = AREA_COLOR,
              fill: bool = True) -> None:
    """The search area: a bold outline with a faint fill. ``xy`` (N, 2) metres, open or closed."""
    ring = _closed(xy)
    if fill:
        ax.add_patch(MplPolygon(ring, closed=True, facecolor=color, alpha=0.06, edgecolor="none", zorder=1))
    ax.plot(ring[:, 0], ring[:, 1], color=color, linewidth=2.0, label=label, zorder=2)
    ax.update_datalim(ring)
    ax.autoscale_view()


def draw_fence(ax: Axes, xy: np.ndarray, label: str | None = "geofence") -> None:
    """A scenario's geofence (uavloc_gcs/geofence.py): a dashed red outline. ``xy`` (N, 2) metres."""
    ring = _closed(xy)
    ax.plot(ring[:, 0], ring[:, 1], color="#c0392b", linewidth=1.4, linestyle=(0, (6, 3)), label=label, zorder=4)
    ax.update_datalim(ring)


def draw_polygons(ax: Axes, polygons: Sequence[np.ndarray], labels: Sequence[str | None] | None = None,
                  colors: Sequence | None = None, *, alpha: float = 0.14) -> None:
    """Filled polygons (e.g. one sub-area per vehicle), a thin dashed edge each."""
    colors = list(colors) if colors is not None else vehicle_colors(len(polygons))
    for k, xy in enumerate(polygons):
        ring = _closed(xy)
        if len(ring) < 3:
            continue
        label = labels[k] if labels is not None else None
        ax.add_patch(MplPolygon(ring, closed=True, facecolor=colors[k], alpha=alpha, edgecolor=colors[k],
                                linewidth=0.8, linestyle="--", label=label, zorder=1))
        ax.update_datalim(ring)
    ax.autoscale_view()


def draw_polylines(ax: Axes, lines: Sequence[np.ndarray], labels: Sequence[str | None] | None = None,
                   colors: Sequence | None = None, *, linewidth: float = 1.8, arrows: bool = True,
                   linestyle: str = "-", markers: bool = False, zorder: float = 3) -> None:
    """Polylines (routes), one colour each; ``arrows`` marks the flight direction on long legs."""
    colors = list(colors) if colors is not None else vehicle_colors(len(lines))
    for k, xy in enumerate(lines):
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        if len(xy) == 0:
            continue
        label = labels[k] if labels is not None else None
        ax.plot(xy[:, 0], xy[:, 1], color=colors[k], linewidth=linewidth, linestyle=linestyle, label=label,
                marker="o" if markers else None, markersize=3, zorder=zorder, solid_capstyle="round")
        if arrows and len(xy) >= 2:
            _direction_arrows(ax, xy, colors[k], zorder)
    ax.autoscale_view()


def _direction_arrows(ax: Axes, xy: np.ndarray, color, zorder: float) -> None:
    seg = np.diff(xy, axis=0)
    length = np.linalg.norm(seg, axis=1)
    if length.max() <= 0:
        return
    x0, x1 = ax.dataLim.intervalx
    min_len = 0.08 * max(x1 - x0, float(length.max()))
    for k in np.nonzero(length >= min_len)[0]:
        mid = xy[k] + 0.5 * seg[k]
        d = seg[k] / length[k] * 1e-3 * length[k]
        ax.annotate("", xy=mid + d, xytext=mid - d, zorder=zorder + 0.1,
                    arrowprops=dict(arrowstyle="-|>", color=color, lw=0, mutation_scale=13))


def draw_points(ax: Axes, xy: np.ndarray, label: str | None = None, *, color="#222222", marker: str = "o",
                size: float = 30.0, annotations: Sequence[str] | None = None, zorder: float = 5) -> None:
    """Scatter points (waypoints, people, estimates); optional text next to each."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    if len(xy) == 0:
        return
    ax.scatter(xy[:, 0], xy[:, 1], s=size, c=[color], marker=marker, label=label, zorder=zorder,
               edgecolors="white", linewidths=0.6)
    if annotations is not None:
        for (x, y), text in zip(xy, annotations):
            ax.annotate(str(text), (x, y), xytext=(4, 4), textcoords="offset points", fontsize=8,
                        color=color, zorder=zorder)
    ax.update_datalim(xy)
    ax.autoscale_view()


def draw_circles(ax: Axes, centres: np.ndarray, radii: Sequence[float] | float, label: str | None = None, *,
                 color="#d62728", alpha: float = 0.15, linestyle: str = "-", fill: bool = True,
                 zorder: float = 4) -> None:
    """Circles of radius ``radii`` [m] (e.g. 95 % error circles) around ``centres`` (N, 2)."""
    c = np.asarray(centres, dtype=float).reshape(-1, 2)
    r = np.broadcast_to(np.asarray(radii, dtype=float), (len(c),))
    for k, ((x, y), rad) in enumerate(zip(c, r)):
        if not math.isfinite(rad) or rad <= 0:
            continue
        ax.add_patch(Circle((x, y), rad, facecolor=color if fill else "none", alpha=alpha if fill else 1.0,
                            edgecolor="none", zorder=zorder))
        ax.add_patch(Circle((x, y), rad, facecolor="none", edgecolor=color, linewidth=1.0,
                            linestyle=linestyle, zorder=zorder, label=label if k == 0 else None))
        ax.update_datalim([[x - rad, y - rad], [x + rad, y + rad]])
    ax.autoscale_view()


def draw_launch(ax: Axes, xy: Sequence[float] = (0.0, 0.0), label: str = "launch / home") -> None:
    """The launch point: a large red triangle."""
    ax.scatter([xy[0]], [xy[1]], s=160, marker="^", c=LAUNCH_COLOR, edgecolors="white", linewidths=1.2,
               label=label, zorder=10)
    ax.update_datalim([xy])
    ax.autoscale_view()


def _nice_length(target: float) -> float:
    if target <= 0:
        return 1.0
    exp = 10 ** math.floor(math.log10(target))
    for m in (5, 2, 1):
        if m * exp <= target:
            return m * exp
    return exp


def add_scale_bar(ax: Axes, length_m: float | None = None, *, outside: bool = True,
                  loc: str = "lower right") -> float:
    """A labelled scale bar (about a fifth of the view width unless ``length_m``). Returns its length.

    ``outside`` (default) puts it right of the map, under the legend, so it never hides data.
    """
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar

    ax.autoscale_view()
    x0, x1 = ax.get_xlim()
    length = length_m or _nice_length((x1 - x0) / 5.0)
    text = f"{length / 1000:g} km" if length >= 1000 else f"{length:g} m"
    where = dict(loc="lower left", bbox_to_anchor=(1.02, 0.0), bbox_transform=ax.transAxes) if outside \
        else dict(loc=loc)
    bar = AnchoredSizeBar(ax.transData, length, text, pad=0.6, sep=4, frameon=True, size_vertical=0,
                          fontproperties={"size": 9}, **where)
    bar.patch.set_alpha(0.8)
    bar.patch.set_edgecolor("#bbbbbb")
    ax.add_artist(bar)
    return length


def add_north_arrow(ax: Axes, *, xy_axes: tuple[float, float] = (1.05, 0.16)) -> None:
    """An 'N' arrow in axes coordinates (north is up in the local frame); default right of the map."""
    x, y = xy_axes
    ax.annotate("N", xy=(x, y + 0.09), xytext=(x, y), xycoords="axes fraction", textcoords="axes fraction",
                ha="center", va="top", fontsize=10, fontweight="bold", annotation_clip=False,
                arrowprops=dict(arrowstyle="-|>", color="black", lw=1.2), zorder=20)


def add_legend(ax: Axes, *, loc: str = "upper left", outside: bool = True, ncol: int = 1) -> None:
    """A legend without duplicate labels; by default outside the map on the right."""
    handles, labels = ax.get_legend_handles_labels()
    seen: dict[str, object] = {}
    for h, lab in zip(handles, labels):
        if lab and not lab.startswith("_") and lab not in seen:
            seen[lab] = h
    if not seen:
        return
    kwargs = dict(fontsize=9, framealpha=0.9, ncol=ncol)
    if outside:
        ax.legend(seen.values(), seen.keys(), loc="upper left", bbox_to_anchor=(1.01, 1.0), **kwargs)
    else:
        ax.legend(seen.values(), seen.keys(), loc=loc, **kwargs)


def save_figure(fig: Figure, path: str | Path) -> Path:
    """Write ``fig`` to ``path`` as PNG or SVG (by suffix), deterministically and atomically."""
    import matplotlib

    p = Path(path)
    fmt = p.suffix.lower().lstrip(".")
    if fmt not in ("png", "svg"):
        raise ValueError(f"picture format must be .png or .svg, got {p.name!r}")
    metadata = {"Software": None} if fmt == "png" else {"Date": None, "Creator": None}
    with atomic_open(p, "wb", suffix=f".{fmt}") as fh, matplotlib.rc_context({"svg.hashsalt": "uavloc"}):
        fig.savefig(fh, format=fmt, metadata=metadata, bbox_inches="tight", pad_inches=0.2)
    return p


def place_labels(ax: Axes, xy: np.ndarray, texts: Sequence[str], colors: Sequence | str = "#222222", *,
                 fontsize: float = 8.5, avoid_xy: np.ndarray | None = None, zorder: float = 12) -> list:
    """Labels next to points that overlap neither each other nor the points (``avoid_xy``: more
    points to keep clear of). Call after everything else is drawn (it draws the figure once to
    know the final layout). A label pushed away from its point gets a thin leader line.

    Greedy: each label (in the given order) takes the first free spot from rings of 8 directions
    at growing distance; when none is free it takes the least crowded one.
    """
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    if len(xy) == 0:
        return []
    colors = [colors] * len(xy) if isinstance(colors, str) else list(colors)
    fig = ax.figure
    fig.canvas.draw()
    ax.set_autoscale_on(False)
    renderer = fig.canvas.get_renderer()
    to_px = ax.transData.transform
    pts = to_px(xy)
    obstacles = [pts] if avoid_xy is None else [pts, to_px(np.asarray(avoid_xy, dtype=float).reshape(-1, 2))]
    marks = np.vstack(obstacles)
    scale = fig.dpi / 72.0
    placed: list[tuple[float, float, float, float]] = []
    out = []
    dirs = [(1, 1), (1, -1), (-1, 1), (-1, -1), (1, 0), (-1, 0), (0, 1), (0, -1)]
    for (px, py), text, color in zip(pts, texts, colors):
        probe = ax.text(0, 0, text, fontsize=fontsize, fontweight="bold")
        bb = probe.get_window_extent(renderer)
        probe.remove()
        w, h = bb.width + 2 * scale, bb.height + 2 * scale
        best, best_cost = None, math.inf
        for ring in (6, 14, 24, 36, 50):
            for dx, dy in dirs:
                cx = px + dx * (ring * scale + (w / 2 if dx else 0))
                cy = py + dy * (ring * scale + (h / 2 if dy else 0))
                box = (cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2)
                cost = sum(_overlap(box, b) for b in placed)
                cost += sum(w * h * 0.5 for mx, my in marks
                            if box[0] - 3 * scale <= mx <= box[2] + 3 * scale and box[1] - 3 * scale <= my <= box[3] + 3 * scale)
                cost += ring * 0.01  # prefer close
                if cost < best_cost:
                    best, best_cost = (cx, cy, box, ring), cost
            if best_cost < 1.0:
                break
        cx, cy, box, ring = best
        placed.append(box)
        dx_pt, dy_pt = (cx - px) / scale, (cy - py) / scale
        x, y = ax.transData.inverted().transform((px, py))
        arrow = dict(arrowstyle="-", color=color, lw=0.6, shrinkA=0, shrinkB=2) if ring > 6 else None
        out.append(ax.annotate(text, (x, y), xytext=(dx_pt, dy_pt), textcoords="offset points", ha="center",
                               va="center", fontsize=fontsize, fontweight="bold", color=color, zorder=zorder,
                               arrowprops=arrow, annotation_clip=False,
                               bbox=dict(boxstyle="round,pad=0.15", facecolor="white", edgecolor="none",
                                         alpha=0.75)))
    return out


def _overlap(a, b) -> float:
    w = min(a[2], b[2]) - max(a[0], b[0])
    h = min(a[3], b[3]) - max(a[1], b[1])
    return w * h if w > 0 and h > 0 else 0.0
