"""Simulated people: piecewise-linear ground tracks inside the search area.

Every person's track is a list of knots (time, position); between knots the person walks in a
straight line at constant speed <= ``max_speed_m_s``; after the last knot they stand still. The
three motion models of SPEC §1:

- ``static``: one knot, never moves.
- ``constant_velocity``: a uniformly random heading and a speed uniform in [0, v_max]; the person
  walks straight until the area boundary and then stops there (clipped to the area).
- ``random_waypoint``: walk to a uniformly random point of the area at a speed uniform in
  [v_max/2, v_max], pause 0-30 s, repeat. Legs are drawn so they stay inside the area polygon (a
  concave area is never cut across), so positions never leave it.

Tracks are generated up to ``horizon_s`` seconds after mission start; beyond that everyone holds
their last position (missions last minutes, the default horizon is four hours).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import LineString, Polygon

MOTIONS = ("static", "constant_velocity", "random_waypoint")
RWP_MAX_PAUSE_S = 30.0
_MAX_TRIES = 200


@dataclass(frozen=True)
class Tracks:
    """S piecewise-linear tracks. ``knots_t_s[i]`` (K_i,) ascending, ``knots_xy_m[i]`` (K_i, 2)."""

    knots_t_s: tuple
    knots_xy_m: tuple

    def __post_init__(self) -> None:
        # padded (S, K) copies for vectorized lookups: padding repeats the last knot 1 s apart
        k = max([2] + [len(t) for t in self.knots_t_s])
        s = len(self.knots_t_s)
        kt, kxy = np.zeros((s, k)), np.zeros((s, k, 2))
        for i, (t, xy) in enumerate(zip(self.knots_t_s, self.knots_xy_m)):
            m = len(t)
            kt[i, :m], kxy[i, :m] = t, xy
            kt[i, m:] = t[-1] + np.arange(1, k - m + 1)
            kxy[i, m:] = xy[-1]
        object.__setattr__(self, "_kt", kt)
        object.__setattr__(self, "_kxy", kxy)
        last = np.array([len(t) - 1 for t in self.knots_t_s], dtype=int).reshape(-1, 1)
        object.__setattr__(self, "_real", np.arange(k - 1)[None, :] < last)  # (S, K-1) real segments

    def __len__(self) -> int:
        return len(self.knots_t_s)

    def _segment(self, tt: np.ndarray):
        """Per (time, person): segment index (T, S) and the fraction along it."""
        seg = np.sum(self._kt[None, :, :] <= tt[:, None, None], axis=2) - 1
        seg = np.clip(seg, 0, self._kt.shape[1] - 2)
        rows = np.arange(len(self))[None, :]
        t0, t1 = self._kt[rows, seg], self._kt[rows, seg + 1]
        frac = np.clip((tt[:, None] - t0) / (t1 - t0), 0.0, 1.0)
        return seg, frac, t0, t1

    def positions(self, t_s) -> np.ndarray:
        """Positions at time(s) t_s: (S, 2) for a scalar, (T, S, 2) for an array [m]."""
        t = np.asarray(t_s, dtype=float)
        tt = t.reshape(-1)
        if len(self) == 0:
            return np.zeros(t.shape + (0, 2))
        seg, frac, _, _ = self._segment(tt)
        rows = np.arange(len(self))[None, :]
        p0, p1 = self._kxy[rows, seg], self._kxy[rows, seg + 1]
        out = p0 + frac[..., None] * (p1 - p0)
        return out[0] if t.ndim == 0 else out.reshape(t.shape + (len(self), 2))

    def positions_of(self, person, t_s) -> np.ndarray:
        """Positions (F, 2) [m] of person[f] at time t_s[f]: one person per time, for sparse
        lookups (frames) where ``positions`` would evaluate everyone at every time."""
        person = np.asarray(person, dtype=int).reshape(-1)
        tt = np.asarray(t_s, dtype=float).reshape(-1)
        kt, kxy = self._kt[person], self._kxy[person]  # (F, K), (F, K, 2)
        seg = np.clip(np.sum(kt <= tt[:, None], axis=1) - 1, 0, kt.shape[1] - 2)
        rows = np.arange(len(person))
        t0, t1 = kt[rows, seg], kt[rows, seg + 1]
        frac = np.clip((tt - t0) / (t1 - t0), 0.0, 1.0)
        p0, p1 = kxy[rows, seg], kxy[rows, seg + 1]
        return p0 + frac[:, None] * (p1 - p0)

    def velocities(self, t_s) -> np.ndarray:
        """Velocities at time(s) t_s: (S, 2) or (T, S, 2) [m/s] (right derivative at knots)."""
        t = np.asarray(t_s, dtype=float)
        tt = t.reshape(-1)
        if len(self) == 0:
            return np.zeros(t.shape + (0, 2))
        seg, _, t0, t1 = self._segment(tt)
        rows = np.arange(len(self))[None, :]
        inside = (tt[:, None] >= t0) & (tt[:, None] < t1) & self._real[rows, seg]
        v = (self._kxy[rows, seg + 1] - self._kxy[rows, seg]) / (t1 - t0)[..., None]
        out = np.where(inside[..., None], v, 0.0)
        return out[0] if t.ndim == 0 else out.reshape(t.shape + (len(self), 2))


def sample_in_polygon(poly: Polygon, n: int, rng: np.random.Generator) -> np.ndarray:
    """n points uniform in the polygon (rejection from its bounding box) [m]."""
    x0, y0, x1, y1 = poly.bounds
    out = np.empty((0, 2))
    while len(out) < n:
        cand = rng.uniform([x0, y0], [x1, y1], size=(max(2 * (n - len(out)), 16), 2))
        inside = shapely.contains_xy(poly, cand[:, 0], cand[:, 1])
        out = np.vstack([out, cand[inside]])
    return out[:n]


def make_tracks(
    area_xy_m: np.ndarray,
    count: int,
    motion: str,
    max_speed_m_s: float,
    rng: np.random.Generator,
    *,
    horizon_s: float = 4 * 3600.0,
) -> Tracks:
    """Random people in the area with the given motion model (see module docstring)."""
    if motion not in MOTIONS:
        raise ValueError(f"unknown motion {motion!r}; expected one of {', '.join(MOTIONS)}")
    poly = Polygon(area_xy_m)
    start = sample_in_polygon(poly, count, rng)
    kt, kxy = [], []
    for p in start:
        if motion == "static" or max_speed_m_s <= 0:
            t, xy = np.array([0.0]), p[None, :]
        elif motion == "constant_velocity":
            heading = rng.uniform(0, 2 * np.pi)
            speed = rng.uniform(0, max_speed_m_s)
            t, xy = _straight_until_boundary(poly, p, speed * np.array([np.cos(heading), np.sin(heading)]),
                                             horizon_s)
        else:
            t, xy = _random_waypoint(poly, p, max_speed_m_s, rng, horizon_s)
        kt.append(t)
        kxy.append(xy)
    return Tracks(tuple(kt), tuple(kxy))


def constant_velocity_tracks(
    area_xy_m: np.ndarray, start_xy_m: np.ndarray, velocity_m_s: np.ndarray, *, horizon_s: float = 4 * 3600.0
) -> Tracks:
    """Explicit people: start positions (S, 2) walking at constant velocities (S, 2), stopping at the
    area boundary. Start points outside the area are kept where they are (and stay there)."""
    poly = Polygon(area_xy_m)
    start = np.asarray(start_xy_m, dtype=float).reshape(-1, 2)
    vel = np.asarray(velocity_m_s, dtype=float).reshape(-1, 2)
    kt, kxy = [], []
    for p, v in zip(start, vel):
        if not np.any(v) or not poly.covers(shapely.Point(p)):
            t, xy = np.array([0.0]), p[None, :]
        else:
            t, xy = _straight_until_boundary(poly, p, v, horizon_s)
        kt.append(t)
        kxy.append(xy)
    return Tracks(tuple(kt), tuple(kxy))


def _straight_until_boundary(poly: Polygon, p: np.ndarray, v: np.ndarray, horizon_s: float):
    speed = float(np.hypot(*v))
    if speed == 0.0:
        return np.array([0.0]), p[None, :]
    end = p + v * horizon_s
    ray = LineString([p, end])
    hit = ray.intersection(poly.exterior)
    t_exit = horizon_s
    if not hit.is_empty:
        pts = np.asarray([g.coords[0] for g in getattr(hit, "geoms", [hit])] if hit.geom_type != "LineString"
                         else hit.coords)
        dist = np.hypot(*(pts - p).T)
        dist = dist[dist > 1e-9]
        if dist.size:
            t_exit = min(horizon_s, float(dist.min()) / speed)
    return np.array([0.0, t_exit]), np.vstack([p, p + v * t_exit])


def _random_waypoint(poly: Polygon, p: np.ndarray, vmax: float, rng: np.random.Generator, horizon_s: float):
    t_list, xy_list = [0.0], [p]
    t = 0.0
    while t < horizon_s:
        for _ in range(_MAX_TRIES):
            q = sample_in_polygon(poly, 1, rng)[0]
            if poly.covers(LineString([p, q])):
                break
        else:  # nowhere visible: wait in place
            q = p
        speed = rng.uniform(0.5 * vmax, vmax)
        dt = float(np.hypot(*(q - p))) / speed
        t += max(dt, 1e-6)
        t_list.append(t)
        xy_list.append(q)
        pause = rng.uniform(0, RWP_MAX_PAUSE_S)
        if pause > 0:
            t += pause
            t_list.append(t)
            xy_list.append(q)
        p = q
    return np.array(t_list), np.array(xy_list)
