"""Vehicle colours shared by pictures, GeoJSON and KML (no matplotlib import here)."""

from __future__ import annotations

# Okabe-Ito (colour-blind safe) first, then the tab20 colours for large fleets.
PALETTE = ("#0072B2", "#E69F00", "#009E73", "#CC79A7", "#56B4E9", "#D55E00", "#F0E442", "#000000")
_TAB20 = ("#1f77b4", "#aec7e8", "#ff7f0e", "#ffbb78", "#2ca02c", "#98df8a", "#d62728", "#ff9896", "#9467bd",
          "#c5b0d5", "#8c564b", "#c49c94", "#e377c2", "#f7b6d2", "#7f7f7f", "#c7c7c7", "#bcbd22", "#dbdb8d",
          "#17becf", "#9edae5")


def vehicle_color(k: int) -> str:
    """Colour of vehicle ``k`` (0-based) as '#rrggbb'; vehicle k always gets the same one."""
    if k < len(PALETTE):
        return PALETTE[k]
    return _TAB20[(k - len(PALETTE)) % len(_TAB20)]


def vehicle_colors(n: int) -> list[str]:
    """``n`` colours, one per vehicle."""
    return [vehicle_color(k) for k in range(n)]
