"""People on the ground's surface: the estimator's slant range over terrain (issue 28 item 3).

The ranging model (:mod:`.model`) takes the vehicle's height above the person, ``h``, from the
slots' z: over flat ground the launch point's height, so z (the altitude above the launch point)
is h. Over terrain the person stands on the ground where they are, ``ground(p) - ground(launch)``
above or below the launch point, so

    h = z - (ground(p) - ground(launch)),

which depends on the position p being estimated. :func:`estimate_on_terrain` solves it by a fixed
point: estimate with the launch point's height, take the DEM's height at the estimate, re-estimate
with those heights above the person, and again (``ITERATIONS`` refits; the height at a position off
by e metres is off by e x the local slope, a second-order error in the slant range). A vehicle
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


def above_person(xyz_m: np.ndarray, person_ground_m: float) -> np.ndarray:
    """Vehicle positions with z made the height above a person standing ``person_ground_m``
    above (or below) the launch point."""
    out = np.array(xyz_m, dtype=float, copy=True).reshape(-1, 3)
    out[:, 2] = out[:, 2] - person_ground_m
    return out


def estimate_on_terrain(slots: SlotBatch, channel, dem, *, estimate, censored=None, silence=None, **options):
    """``estimate(slots, channel, **options)`` (``estimate_emitter``) with the person on ``dem``'s
    ground (a :class:`~uavloc_gcs.terrain.Terrain` in the same local frame as the slots)."""
    home = dem.height_at(0.0, 0.0, clamp=True)

    def ground(e) -> float | None:  # the person's ground above the launch point at estimate e
        xy = getattr(e, "position_xy_m", None)
        if xy is None or not np.all(np.isfinite(xy)):
            return None
        return float(dem.height_at(*map(float, np.asarray(xy)[:2]), clamp=True)) - home

    # Start from the ground under the previous estimate when there is one: the flat first pass put
    # a phone 300 m up the slope at the launch point's height, its ranges "contradicted the nominal
    # transmit power" and the estimator fitted that too -- 3 slow fits per person per update,
    # which idled the mountains demo for minutes of wall time (issue 28). Refits stop once the
    # ground under the estimate moves less than CONVERGED_M.
    est = None
    offset = ground(options.get("previous"))
    if offset is None:
        est = estimate(slots, channel, censored=censored, silence=silence, **options)
        offset = ground(est)
        if offset is None:
            return est
    for _ in range(ITERATIONS):
        moved = dataclasses.replace(slots, xyz_m=above_person(slots.xyz_m, offset))
        cen = (dataclasses.replace(censored, xyz_m=above_person(censored.xyz_m, offset))
               if censored is not None and len(censored) else censored)
        sil = silence
        if silence is not None and hasattr(silence, "xyz_m") and len(silence.xyz_m):
            sil = dataclasses.replace(silence, xyz_m=above_person(silence.xyz_m, offset))
        opts = dict(options)
        if est is not None:
            opts["previous"] = est
        est = estimate(moved, channel, censored=cen, silence=sil, **opts)
        new = ground(est)
        if new is None or abs(new - offset) < CONVERGED_M:
            return est
        offset = new
    return est
