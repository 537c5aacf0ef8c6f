"""People on the ground's surface: the estimator's slant range over terrain (issue 28 item 3).

The ranging model (:mod:`.model`) takes the vehicle's height above the person, ``h``, from the
slots' z: over flat ground the launch point's height, so z (the altitude above the launch point)
is h. Over terrain the person stands on the ground where they are, ``ground(p) - ground(launch)``
above or below the launch point, so

    h = z - (ground(p) - ground(launch)),

which depends on the position p being estimated. The fit keeps the person on the ground wherever
it moves them: each step of the fit takes the ground's height (and its gradient, for the
Jacobian) where the step puts the person at each slot's time (``Prepared.ground``, fed from
:class:`LocalGround`, the DEM resampled once around the data). The heights the slots carry are
taken on the previous estimate's track (a walker: position plus velocity times the time from the
reference), which is what the start points and the hearing bounds use; the first pass puts the
person on the ground under the vehicle that heard them. A refit on the new track follows while
that ground moves more than ``CONVERGED_M`` (at most ``ITERATIONS`` times), and the estimate with
the most posterior mass is kept.

Holding the heights fixed during a fit (uavloc's first terrain fit) let the fixed point settle
where the heights it had assumed agreed with a wrong position, with a radius that knew nothing of
how the ground changes under a moved person: walkers over the mountains scenario's slope ended
outside their 95 % circle 1 time in 5 (tests/terrain/test_people_on_terrain.py). Censored rows
and silences keep the heights of the estimate's track.

Without a DEM nothing here is called: the flat estimator is bit-identical (paper reproduction).
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from ..observations import SlotBatch

__all__ = ["estimate_on_terrain", "fit_for", "above_person", "LocalGround", "ITERATIONS", "CONVERGED_M"]

ITERATIONS = 4
CONVERGED_M = 2.0  # the ground under the estimate moved less than this: a further refit changes nothing
GROUND_MARGIN_M = 600.0  # the fit's ground reaches this far beyond where the slots were heard from
MAX_GROUND_MARGIN_M = 3000.0


def above_person(xyz_m: np.ndarray, person_ground_m) -> np.ndarray:
    """Vehicle positions with z made the height above a person standing ``person_ground_m``
    above (or below) the launch point: one height, or one per row (a walker's ground where they
    were at each row's time)."""
    out = np.array(xyz_m, dtype=float, copy=True).reshape(-1, 3)
    out[:, 2] = out[:, 2] - np.asarray(person_ground_m, dtype=float)
    return out


class LocalGround:
    """The DEM's ground [m above the launch point] resampled once on a local grid around the data,
    with its gradient: what the fit asks for at every step (a DEM lookup goes through the DEM's
    projection, about 20x slower). Bilinear between grid points half a DEM cell apart; beyond
    the grid, the nearest edge's height and zero slope."""

    def __init__(self, dem, lo_xy_m, hi_xy_m, home_m: float):
        self.step = max(0.5 * float(dem.resolution_m), 1.0)
        self.lo = np.floor(np.asarray(lo_xy_m, dtype=float) / self.step) * self.step
        n = np.maximum(np.ceil((np.asarray(hi_xy_m, dtype=float) - self.lo) / self.step).astype(int) + 1, 2)
        xs, ys = self.lo[0] + self.step * np.arange(n[0]), self.lo[1] + self.step * np.arange(n[1])
        gx, gy = np.meshgrid(xs, ys)  # rows: north, cols: east
        self.h = (dem.height_xy(np.column_stack([gx.ravel(), gy.ravel()]), clamp=True) - home_m).reshape(gx.shape)

    def height_gradient(self, xy_m) -> tuple[np.ndarray, np.ndarray]:
        """Heights (N,) and gradients (N, 2) at local points (N, 2)."""
        xy = np.asarray(xy_m, dtype=float).reshape(-1, 2)
        rows, cols = self.h.shape
        u = (xy - self.lo) / self.step
        inside = (u[:, 0] >= 0) & (u[:, 0] <= cols - 1) & (u[:, 1] >= 0) & (u[:, 1] <= rows - 1)
        cx, cy = np.clip(u[:, 0], 0.0, cols - 1.0), np.clip(u[:, 1], 0.0, rows - 1.0)
        c0, r0 = np.minimum(cx.astype(int), cols - 2), np.minimum(cy.astype(int), rows - 2)
        tx, ty = cx - c0, cy - r0
        h00, h01 = self.h[r0, c0], self.h[r0, c0 + 1]
        h10, h11 = self.h[r0 + 1, c0], self.h[r0 + 1, c0 + 1]
        z = (1 - ty) * ((1 - tx) * h00 + tx * h01) + ty * ((1 - tx) * h10 + tx * h11)
        dzdx = ((1 - ty) * (h01 - h00) + ty * (h11 - h10)) / self.step
        dzdy = ((1 - tx) * (h10 - h00) + tx * (h11 - h01)) / self.step
        grad = np.where(inside[:, None], np.column_stack([dzdx, dzdy]), 0.0)
        return z, grad


def fit_for(dem):
    """The estimator to call for a scenario: ``estimate_emitter`` on flat ground (``dem`` None),
    else :func:`estimate_on_terrain` on ``dem``'s ground, with the same arguments. Read from the
    package at each call, so that what the package holds is what runs."""
    from . import estimate_emitter

    if dem is None:
        return estimate_emitter
    return functools.partial(estimate_on_terrain, dem=dem, estimate=estimate_emitter)


def estimate_on_terrain(slots: SlotBatch, channel, dem, *, estimate, censored=None, silence=None, **options):
    """``estimate(slots, channel, **options)`` (``estimate_emitter``) with the person on ``dem``'s
    ground (a :class:`~uavloc_gcs.terrain.Terrain` in the same local frame as the slots).

    A walker's ground is taken where the estimate's track puts them at each row's time (position
    plus velocity times the time from the estimate's reference), not where they are at the end:
    the mountains demo located walkers 80-190 m from the truth with 10-13 m radii, their earlier
    slots heard over ground tens of metres higher or lower than where they ended."""
    home = dem.height_at(0.0, 0.0, clamp=True)

    def track(e, t_s) -> np.ndarray | None:  # where the estimate puts the person at times t_s
        xy = getattr(e, "position_xy_m", None)
        t = np.asarray(t_s, dtype=float).reshape(-1)
        if xy is None or not np.all(np.isfinite(xy)):
            return None
        v = np.asarray(getattr(e, "velocity_m_s", None) if getattr(e, "model_motion", False) else (0.0, 0.0),
                       dtype=float)
        t_ref = float(getattr(e, "t_ref_s", np.nan))
        if not (np.all(np.isfinite(v)) and np.isfinite(t_ref)):
            v, t_ref = np.zeros(2), 0.0
        return np.asarray(xy, dtype=float)[:2] + np.outer(t - t_ref, v)

    def ground(e, t_s) -> np.ndarray | None:  # the person's ground above the launch point at times t_s
        pts = track(e, t_s)
        return None if pts is None else dem.height_xy(pts, clamp=True) - home

    # the ground the fit moves the person on: around every place the slots were heard from, as
    # far as hearing reaches plus the walk the data span allows
    xyz = np.asarray(slots.xyz_m, dtype=float).reshape(-1, 3)
    span = float(np.ptp(slots.t_s)) if len(slots) else 0.0
    reach = min(GROUND_MARGIN_M + float(options.get("max_speed_m_s", 0.0)) * span, MAX_GROUND_MARGIN_M)
    local = LocalGround(dem, xyz[:, :2].min(axis=0) - reach, xyz[:, :2].max(axis=0) + reach, home) if len(xyz) \
        else None

    def surface(e):  # for the fit: the ground anywhere, against the ground on the estimate's track
        bases: dict = {}  # the ground on the track, per set of times (the slots', the bounds')
        last: list = []  # the last answer: the fit asks for residuals and Jacobian at one point

        def rise(t_s, xy):
            t, xy = np.asarray(t_s, dtype=float), np.asarray(xy, dtype=float)
            kt, kx = t.tobytes(), xy.tobytes()
            if last and last[0] == kt and last[1] == kx:
                return last[2]
            base = bases.get(kt)
            if base is None:
                if len(bases) > 16:
                    bases.clear()
                base = bases[kt] = local.height_gradient(track(e, t))[0]
            z, grad = local.height_gradient(xy)
            last[:] = [kt, kx, (z - base, grad)]
            return last[2]
        return rise if local is not None and track(e, slots.t_s[:1]) is not None else None

    def rows(e):  # the ground for the slots, the censored rows and the silences
        g = ground(e, slots.t_s)
        if g is None:
            return None
        gc = ground(e, censored.t_s) if censored is not None and len(censored) else None
        ge = (ground(e, censored.exposure.t_s) if censored is not None and getattr(censored, "exposure", None)
              is not None and len(censored.exposure) else None)
        gs = ground(e, silence.t_s) if silence is not None and hasattr(silence, "xyz_m") and len(silence.xyz_m) \
            else None
        return g, (gc, ge), gs

    # Start from the ground under the previous estimate when there is one: the flat first pass put
    # a phone 300 m up the slope at the launch point's height, its ranges "contradicted the nominal
    # transmit power" and the estimator fitted that too -- 3 slow fits per person per update,
    # which idled the mountains demo for minutes of wall time (issue 28). Refits stop once the
    # ground under the estimate's track moves less than CONVERGED_M.
    est = None
    prev = options.get("previous")
    offset = rows(prev) if prev is not None else None
    if offset is None:
        # first guess: each slot's person on the ground under the vehicle (within hearing range of
        # it), not at the launch point's height, which is hundreds of metres off up a valley side
        under = dem.height_xy(slots.xyz_m[:, :2], clamp=True) - home
        moved = dataclasses.replace(slots, xyz_m=above_person(slots.xyz_m, under))
        est = estimate(moved, channel, censored=censored, silence=silence, **options)
        offset = rows(est)
        if offset is None:
            return est
    best = None
    for _ in range(ITERATIONS):
        g, (gc, ge), gs = offset
        moved = dataclasses.replace(slots, xyz_m=above_person(slots.xyz_m, g))
        cen = (dataclasses.replace(censored, xyz_m=above_person(censored.xyz_m, gc))
               if gc is not None else censored)
        if ge is not None:  # the bursts nobody heard: the vehicles above the person there too
            cen = dataclasses.replace(cen, exposure=dataclasses.replace(
                cen.exposure, xyz_m=above_person(cen.exposure.xyz_m, ge)))
        sil = dataclasses.replace(silence, xyz_m=above_person(silence.xyz_m, gs)) if gs is not None else silence
        opts = dict(options)
        if est is not None:
            opts["previous"] = est
        ref = est if est is not None else prev
        est = estimate(moved, channel, censored=cen, silence=sil, ground=surface(ref), **opts)
        if best is None or _mass(est) > _mass(best):
            best = est
        new = rows(est)
        if new is None or float(np.max(np.abs(new[0] - g), initial=0.0)) < CONVERGED_M:
            break
        offset = new
    return best


def _mass(e) -> float:
    m = getattr(e, "log_mass", np.nan)
    return float(m) if np.isfinite(m) else -np.inf
