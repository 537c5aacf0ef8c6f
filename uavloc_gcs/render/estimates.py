"""The localization picture: area, where each vehicle heard phones, estimates with their 95 %
circles, mirror candidates of ambiguous estimates (dashed), and the truth when simulated."""

from __future__ import annotations

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
        maps.draw_points(ax, xy, "estimate", color="#d62728", marker="P", size=60,
                         annotations=[str(e.emitter_id) for e in ok])
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
    return fig
