"""When a new plan is worth uploading to a vehicle that is already flying a look mission.

An upload is not free: each new mission sent to a flying vehicle costs flight time (ArduCopter
restarts its current leg, PX4 restarts the mission and the daemon switches it on), and on the
SITL runs of issue 14 a daemon that uploaded every small change of the plan kept its vehicles
crawling at 1-10 m/s. So a vehicle flying looks gets a new mission only when

* it would otherwise miss a person: a person added to its route, or an access point moved by more
  than the move tolerance (passing the old point is no longer a look), or
* the new route saves more flight time than the upload costs (:data:`UPLOAD_COST_S`, measured),

and never more than once between two of its looks (the daemon counts them). A first look mission
(the vehicle hovers after its scan, or is home) is always sent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# Flight seconds an upload + switch costs a vehicle flying at 10 m/s: the time of a 300 m leg
# with the daemon's mid-leg upload and switch minus the same leg without. Measured on the SITL
# builds in ../shared/sitl (speed-up 5) with `python -m benchmarks.upload_cost ardupilot px4`:
# ArduCopter legs 32.6/32.7 s without, 35.6 s with (it restarts the leg: brakes and accelerates
# again); PX4 legs 38.0/37.2 s without, 37.8 s with (it restarts the mission at the speed item
# and flies on to the same waypoint). Other autopilots: the larger one.
UPLOAD_COST_S = {"ardupilot": 3.0, "px4": 0.2}
DEFAULT_UPLOAD_COST_S = 3.0


@dataclass(frozen=True)
class UploadDecision:
    upload: bool
    reason: str


def route_time_s(start_xy_m, points_xy_m, speed_m_s: float) -> float:
    """Straight-line time [s] from ``start_xy_m`` through ``points_xy_m`` (k, 2)."""
    pts = np.vstack([np.asarray(start_xy_m, dtype=float).reshape(1, 2),
                     np.asarray(points_xy_m, dtype=float).reshape(-1, 2)])
    return float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1))) / speed_m_s


def decide_upload(*, flying_look: bool, uploads_since_look: int, position_xy_m,
                  old_targets: tuple, old_points_xy_m, new_targets: tuple, new_points_xy_m,
                  home_xy_m=(0.0, 0.0), speed_m_s: float, cost_s: float, move_tolerance_m: float,
                  same_tolerance_m: float) -> UploadDecision:
    """Whether to upload ``new_*`` (the looks still ahead in the new plan) to a vehicle whose
    mission still has ``old_*`` ahead of it. Points are (k, 2) local metres, one per target."""
    new_pts = np.asarray(new_points_xy_m, dtype=float).reshape(-1, 2)
    if not flying_look:
        return UploadDecision(True, "first look mission")
    old_pts = np.asarray(old_points_xy_m, dtype=float).reshape(-1, 2)
    if tuple(old_targets) == tuple(new_targets) and len(old_pts) == len(new_pts) and (
            len(new_pts) == 0 or np.all(np.linalg.norm(old_pts - new_pts, axis=1) <= same_tolerance_m)):
        return UploadDecision(False, "unchanged")
    if uploads_since_look >= 1:
        return UploadDecision(False, "already uploaded once since its last look")
    old_at = {t: p for t, p in zip(old_targets, old_pts)}
    added = [t for t in new_targets if t not in old_at]
    if added:
        return UploadDecision(True, f"new look(s) at {', '.join(map(str, added))}")
    moved = [t for t, p in zip(new_targets, new_pts) if float(np.hypot(*(p - old_at[t]))) > move_tolerance_m]
    if moved:
        return UploadDecision(True, f"look point(s) of {', '.join(map(str, moved))} moved more than "
                                    f"{move_tolerance_m:g} m")
    home = np.asarray(home_xy_m, dtype=float).reshape(1, 2)
    old_s = route_time_s(position_xy_m, np.vstack([old_pts, home]), speed_m_s)
    new_s = route_time_s(position_xy_m, np.vstack([new_pts, home]), speed_m_s)
    gain = old_s - new_s
    if gain > cost_s:
        return UploadDecision(True, f"saves {gain:.0f} s of flight (an upload costs {cost_s:g} s)")
    return UploadDecision(False, f"saves {gain:.0f} s, less than the {cost_s:g} s an upload costs" if math.isfinite(
        gain) else "no gain")
