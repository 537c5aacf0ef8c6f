"""The scan's lanes as rows of intervals in a frame rotated to the lane direction (for :mod:`.scan`).

A row is a lane's offset across the area and the intervals of it inside the area polygon; rows are
laid out at the lane spacing (``layout_rows``), and where the area's shape leaves a sample of it
heard by fewer lanes than asked, lanes are added or moved until it is (``repair``, ``refine``).
``coverage_counts`` says how many lanes hear each point: the tests' and the scan's yardstick.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

_EDGE_INSET_M = 0.5  # double coverage: outer lanes this far inside the edge (clipping stays robust)


@dataclass(frozen=True)
class Rows:
    offsets: np.ndarray  # (n,) across-coordinate of each row
    intervals: tuple  # n lists of [a0, a1] along-intervals, sorted
    spacing_m: float


def rotation(theta: float) -> np.ndarray:
    """Matrix mapping xy -> (along, across) for lanes pointing at math angle ``theta``."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, s], [-s, c]])


def layout_rows(poly_r, spacing: float, mode: str) -> Rows:
    from shapely.geometry import LineString

    a_min, c_min, a_max, c_max = poly_r.bounds
    width = c_max - c_min
    if mode == "double":
        inset = min(_EDGE_INSET_M, width / 10.0)
        n = max(2, math.ceil((width - 2 * inset) / max(spacing - inset, 1e-9) - 1e-9) + 1)
        step = (width - 2 * inset) / (n - 1)
        offsets = c_min + inset + step * np.arange(n)
    else:
        n = max(1, math.ceil(width / spacing - 1e-9))
        step = width / n
        offsets = c_min + step * (np.arange(n) + 0.5)
    rows, offs = [], []
    for c in offsets:
        cut = poly_r.intersection(LineString([(a_min - 1.0, c), (a_max + 1.0, c)]))
        parts = [g for g in getattr(cut, "geoms", [cut]) if g.geom_type == "LineString" and g.length > 1e-3]
        ivs = sorted([min(g.coords[0][0], g.coords[-1][0]), max(g.coords[0][0], g.coords[-1][0])] for g in parts)
        if ivs:
            rows.append(ivs)
            offs.append(float(c))
    return Rows(np.array(offs), tuple(rows), float(step))


def sample_area(poly_r, step: float) -> np.ndarray:
    """Grid points inside the polygon plus points along its boundary, (K, 2) rotated frame."""
    import shapely

    a0, c0, a1, c1 = poly_r.bounds
    ga = np.arange(a0, a1 + step, step)
    gc = np.arange(c0, c1 + step, step)
    grid = np.array(np.meshgrid(ga, gc)).reshape(2, -1).T
    inside = grid[shapely.contains_xy(poly_r, grid[:, 0], grid[:, 1])]
    ring = poly_r.exterior
    k = max(4, int(ring.length / step))
    edge = np.array([ring.interpolate(t, normalized=True).coords[0] for t in np.linspace(0, 1, k, endpoint=False)])
    verts = np.asarray(ring.coords)
    return np.vstack([inside, edge, verts])


def coverage_counts(points_xy_m: np.ndarray, lanes_xy_m, range_m: float) -> np.ndarray:
    """How many lane segments pass within ``range_m`` of each point. (K,) ints."""
    p = np.asarray(points_xy_m, dtype=float).reshape(-1, 2)
    counts = np.zeros(len(p), dtype=int)
    for seg in lanes_xy_m:
        a, b = np.asarray(seg[0], float), np.asarray(seg[1], float)
        d = b - a
        L2 = float(d @ d)
        t = np.zeros(len(p)) if L2 == 0 else np.clip(((p - a) @ d) / L2, 0.0, 1.0)
        dist = np.linalg.norm(p - (a + t[:, None] * d), axis=1)
        counts += dist <= range_m + 1e-6
    return counts


def repair(rows: Rows, samples: np.ndarray, r: float, need: int, margin: float) -> Rows:
    """Lengthen lane ends until every sample is within ``r`` of ``need`` distinct rows.

    A lane is lengthened so that the sample ends up within ``r - margin`` of it, which also covers
    the points around the sample.
    """
    ivs = [[list(iv) for iv in row] for row in rows.intervals]
    for _ in range(3):
        changed = False
        for pa, pc in samples[_row_counts(rows.offsets, ivs, samples, r) < need]:
            dc = np.abs(rows.offsets - pc)
            near = [k for k in np.argsort(dc, kind="stable") if dc[k] <= r]
            covering = 0
            for k in near:
                reach = math.sqrt(max(r * r - dc[k] ** 2, 0.0))
                if any(a0 - reach <= pa <= a1 + reach for a0, a1 in ivs[k]):
                    covering += 1
            if covering >= need:
                continue
            for k in near:
                reach = math.sqrt(max(r * r - dc[k] ** 2, 0.0))
                if any(a0 - reach <= pa <= a1 + reach for a0, a1 in ivs[k]):
                    continue
                iv = min(ivs[k], key=lambda v: min(abs(v[0] - pa), abs(v[1] - pa)))
                # Extend to within (r - margin) of the sample so the points between samples
                # (up to ``margin`` away) are covered too.
                ext = math.sqrt(max((r - margin) ** 2 - dc[k] ** 2, 0.0))
                if pa < iv[0]:
                    iv[0] = pa + ext
                else:
                    iv[1] = pa - ext
                changed = True
                covering += 1
                if covering >= need:
                    break
        if not changed:
            break
    return Rows(rows.offsets, tuple(ivs), rows.spacing_m)


def _uncovered(poly_r, rows: Rows, r: float, need: int):
    """The part of the area heard from fewer than ``need`` rows, computed with polygons.

    Buffers are inscribed polygons of the true disks, so this errs on the side of "uncovered".
    """
    from shapely.geometry import LineString, Point
    from shapely.ops import unary_union

    def reach(row, c):
        return unary_union([(LineString([(a0, c), (a1, c)]) if a1 - a0 > 1e-9 else Point(a0, c)).buffer(r, 32)
                            for a0, a1 in row])

    regions = [reach(row, c) for row, c in zip(rows.intervals, rows.offsets)]
    if need == 1:
        covered = unary_union(regions)
    else:
        pairs = [regions[k].intersection(regions[m]) for k in range(len(regions))
                 for m in range(k + 1, len(regions)) if abs(rows.offsets[k] - rows.offsets[m]) < 2 * r]
        covered = unary_union(pairs) if pairs else None
    return poly_r if covered is None else poly_r.difference(covered)


def refine(rows: Rows, poly_r, r: float, need: int, step: float) -> Rows:
    """Close what sampling missed: lengthen lanes toward the points of the exactly computed
    uncovered region (its vertices and boundary) until nothing measurable is left."""
    for _ in range(6):
        gap = _uncovered(poly_r, rows, r - 0.05, need)
        if gap.is_empty or gap.area < 1e-4:
            break
        pts = []
        for g in getattr(gap, "geoms", [gap]):
            if g.geom_type != "Polygon":
                continue
            ring = g.exterior
            k = max(4, int(ring.length / step))
            pts += [ring.interpolate(t, normalized=True).coords[0] for t in np.linspace(0, 1, k, endpoint=False)]
            pts += list(ring.coords) + [g.representative_point().coords[0]]
        if not pts:
            break
        rows = repair(rows, np.array(pts), r - 0.1, need, margin=0.2)
    return rows


def _row_counts(offsets: np.ndarray, ivs: list, samples: np.ndarray, r: float) -> np.ndarray:
    """Number of distinct rows within ``r`` of each sample (rotated frame)."""
    counts = np.zeros(len(samples), dtype=int)
    for c, row in zip(offsets, ivs):
        dc = np.abs(samples[:, 1] - c)
        reach = np.sqrt(np.maximum(r * r - dc * dc, 0.0))
        hit = np.zeros(len(samples), dtype=bool)
        for a0, a1 in row:
            hit |= (samples[:, 0] >= a0 - reach) & (samples[:, 0] <= a1 + reach)
        counts += hit & (dc <= r)
    return counts


