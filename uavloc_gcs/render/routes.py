"""Picture of a routing plan: access disks, routes through their access points, starts and homes."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..planning.problem import Plan, RoutingProblem
from .maps import (add_legend, add_scale_bar, draw_circles, draw_points, draw_polylines, new_map,
                   save_figure, vehicle_colors)


def plan_figure(problem: RoutingProblem, plan: Plan, *, title: str = "Route plan",
                subtitle: str | None = None):
    """A matplotlib Figure of ``plan`` over ``problem`` (metres, local frame)."""
    if subtitle is None:
        subtitle = (f"makespan {plan.makespan_s:.1f} s, lower bound {plan.lower_bound_s:.1f} s, "
                    f"{len(problem.targets)} people, {len(problem.vehicles)} vehicles at "
                    f"{problem.speed_m_s:g} m/s")
    fig, ax = new_map(title, subtitle=subtitle)
    centres = problem.centres_xy_m
    if len(centres):
        draw_circles(ax, centres, problem.radii_m, label="access disk (at t0)", color="#7f7f7f",
                     alpha=0.12)
        draw_points(ax, centres, "person (predicted, t0)", color="#444444", marker="o", size=12,
                    annotations=[t.id for t in problem.targets])
        vel = problem.velocities_m_s
        moving = np.linalg.norm(vel, axis=1) > 0
        if moving.any():
            for (x, y), (vx, vy) in zip(centres[moving], vel[moving]):
                ax.annotate("", xy=(x + 20 * vx, y + 20 * vy), xytext=(x, y),
                            arrowprops=dict(arrowstyle="->", color="#444444", lw=0.8))
    colors = vehicle_colors(len(problem.vehicles))
    by_id = {r.vehicle_id: r for r in plan.routes}
    # Moving people: the disk where the vehicle meets it, dashed.
    tindex = {t.id: i for i, t in enumerate(problem.targets)}
    met_c, met_r = [], []
    for r in plan.routes:
        for tid, t_s in zip(r.target_ids, r.access_times_s):
            t = problem.targets[tindex[tid]]
            if t.velocity_m_s != (0.0, 0.0):
                dt = float(t_s) - problem.t0_s
                met_c.append((t.xy_m[0] + t.velocity_m_s[0] * dt, t.xy_m[1] + t.velocity_m_s[1] * dt))
                met_r.append(t.radius_m)
    if met_c:
        draw_circles(ax, np.array(met_c), met_r, label="access disk when met", color="#7f7f7f",
                     linestyle="--", fill=False)
    lines, labels = [], []
    for v in problem.vehicles:
        r = by_id.get(v.id)
        pts = np.zeros((0, 2)) if r is None else np.asarray(r.access_points_xy_m).reshape(-1, 2)
        lines.append(np.vstack([v.start_xy_m, pts, v.home_xy_m]))
        dur = 0.0 if r is None else r.duration_s
        labels.append(f"{v.id}: {0 if r is None else len(r.target_ids)} people, {dur:.1f} s")
    draw_polylines(ax, lines, labels=labels, colors=colors)
    for k, (v, line) in enumerate(zip(problem.vehicles, lines)):
        if len(line) > 2:
            draw_points(ax, line[1:-1], None, color=colors[k], size=14)
    starts = problem.starts_xy_m
    homes = problem.homes_xy_m
    draw_points(ax, starts, "start (now)", color="#1a1a1a", marker="s", size=40)
    draw_points(ax, homes, "home", color="#d62728", marker="^", size=90)
    add_scale_bar(ax)
    add_legend(ax)
    return fig


def save_plan_picture(problem: RoutingProblem, plan: Plan, path: str | Path, **kwargs) -> Path:
    """Write the plan picture as PNG or SVG (by suffix)."""
    return save_figure(plan_figure(problem, plan, **kwargs), path)
