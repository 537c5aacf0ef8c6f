"""PNG figures of the paper experiment (matplotlib, Agg backend): means with 95 % CI bands."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

STYLE = {
    "MLE-EPSO (M)": ("tab:red", "o", "-"),
    "MLE-EPSO (NM)": ("tab:orange", "s", "--"),
    "MLE-PSO": ("tab:blue", "^", "-"),
    "MLE-GA": ("tab:green", "v", "-"),
    "RL-NM": ("tab:purple", "D", ":"),
}


def _series(rows, key_x, key_y, key_ci):
    by = {}
    for r in rows:
        by.setdefault(r["method"], []).append((r[key_x], r[key_y], r[key_ci]))
    return {m: np.array(v, dtype=float) for m, v in by.items()}


def _plot(ax, series, *, bars: bool, log: bool) -> None:
    # the reference method last and thickest: PSO/GA often coincide with it and would hide it
    # a method with no value to draw (none finite; on a log axis none positive) gets no legend entry
    order = [m for m in sorted(series, key=lambda m: m == "MLE-EPSO (M)")
             if (np.isfinite(series[m][:, 1]) & ((series[m][:, 1] > 0) if log else True)).any()]
    xs = np.unique(np.concatenate([series[m][:, 0] for m in order])) if order else np.array([])
    # error bars of the methods side by side at each x, not on top of each other
    step = (np.min(np.diff(xs)) if len(xs) > 1 else 1.0) * 0.06
    for k, m in enumerate(order):
        a = series[m]
        color, marker, ls = STYLE.get(m, ("k", ".", "-"))
        lw = 2.6 if m == "MLE-EPSO (M)" else 1.4
        x, y, ci = a[:, 0], a[:, 1], np.nan_to_num(a[:, 2], nan=0.0)
        if bars:
            x = x + (k - (len(order) - 1) / 2) * step
        lo = np.maximum(y - ci, y / 10.0) if log else np.maximum(y - ci, 0.0)
        if bars:
            ax.errorbar(x, y, yerr=[y - lo, ci], color=color, marker=marker, ls=ls, lw=lw, capsize=3, label=m)
        else:
            ax.plot(x, y, color=color, ls=ls, lw=lw, label=m)
            ax.fill_between(x, lo, y + ci, color=color, alpha=0.08, lw=0)


def plot_all(rows_a, rows_b, rows_c, out_dir: Path, required_m: float | None = None) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = []
    specs = [
        ("fig_a_completion_time.png", rows_a, "people", "completion_time_mean_s", "completion_time_ci95_s",
         "number of people", "task completion time [s]", "(a) Task completion time", True, False),
        ("fig_b_runtime.png", rows_b, "people", "runtime_mean_s", "runtime_ci95_s",
         "number of people", "algorithm run time [s]", "(b) Algorithm run time (planning / learning)", True, True),
        ("fig_c_error_vs_time.png", rows_c, "t_s", "max_error_mean_m", "max_error_ci95_m",
         "task time [s]", "maximum localization error [m]", "(c) Maximum localization error vs time", False, True),
    ]
    for name, rows, kx, ky, kci, xl, yl, title, bars, logy in specs:
        if not rows:
            continue
        fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=120)
        _plot(ax, _series(rows, kx, ky, kci), bars=bars, log=logy)
        ax.set_xlabel(xl)
        ax.set_ylabel(yl)
        ax.set_title(title)
        ax.margins(y=0.08)  # no marker on the frame
        if logy:
            vals = [r[ky] for r in rows if r[ky] is not None and math.isfinite(r[ky]) and r[ky] > 0]
            if vals:
                ax.set_yscale("log")
                # plain numbers (0.5, 4, 30), not 4x10^0
                from matplotlib.ticker import FuncFormatter, LogLocator

                plain = FuncFormatter(lambda v, _: f"{v:g}")
                ax.yaxis.set_major_formatter(plain)
                ax.yaxis.set_minor_locator(LogLocator(subs=(2.0, 5.0)))
                ax.yaxis.set_minor_formatter(plain)
        else:
            tops = [r[ky] + (r[kci] if r[kci] is not None and math.isfinite(r[kci]) else 0.0) for r in rows
                    if r[ky] is not None and math.isfinite(r[ky])]
            ax.set_ylim(0.0, max(tops) * 1.1 if tops and max(tops) > 0 else None)
        if kx == "people":  # the people counts run, as whole numbers, with room on both sides
            xs = sorted({r[kx] for r in rows})
            ax.set_xticks(xs)
            pad = (xs[-1] - xs[0]) * 0.06 if len(xs) > 1 else 1.0
            ax.set_xlim(xs[0] - pad, xs[-1] + pad)
        if name.startswith("fig_a"):  # the clairvoyant yardstick of the reference method
            ref = sorted((r["people"], r.get("oracle_completion_time_mean_s", math.nan)) for r in rows
                         if r["method"] == "MLE-EPSO (M)")
            if ref and any(math.isfinite(v) for _, v in ref):
                ax.plot([x for x, _ in ref], [v for _, v in ref], color="k", ls="--", lw=1.2, marker="x",
                        label="clairvoyant (true tracks after the scan)")
        if name.startswith("fig_c") and required_m:
            ax.axhline(required_m, color="k", lw=0.8, ls="--", label=f"required {required_m:g} m")
        ax.grid(True, alpha=0.3, which="both")
        ax.legend(fontsize=8)
        fig.tight_layout()
        path = Path(out_dir) / name
        fig.savefig(path)
        plt.close(fig)
        out.append(path)
    return out
