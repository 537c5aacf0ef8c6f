"""Heights as data of the flight (issue 41 item 2): how low a look may fly, below which height a
vehicle is taking off or landing, and what a look's descent and climb cost in time and energy.

A look flies at its own height ``alt_m`` (None: the survey altitude ``fleet.altitude_m``): the
vehicle transits at the survey altitude, descends at the look's entry point, flies the look there
and climbs back before transiting on (``mission.flight_mission``, ``search.orbit.look_mission``).
Heights are above the ground under the people (flat ground: the launch point's; over a DEM the
terrain missions keep them above the ground under the vehicle).

* **The look floor** (:func:`look_floor_m`): ``search.look_min_height_m`` above what stands on the
  ground (``terrain.obstacle_height_m``); over a DEM at least ``terrain.min_clearance_m`` above it,
  which every leg keeps. A look asked below it is refused (:func:`check_look_alt`).
* **Airborne** (:func:`airborne_floor_m`): half the lowest height the search flies on purpose (the
  looks' ``search.look_height_m``, or the survey altitude when that is lower or no look height is
  asked). Slots heard and positions flown below it
  are a vehicle taking off, landing or on the ground, and are neither estimated from nor counted as
  searched. Half, because a vehicle holding a planned height stays within a few metres of it (the
  SITL look flights of ``tests/sitl/test_orbits.py`` held the ring's height within 1-2 m), so no
  slot of a look is lost to altitude noise, while a vehicle below half of it is within seconds
  of the ground (15 m for looks at the 30 m floor: 6 s at ArduCopter's 2.5 m/s climb). The rule it
  generalises (half the survey altitude, ``MIN_ALTITUDE_FRACTION``) would have thrown a look at 30 m
  away as "taking off"; with no look height asked it is that rule.
* **Time and energy of the altitude change** (:func:`vertical_s`, :func:`vertical_energy_j`): down
  at ``terrain.max_descent_m_s`` and up at ``terrain.max_climb_m_s`` (the rates missions are planned
  within: ArduCopter's WPNAV_SPEED_DN / _UP 1.5 / 2.5 m/s, PX4's MPC_Z_VEL_MAX_DN / _UP 1.5 / 3 m/s),
  at the hover power P(0) of Zeng's model plus the climb's work W dh (energy.RotorcraftPower, the
  climb term the terrain missions use); a descent recovers nothing.
"""

from __future__ import annotations

import math

import numpy as np

from .errors import InfeasibleError

AIRBORNE_SHARE = 0.5  # of the lowest height flown on purpose: below it a vehicle takes off or lands
SAME_HEIGHT_M = 0.5  # a look within this of the survey altitude is flown at it (no descent, no climb)


def survey_alt_m(sc) -> float:
    """The survey (transit) altitude [m above the ground]: ``fleet.altitude_m``."""
    return float(sc.fleet.altitude_m)


def look_alt_m(sc, alt_m: float | None) -> float:
    """The height [m] a look flies at: ``alt_m``, or the survey altitude for None."""
    return survey_alt_m(sc) if alt_m is None else float(alt_m)


def changes_height(sc, alt_m: float | None) -> bool:
    """Whether a look at ``alt_m`` leaves the survey altitude (a descent and a climb back)."""
    return alt_m is not None and abs(float(alt_m) - survey_alt_m(sc)) > SAME_HEIGHT_M


def look_floor_m(sc) -> float:
    """The least height [m above the ground] a look may fly (see the module's doc)."""
    t = sc.terrain
    clearance = t.min_clearance_m if t.dem else 0.0
    return float(t.obstacle_height_m + max(sc.search.look_min_height_m, clearance))


def planned_look_alt_m(sc) -> float:
    """The height [m] the policy's looks fly at: ``search.look_height_m``, or the survey altitude."""
    return look_alt_m(sc, sc.search.look_height_m)


def airborne_floor_m(sc) -> float:
    """Height [m above the ground] below which a vehicle is taking off, landing or on the ground:
    half the lowest height the search flies on purpose, the survey's or its looks'
    (``search.look_height_m``). With no look height asked this is half the survey altitude, the
    rule of before issue 41 (``MIN_ALTITUDE_FRACTION``), so those scenarios keep every slot choice.
    Where phones send BLE beacons their looks fly at the look floor (uavloc_gcs.radios.ble_view)."""
    lowest = min(survey_alt_m(sc), planned_look_alt_m(sc))
    if getattr(sc.emission, "findmy_share", 0.0) > 0:  # BLE identities are looked at from the floor
        lowest = min(lowest, look_floor_m(sc))
    return AIRBORNE_SHARE * lowest


def check_look_alt(sc, alt_m: float | None, what: str = "a look") -> float:
    """The height ``alt_m`` of ``what`` [m], checked: finite, and not below :func:`look_floor_m`
    (one sentence naming the keys otherwise, InfeasibleError). None: the survey altitude."""
    if alt_m is None:
        return survey_alt_m(sc)
    alt = float(alt_m)
    floor = look_floor_m(sc)
    if not math.isfinite(alt):
        raise InfeasibleError(f"{what}: its height {alt_m} is not a number of metres; not flown")
    if alt < floor - 1e-9:
        t = sc.terrain
        raise InfeasibleError(
            f"{what} at {alt:g} m is below the look floor of {floor:g} m above the ground (search.look_min_height_m = "
            f"{sc.search.look_min_height_m:g} m above terrain.obstacle_height_m = {t.obstacle_height_m:g} m"
            + (f", at least terrain.min_clearance_m = {t.min_clearance_m:g} m over the DEM" if t.dem else "")
            + "); not flown")
    return alt


def vertical_s(sc, alt_m: float | None, transit_alt_m: float | None = None) -> float:
    """Seconds to go from the transit altitude (default: the survey's) to ``alt_m`` and back, at
    the planned descent and climb rates (0 for a look at the transit altitude)."""
    top = survey_alt_m(sc) if transit_alt_m is None else float(transit_alt_m)
    if alt_m is None or abs(float(alt_m) - top) <= SAME_HEIGHT_M:
        return 0.0
    dh = abs(top - float(alt_m))
    return dh / sc.terrain.max_descent_m_s + dh / sc.terrain.max_climb_m_s


def vertical_energy_j(sc, alt_m: float | None, transit_alt_m: float | None = None) -> float:
    """Energy [J] of that descent and climb: hovering power for :func:`vertical_s` plus the climb's
    work W dh (energy.RotorcraftPower.climb_energy_j; descents recover nothing)."""
    t = vertical_s(sc, alt_m, transit_alt_m)
    if t == 0.0:
        return 0.0
    top = survey_alt_m(sc) if transit_alt_m is None else float(transit_alt_m)
    pw = sc.power_model
    return float(pw.hover_power_w() * t + pw.climb_energy_j([top, float(alt_m), top]))


def height_above_ground_m(xyz_m, dem=None) -> np.ndarray:
    """Each position's height [m] above the ground under it: z (above the launch point) over flat
    ground; over a DEM (``uavloc_gcs.terrain.Terrain``) z less the ground's rise from the launch
    point, so a vehicle 100 m above a valley below the launch point (z < 0) is 100 m up."""
    xyz = np.asarray(xyz_m, float).reshape(-1, 3)
    if dem is None or not len(xyz):
        return xyz[:, 2].copy()
    out = np.full(len(xyz), np.nan)
    ok = np.all(np.isfinite(xyz[:, :2]), axis=1)  # no ground under an unknown position
    if np.any(ok):
        ground = dem.height_xy(xyz[ok, :2], clamp=True) - dem.height_at(0.0, 0.0, clamp=True)
        out[ok] = xyz[ok, 2] - ground
    return out


def airborne(xyz_m, floor_m: float, dem=None) -> np.ndarray:
    """Which positions (N, 3) are at or above ``floor_m`` [m] over the ground under them."""
    return height_above_ground_m(xyz_m, dem) >= floor_m
