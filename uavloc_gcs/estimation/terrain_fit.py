"""People on the ground's surface: the estimator's slant range over terrain (issue 28 item 3).

The ranging model (:mod:`.model`) takes the vehicle's height above the person, ``h``, from the
slots' z: over flat ground the launch point's height, so z (the altitude above the launch point)
is h. Over terrain the person stands on the ground where they are, ``ground(p) - ground(launch)``
above or below the launch point, so

    h = z - (ground(p) - ground(launch)),

which depends on the position p being estimated. :func:`estimate_on_terrain` solves it by a fixed
point: estimate with the launch point's height, take the DEM's height where the estimate puts the
person at each slot's time (a walker's track: position plus velocity times the time from the
reference), re-estimate with those heights above the person, and again (``ITERATIONS`` refits;
the height at a position off by e metres is off by e x the local slope, a second-order error in
the slant range). A vehicle
lower than the ground at the estimate (a phone up a slope above it) keeps h = 0, as the model's
own floor does.

Without a DEM nothing here is called: the flat estimator is bit-identical (paper reproduction).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..observations import SlotBatch

__all__ = ["estimate_on_terrain", "above_person", "ITERATIONS", "CONVERGED_M"]

ITERATIONS = 2
CONVERGED_M = 2.0  # the ground under the estimate moved less than this: a further refit changes nothing


def above_person(xyz_m: np.ndarray, person_ground_m) -> np.ndarray:
    """Vehicle positions with z made the height above a person standing ``person_ground_m``
    above (or below) the launch point: one height, or one per row (a walker's ground where they
    were at each row's time)."""
    out = np.array(xyz_m, dtype=float, copy=True).reshape(-1, 3)
    out[:, 2] = out[:, 2] - np.asarray(person_ground_m, dtype=float)
    return out


def estimate_on_terrain(slots: SlotBatch, channel, dem, *, estimate, censored=None, silence=None, **options):
    """``estimate(slots, channel, **options)`` (``estimate_emitter``) with the person on ``dem``'s
    ground (a :class:`~uavloc_gcs.terrain.Terrain` in the same local frame as the slots).

    A walker's ground is taken where the estimate's track puts them at each row's time (position
    plus velocity times the time from the estimate's reference), not where they are at the end:
    the mountains demo located walkers 80-190 m from the truth with 10-13 m radii, their earlier
    slots heard over ground tens of metres higher or lower than where they ended."""
    home = dem.height_at(0.0, 0.0, clamp=True)

    def ground(e, t_s) -> np.ndarray | None:  # the person's ground above the launch point at times t_s
        xy = getattr(e, "position_xy_m", None)
        t = np.asarray(t_s, dtype=float).reshape(-1)
        if xy is None or not np.all(np.isfinite(xy)):
            return None
        v = np.asarray(getattr(e, "velocity_m_s", None) if getattr(e, "model_motion", False) else (0.0, 0.0),
                       dtype=float)
        t_ref = float(getattr(e, "t_ref_s", np.nan))
        if not (np.all(np.isfinite(v)) and np.isfinite(t_ref)):
            v, t_ref = np.zeros(2), 0.0
        pts = np.asarray(xy, dtype=float)[:2] + np.outer(t - t_ref, v)
        return dem.height_xy(pts, clamp=True) - home

    def rows(e):  # the ground for the slots, the censored rows and the silences
        g = ground(e, slots.t_s)
        if g is None:
            return None
        gc = ground(e, censored.t_s) if censored is not None and len(censored) else None
        gs = ground(e, silence.t_s) if silence is not None and hasattr(silence, "xyz_m") and len(silence.xyz_m) \
            else None
        return g, gc, gs

    # Start from the ground under the previous estimate when there is one: the flat first pass put
    # a phone 300 m up the slope at the launch point's height, its ranges "contradicted the nominal
    # transmit power" and the estimator fitted that too -- 3 slow fits per person per update,
    # which idled the mountains demo for minutes of wall time (issue 28). Refits stop once the
    # ground under the estimate's track moves less than CONVERGED_M.
    est = None
    prev = options.get("previous")
    offset = rows(prev) if prev is not None else None
    if offset is None:
        est = estimate(slots, channel, censored=censored, silence=silence, **options)
        offset = rows(est)
        if offset is None:
            return est
    for _ in range(ITERATIONS):
        g, gc, gs = offset
        moved = dataclasses.replace(slots, xyz_m=above_person(slots.xyz_m, g))
        cen = (dataclasses.replace(censored, xyz_m=above_person(censored.xyz_m, gc))
               if gc is not None else censored)
        sil = dataclasses.replace(silence, xyz_m=above_person(silence.xyz_m, gs)) if gs is not None else silence
        opts = dict(options)
        if est is not None:
            opts["previous"] = est
        est = estimate(moved, channel, censored=cen, silence=sil, **opts)
        new = rows(est)
        if new is None or float(np.max(np.abs(new[0] - g), initial=0.0)) < CONVERGED_M:
            return est
        offset = new
    return est
