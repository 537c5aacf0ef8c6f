"""Terminal pictures and tables: the same geometry as :mod:`maps`, as characters.

:func:`char_map` rasterizes layers (outlines, routes, points) given in local metres onto a
character grid, north up, with a border and a scale line. Terminal cells are about twice as tall
as wide, so a row spans twice the metres of a column. :func:`format_table` right-aligns numbers.
Both return plain strings (no colour codes), so tests and logs can hold them.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Sequence

import numpy as np

__all__ = ["Layer", "char_map", "format_table"]

CELL_ASPECT = 2.0  # a character cell is about twice as tall as it is wide


@dataclass(frozen=True)
class Layer:
    """Geometry to draw: ``kind`` 'line' (polyline), 'ring' (closed outline) or 'points'.

    ``char`` is the character used; for 'points' with ``labels`` each point gets its own
    (first character of the label). Later layers draw over earlier ones.
    """

    xy_m: np.ndarray
    char: str
    kind: str = "line"
    labels: tuple = ()
    name: str = ""


def char_map(layers: Sequence[Layer], *, width: int = 72, max_height: int = 30) -> str:
    """Render ``layers`` onto a ``width``-column grid (border included), north up."""
    pts = [np.asarray(layer.xy_m, dtype=float).reshape(-1, 2) for layer in layers]
    allp = np.vstack([p for p in pts if len(p)] or [np.zeros((1, 2))])
    x0, y0 = allp.min(axis=0)
    x1, y1 = allp.max(axis=0)
    span_x, span_y = max(x1 - x0, 1e-9), max(y1 - y0, 1e-9)
    cols = max(width - 2, 8)
    m_per_col = max(span_x / (cols - 1), span_y / (CELL_ASPECT * (max_height - 4)), 1e-9)
    m_per_row = m_per_col * CELL_ASPECT
    cols = int(round(span_x / m_per_col)) + 1
    rows = int(round(span_y / m_per_row)) + 1
    grid = [[" "] * cols for _ in range(rows)]

    def cell(x: float, y: float) -> tuple[int, int]:
        c = int(round((x - x0) / m_per_col))
        r = rows - 1 - int(round((y - y0) / m_per_row))
        return min(max(r, 0), rows - 1), min(max(c, 0), cols - 1)

    def segment(a, b, ch: str) -> None:
        (r0, c0), (r1, c1) = cell(*a), cell(*b)
        n = max(abs(r1 - r0), abs(c1 - c0), 1)
        for k in range(n + 1):
            grid[round(r0 + (r1 - r0) * k / n)][round(c0 + (c1 - c0) * k / n)] = ch

    for layer, p in zip(layers, pts):
        if not len(p):
            continue
        if layer.kind == "points":
            for k, (x, y) in enumerate(p):
                r, c = cell(x, y)
                label = layer.labels[k] if k < len(layer.labels) else layer.char
                grid[r][c] = str(label)[:1] or layer.char
        else:
            seq = np.vstack([p, p[:1]]) if layer.kind == "ring" else p
            for a, b in zip(seq[:-1], seq[1:]):
                segment(a, b, layer.char)
            if len(seq) == 1:
                r, c = cell(*seq[0])
                grid[r][c] = layer.char
    lines = ["+" + "-" * cols + "+"]
    lines += ["|" + "".join(row) + "|" for row in grid]
    lines.append("+" + "-" * cols + "+")
    lines.append(_scale_line(m_per_col, cols))
    legend = [f"{layer.char} {layer.name}" for layer in layers if layer.name]
    if legend:
        lines.append("   ".join(legend))
    return "\n".join(lines)


def _scale_line(m_per_col: float, cols: int) -> str:
    target = m_per_col * min(cols, 40) / 2
    exp = 10 ** math.floor(math.log10(target)) if target > 0 else 1
    length = next(m * exp for m in (5, 2, 1) if m * exp <= target) if target >= exp else exp
    n = max(int(round(length / m_per_col)), 2)
    text = f"{length / 1000:g} km" if length >= 1000 else f"{length:g} m"
    return f" |{'-' * (n - 1)}| {text}   (north up; one column = {m_per_col:.0f} m)"


def format_table(headers: Sequence[str], rows: Sequence[Sequence], *, title: str | None = None) -> str:
    """A plain aligned table: numbers right-aligned, text left-aligned."""
    text = [[_cell(v) for v in row] for row in rows]
    widths = [max([len(h)] + [len(r[k]) for r in text]) for k, h in enumerate(headers)]
    numeric = [bool(rows) and all(_is_number(row[k]) for row in rows if row[k] != "") for k in range(len(headers))]

    def fmt(values: Sequence[str]) -> str:
        return "  ".join(v.rjust(w) if numeric[k] else v.ljust(w) for k, (v, w) in enumerate(zip(values, widths))).rstrip()

    out = [title] if title else []
    out += [fmt(headers), "  ".join("-" * w for w in widths)]
    out += [fmt(r) for r in text]
    return "\n".join(out)


_NUMERIC = re.compile(r"^[+-]?[\d.:,]+%?$")


def _is_number(v) -> bool:
    """Numbers, and strings that read as one (``"2.50"``, ``"1:38"``, ``"12%"``), align right."""
    if isinstance(v, str):
        return bool(_NUMERIC.match(v))
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)


def _cell(v) -> str:
    if isinstance(v, float) and math.isnan(v):
        return "-"
    return str(v)
