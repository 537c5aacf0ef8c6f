"""Orbit looks: a vehicle circles a person heard in bursts long enough to catch their next bursts.

A fly-by crosses a phone's hearing disk in seconds; a phone that probes every 20-270 s is then
usually silent (issue 25). An *orbit look* is a non-hovering circle of radius ``radius_m`` around
the person's predicted position, flown for ``dwell_s`` seconds: long enough that the phone sends
``k`` bursts with probability ``p`` (search.burst_timing.BurstTiming) and, divided by the mean probability
that a burst sent while the vehicle is on the circle is heard (search.pod.p_burst_heard), that
they are heard. What each autopilot flies was measured on SITL (docs/science/looks.md,
``python -m tests.sitl.orbit_measure``):

* ArduCopter flies NAV_LOITER_TURNS as a true circle (radius held to about 1 m at 60 m), clockwise
  for a positive radius, at the speed its circle controller allows (7.9 m/s at 60 m with the stock
  parameters), entering at the circle's point nearest to where it comes from and leaving there
  after the whole turns;
* PX4 (multicopter) refuses NAV_LOITER_TURNS in a mission (MAV_MISSION_UNSUPPORTED), so it flies a
  ring of pass-through waypoints; it slows at every corner (4.9 m/s mean on a 12-point, 60 m ring
  asked for 10 m/s).

The form per autopilot is :data:`ORBIT_FORM` (a ring for both: see there); both forms start and end
at the entry point (whole turns), so the router may treat an orbit as an access point on the circle
plus a service time.

Radius: the horizontal distance that gives the most position information per burst, averaged over
where the person may be (the estimate's spread) and where on the circle the vehicle is when the
phone speaks: information of one RSSI range about the horizontal position grows as rho^2 / d^4
(rho horizontal, d 3-D distance; largest at rho = altitude) and is only gained when the burst is
heard (p_burst_heard), so :func:`orbit_radius_m` maximises E[p_heard(d) rho^2 / d^4].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .look_mission import NAV_LOITER_TURNS  # noqa: F401 (its home before issue 41)

# How each autopilot flies an orbit (measured, docs/science/looks.md). A ring of waypoints is what
# both fly (PX4 refuses NAV_LOITER_TURNS), so it is the shipped form for both; ArduCopter flies
# NAV_LOITER_TURNS better (a true circle, faster) and ``"loiter-turns"`` selects it (uavloc's fake
# ArduPilot flies it as the SITL does since 2026-11-26; before, it hovered at the centre for ever).
ORBIT_FORM = {"ardupilot": "ring", "px4": "ring"}
RING_POINTS_PER_TURN = 12
# Speeds measured on SITL around a 60 m circle with 10 m/s asked (docs/science/looks.md): the
# planner's orbit speed is min(cruise, this, sqrt(a_c * r)) with a_c the centripetal acceleration
# the measured speed implies; energy and dwell are counted at that speed.
ORBIT_SPEED_M_S = {"loiter-turns": 7.9, "ring": 4.9}
ORBIT_MEASURED_RADIUS_M = 60.0
# Bursts an orbit waits for and the probability it catches them (k, p): one heard burst locates
# nobody in the field world, two or three give a fix of 116-153 m RMSE (docs/science/estimator.md),
# so an orbit asks for two.
ORBIT_BURSTS = 2
ORBIT_P = 0.5
MAX_DWELL_S = 600.0  # one orbit never waits longer than this (a phone in a long silence is missed)
MIN_RADIUS_M = 20.0


@dataclass(frozen=True)
class OrbitLook:
    """One orbit: centre and entry point [m, local frame], radius [m], dwell [s], speed [m/s], and
    the height it is flown at [m above the ground]; None: the survey altitude (uavloc_gcs/heights.py:
    the vehicle goes down to it at the entry and back up after the whole turns)."""

    centre_xy_m: tuple[float, float]
    radius_m: float
    dwell_s: float
    speed_m_s: float
    form: str = "ring"
    alt_m: float | None = None

    @property
    def turns(self) -> int:
        """Whole turns that last at least ``dwell_s`` at ``speed_m_s``."""
        per_turn = 2 * math.pi * self.radius_m / max(self.speed_m_s, 1e-6)
        return max(1, math.ceil(self.dwell_s / per_turn - 1e-9))

    @property
    def flown_s(self) -> float:
        """Time on the circle [s] (whole turns)."""
        return self.turns * 2 * math.pi * self.radius_m / max(self.speed_m_s, 1e-6)

    def entry_xy_m(self, from_xy_m) -> np.ndarray:
        """Where the vehicle joins the circle coming from ``from_xy_m`` (the nearest point)."""
        c = np.asarray(self.centre_xy_m, float)
        d = np.asarray(from_xy_m, float)[:2] - c
        n = float(np.hypot(*d))
        u = d / n if n > 1e-9 else np.array([1.0, 0.0])
        return c + self.radius_m * u

    def ring_xy_m(self, entry_xy_m, points_per_turn: int = RING_POINTS_PER_TURN,
                  clockwise: bool = True) -> np.ndarray:
        """(turns * points_per_turn + 1, 2) points of the ring from the entry round to it again."""
        c = np.asarray(self.centre_xy_m, float)
        e = np.asarray(entry_xy_m, float) - c
        a0 = math.atan2(e[1], e[0])
        sign = -1.0 if clockwise else 1.0
        k = np.arange(self.turns * points_per_turn + 1)
        a = a0 + sign * 2 * math.pi * k / points_per_turn
        return c + self.radius_m * np.column_stack([np.cos(a), np.sin(a)])

    def path_xy_m(self, from_xy_m, points_per_turn: int = 36) -> np.ndarray:
        """The circle as flown, for simulators: entry, then ``turns`` turns back to it."""
        return self.ring_xy_m(self.entry_xy_m(from_xy_m), points_per_turn)


# Ring of waypoints: both autopilots accelerate and brake on every leg, so the speed grows with the
# leg length L, about sqrt(RING_SPEED_K * L) (measured 3.5-6.1 m/s on 16-31 m legs, K 0.5-1.3, median 0.8;
# docs/science/looks.md).
RING_SPEED_K_M_S2 = 0.8


def orbit_speed_m_s(form: str, radius_m: float, cruise_m_s: float,
                    points_per_turn: int = RING_POINTS_PER_TURN) -> float:
    """The speed [m/s] an orbit of ``radius_m`` is flown at. NAV_LOITER_TURNS (ArduCopter): the
    centripetal acceleration the 60 m measurement implies (7.9 m/s: 1.04 m/s^2), v = sqrt(a r),
    at most the cruise speed (measured 9.4 m/s at 120 m, its 10 m/s limit). Ring: see
    RING_SPEED_K_M_S2."""
    if form == "loiter-turns":
        v0 = ORBIT_SPEED_M_S["loiter-turns"]
        a_c = v0 * v0 / ORBIT_MEASURED_RADIUS_M
        return float(min(cruise_m_s, math.sqrt(a_c * max(radius_m, 1.0))))
    leg = 2.0 * radius_m * math.sin(math.pi / points_per_turn)
    return float(min(cruise_m_s, math.sqrt(RING_SPEED_K_M_S2 * max(leg, 1.0))))


_HEARD_CACHE: dict = {}


def elicited(sc) -> bool:
    """Whether the scenario's phones answer an on-board access point (``emission.elicitation_rate_hz``):
    then a look waits for frames the access point asks for, not for the phone's next bursts."""
    return (sc.emission.model == "probe-bursts" and sc.emission.elicitation_rate_hz > 0
            and sc.channel.receiver_sensitivity_dbm is not None)


def _look_h(sc) -> float:
    """The height [m] the policy's looks fly at (``search.look_height_m``, or the survey altitude)."""
    from ..heights import planned_look_alt_m

    return planned_look_alt_m(sc)


def _heard_key(sc) -> tuple:
    return (repr(sc.channel), repr(sc.emission), repr(sc.simulation), sc.fleet.comm_range_m, _look_h(sc))


def _p_heard_table(sc):
    """At the looks' height (``search.look_height_m``, or the survey altitude) on a grid of horizontal distances (cached): p_burst_heard, or
    under elicitation the probability that one elicited frame is heard (pod.elicited_rate_hz over
    the rate: the phone answers within the access point's range, each frame heard above the
    sensitivity)."""
    from .pod import elicited_rate_hz, p_burst_heard

    key = _heard_key(sc)
    if key not in _HEARD_CACHE:
        grid = np.linspace(0.0, 4.0 * max(float(sc.horizontal_range_m), 50.0) + 200.0, 241)
        h = _look_h(sc)
        if elicited(sc):
            table = elicited_rate_hz(sc, np.hypot(grid, h), height_m=h) / sc.emission.elicitation_rate_hz
        else:
            table = p_burst_heard(sc, grid, h)
        _HEARD_CACHE[key] = (grid, np.asarray(table, float))
    return _HEARD_CACHE[key]


def _circle_geometry(sc, radius_m: float, spread_m: float, draws: int, seed: int):
    grid, table = _p_heard_table(sc)
    rng = np.random.default_rng(seed)
    off = rng.standard_normal((draws, 2)) * max(float(spread_m), 0.0)
    ang = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    veh = radius_m * np.column_stack([np.cos(ang), np.sin(ang)])  # (A, 2)
    rel = veh[None, :, :] - off[:, None, :]  # (D, A, 2) person -> vehicle, horizontal
    rho = np.linalg.norm(rel, axis=2)
    ph = np.interp(rho, grid, table, right=0.0)
    return rel, rho, ph


_RADIUS_CACHE: dict = {}


def orbit_radius_m(sc, spread_m: float, *, draws: int = 300, seed: int = 0) -> float:
    """The orbit radius [m] of most expected information per burst for a person whose position is
    known to ``spread_m`` (1-sigma per axis, the estimate's), at the looks' height and the
    scenario's receiver. For a person at offset delta from the centre the Fisher information of the heard
    bursts about their horizontal position, averaged over the circle, is
    J(delta) = mean_theta p_heard(rho) (rho^2 / d^4) u u^T (u the unit vector from person to
    vehicle; one RSS range informs only along it); the radius maximises E_delta sqrt(det J), the
    D-optimal design (a circle the person is outside of sees them from a narrow fan of bearings
    and scores low). Deterministic; cached per 5 m of spread."""
    h = _look_h(sc)
    spread = 5.0 * round(max(float(spread_m), 0.0) / 5.0)
    key = (_heard_key(sc), spread)  # not id(sc): a new scenario may get a collected one's id
    if key in _RADIUS_CACHE:
        return _RADIUS_CACHE[key]
    rng_h = max(float(sc.horizontal_range_m), MIN_RADIUS_M + 1.0)
    best, best_r = -1.0, MIN_RADIUS_M
    for r in np.linspace(MIN_RADIUS_M, 1.5 * rng_h, 30):
        rel, rho, ph = _circle_geometry(sc, float(r), spread, draws, seed)
        d2 = rho * rho + h * h
        w = ph / (d2 * d2)  # (D, A): p_heard * rho^2 / d^4 / rho^2, times rel rel^T below
        jxx = np.mean(w * rel[..., 0] ** 2, axis=1)
        jyy = np.mean(w * rel[..., 1] ** 2, axis=1)
        jxy = np.mean(w * rel[..., 0] * rel[..., 1], axis=1)
        score = float(np.mean(np.sqrt(np.maximum(jxx * jyy - jxy * jxy, 0.0))))
        if score > best:
            best, best_r = score, float(r)
    _RADIUS_CACHE[key] = best_r
    return best_r


def mean_p_heard(sc, radius_m: float, spread_m: float, *, draws: int = 300, seed: int = 0) -> float:
    """Mean probability that a burst sent while the vehicle is on the circle is heard."""
    return float(np.mean(_circle_geometry(sc, radius_m, spread_m, draws, seed)[2]))


_DWELL_CACHE: dict = {}


JOIN_P = 0.6  # a look at a phone that joins the access point at a burst waits for one with this probability
# (0.7 takes 415 s in the field world, 0.75 past MAX_DWELL_S: the population includes phones in long silences)


def join_wait_s(sc) -> float:
    """Seconds within reach of the access point in which the phone sends a burst (and so joins a
    mimicked network, ``emission.elicitation_join = "scan"``) with probability JOIN_P."""
    return dwell_s(sc, 1.0, 1, JOIN_P)


def dwell_s(sc, p_heard: float, k: int = ORBIT_BURSTS, p: float = ORBIT_P) -> float:
    """Seconds on the circle to hear ``k`` bursts with probability ``p``: the window in which the
    phone sends k bursts with probability p (burst_timing.BurstTiming.window_for), stretched by the share
    of bursts the circle hears (a thinning of the burst process), at most MAX_DWELL_S."""
    from .burst_timing import BurstTiming

    key = (repr(sc.emission), sc.channel.slot_s, k, p)
    if key not in _DWELL_CACHE:
        _DWELL_CACHE[key] = BurstTiming.from_scenario(sc).window_for(k, p)
    w = _DWELL_CACHE[key]
    if not math.isfinite(w):
        return MAX_DWELL_S
    return float(min(w / max(p_heard, 1e-3), MAX_DWELL_S))


# Frames an elicited look asks for, as a multiple of what the horizontal position alone would need
# for the required accuracy (elicited_dwell_s). The estimator also fits velocity and transmit power
# from them, but the look's frames add to those the scan heard; 1 was measured (docs/science/looks.md:
# `uavloc bench field --elicitation 2 --trapped`), 2 asked for about 10 minutes a look.
ELICITED_INFO_MARGIN = 1.0


def elicited_dwell_s(sc, radius_m: float, spread_m: float, *, draws: int = 300, seed: int = 0,
                     speed_m_s: float | None = None, cap: bool = True) -> float:
    """Seconds on the circle for the frames an on-board access point elicits to place the person
    within ``people.required_accuracy_m`` (95 %): per frame the phone is asked for, the Fisher
    information about its horizontal position, averaged over the circle and where the person may
    be, is E[p_heard(d) (rho/d^2)^2 u u^T] / sigma_ln^2 (sigma_ln: one frame's log-range std); the
    frames needed are the worst axis's variance over the target's ((required/2.45)^2, a 2-D
    normal's 95 % circle), times ELICITED_INFO_MARGIN; divided by the elicitation rate; at most
    MAX_DWELL_S. At 2 Hz, 100 m up, 4 dB: about 280 s for 15 m (the paper's continuous
    emitter, 400 samples/s, would need about a second). Under the air-to-ground channel frames
    heard a few metres apart share their shadowing and the estimator weighs each by what it adds
    (estimation.burst_grid.unit_weights): with the vehicle at ``speed_m_s`` on the circle, the
    frames needed are divided by that weight: rho = exp(-speed / rate / decorrelation_m), at the
    bearing's turn about the centre between two frames, with the line-of-sight fading's own share
    (burst_grid.unit_weight)."""
    from ..estimation.model import ChannelModel

    rel, rho, ph = _circle_geometry(sc, radius_m, spread_m, draws, seed)
    h = _look_h(sc)
    d2 = rho * rho + h * h
    s_ln = ChannelModel.from_scenario(sc).log_range_sigma
    w = ph / (d2 * d2) / (s_ln * s_ln)
    j = np.array([[np.mean(w * rel[..., 0] ** 2), np.mean(w * rel[..., 0] * rel[..., 1])],
                  [np.mean(w * rel[..., 0] * rel[..., 1]), np.mean(w * rel[..., 1] ** 2)]])
    lo = float(np.min(np.linalg.eigvalsh(j)))
    if lo <= 0:
        return MAX_DWELL_S if cap else math.inf
    target = sc.people.required_accuracy_m / 2.45
    frames = ELICITED_INFO_MARGIN / (lo * target * target)
    rate = sc.emission.elicitation_rate_hz
    env = getattr(sc.channel, "environment", None)
    if env is not None and speed_m_s is not None and speed_m_s > 0:
        from ..a2g import ENVIRONMENTS, fading_law
        from ..estimation.burst_grid import BEARING_WEIGHTS, unit_weight

        e = ENVIRONMENTS[env]
        fade = fading_law(e.rician_k_los_db).std_db
        step = float(speed_m_s) / rate
        rho = math.exp(-step / e.decorrelation_m)
        omega = min(step / max(float(radius_m), 1e-6), math.pi) if BEARING_WEIGHTS else 0.0
        frames /= max(unit_weight(rho, e.shadow_los_db ** 2, float(fade) ** 2, omega=omega), 1e-6)
    return float(min(frames / rate, MAX_DWELL_S) if cap else frames / rate)


_QUICK_CACHE: dict = {}


def _quickest_elicited_orbit(sc, form: str, spread: float, r0: float, v0: float) -> tuple[float, float, float]:
    """(radius, speed, dwell) of the orbit that gathers the accuracy asked for soonest from a
    stream of single frames (elicited, or BLE beacons): under the air-to-ground channel frames a
    few metres apart add little (elicited_dwell_s), so a wider, faster circle can beat the radius
    of most information per frame (``r0``, orbit_radius_m). Cached per 5 m of spread."""
    key = (_heard_key(sc), 5.0 * round(spread / 5.0), form, repr(sc.people))
    hit = _QUICK_CACHE.get(key)
    if hit is None:
        best = (elicited_dwell_s(sc, r0, spread, speed_m_s=v0, cap=False), r0, v0)
        if getattr(sc.channel, "environment", None) is not None:
            rng_h = max(float(sc.horizontal_range_m), MIN_RADIUS_M + 1.0)
            for r in np.linspace(MIN_RADIUS_M, 1.5 * rng_h, 30):
                v = orbit_speed_m_s(form, float(r), sc.fleet.speed_m_s)
                d = elicited_dwell_s(sc, float(r), spread, speed_m_s=v, cap=False)
                if d < best[0] - 1e-9:  # (uncapped: a circle that needs less, even past the cap)
                    best = (d, float(r), v)
        hit = _QUICK_CACHE[key] = (best[1], best[2], float(min(best[0], MAX_DWELL_S)))
    return hit


def plan_orbit(sc, centre_xy_m, spread_m: float, autopilot: str | None = None,
               k: int = ORBIT_BURSTS, p: float = ORBIT_P) -> OrbitLook:
    """The orbit look at ``centre_xy_m`` for a person known to ``spread_m`` (1-sigma) [m]: long
    enough to catch ``k`` bursts with probability ``p``, or under elicitation the frames the
    required accuracy needs (:func:`elicited_dwell_s`); at ``search.look_height_m`` (the radius and
    dwell are those of that height; None, the default: the survey altitude)."""
    form = ORBIT_FORM.get(autopilot or sc.fleet.autopilot, "ring")
    spread = float(min(max(spread_m, 0.0), sc.horizontal_range_m)) if math.isfinite(spread_m) else sc.horizontal_range_m
    r = orbit_radius_m(sc, spread)
    v = orbit_speed_m_s(form, r, sc.fleet.speed_m_s)
    if elicited(sc):
        r, v, dwell = _quickest_elicited_orbit(sc, form, spread, r, v)
        if sc.emission.elicitation_join == "scan":  # the phone joins at its next burst: wait for it too
            dwell = min(dwell + join_wait_s(sc), MAX_DWELL_S)
    else:
        dwell = dwell_s(sc, mean_p_heard(sc, r, spread), k, p)
    alt = sc.search.look_height_m  # None: the survey altitude, no descent (heights.changes_height)
    from ..heights import changes_height

    return OrbitLook((float(centre_xy_m[0]), float(centre_xy_m[1])), r, dwell, v, form,
                     float(alt) if changes_height(sc, alt) else None)


# -- missions (search/look_mission.py since issue 41; re-exported for the callers of before) ---------

from .look_mission import LookMission, look_mission  # noqa: E402,F401


def orbits_for(policy, vehicle_id, targets) -> tuple:
    """The orbits (OrbitLook or None per target) of the policy's current plan for the vehicle
    ``vehicle_id`` whose look targets are ``targets``; () when that plan has none (the daemon asks
    this when it uploads a look)."""
    plan = getattr(policy, "current_plan", None)
    for task in getattr(plan, "tasks", ()):
        if str(task.vehicle_id) == str(vehicle_id) and tuple(task.target_ids) == tuple(targets):
            return tuple(getattr(task, "orbits", ()))
    return ()


def expand_path(points_xy_m, orbits, start_xy_m) -> tuple[np.ndarray, np.ndarray]:
    """A task's path with its orbits flown (for simulators): the polyline from ``start_xy_m``
    through every access point, each orbit's circle inserted at its entry, and the speed factor of
    each segment (orbit speed / cruise is the caller's; here 1 on legs, the orbit's speed
    marker -1 on circle segments). Returns (path (n, 2), per-segment orbit index or -1)."""
    pts = np.asarray(points_xy_m, float).reshape(-1, 2)
    path = [np.asarray(start_xy_m, float)[:2]]
    seg_orbit: list[int] = []
    orbits = list(orbits) if orbits is not None else []
    for i, q in enumerate(pts):
        orb = orbits[i] if i < len(orbits) else None
        if orb is None:
            path.append(q)
            seg_orbit.append(-1)
            continue
        ring = orb.path_xy_m(path[-1])
        path.append(ring[0])
        seg_orbit.append(-1)
        for r in ring[1:]:
            path.append(r)
            seg_orbit.append(i)
    return np.asarray(path), np.asarray(seg_orbit, int)


# -- the search policy's orbit looks (called from search/policy.py) ----------------------------------

# Orbit looks instead of fly-bys for people whose phones send probe bursts, or answer an on-board
# access point at a few frames a second (a fly-by at 25 m/s hears ~20 of them: nobody was located
# that way in the field demo at 2 Hz); False: fly-bys as before. The paper's continuous world never
# gets orbits.
ORBIT_LOOKS = True
# Orbit looks in a row without hearing the phone before the person is given up as "in a long
# silence or gone" (the first may just fall between two bursts; an orbit waits for two bursts with
# probability ORBIT_P, so one silent orbit after heard ones is no evidence: the field search gave up
# a person heard on five orbits at their first silent one). A person heard on their last
# orbit is looked at again (issue 26: give up only when the evidence says gone or the energy is
# spent), up to the scenario's optional cap, [search] max_orbit_looks.
SILENT_ORBIT_LOOKS = 2
# Looks that adapt (issue 41): while a vehicle orbits a person, each new estimate that moves the
# person farther than RECENTRE_FRACTION of the orbit's radius (and RECENTRE_MIN_M) from the orbit's
# centre re-centres the orbit there, as a new look with its own dwell: the circle follows the
# posterior as its bursts narrow it, instead of circling where the scan first put them. Measured on
# one vehicle, 30 m up, trapped people 60 m from the first centre, 20 runs, 20 minutes at most
# (estimation/burst_grid.py): located 11 of 20 re-centred on the posterior mean, 0 of 20 on the
# fixed circle. False: today's fixed orbit (a named variant for comparison).
ADAPTIVE_ORBITS = True
RECENTRE_FRACTION = 0.3
RECENTRE_MIN_M = 5.0


def _uses_orbits(policy) -> bool:
    return bool(ORBIT_LOOKS and (getattr(policy, "_bursts", False) or elicited(policy.scenario)))


def orbit_targets(policy, t_s: float, targets: list) -> list:
    """The policy's planner targets with every pending person's look made an orbit (burst world):
    the target's disk is the orbit's circle (the access point is where the vehicle joins it), its
    service the orbit's whole turns and their energy at the orbit speed. Records the orbits on the
    policy (``policy._orbits``: person -> OrbitLook centred at ``t_s``, ``policy._orbit_vel``)."""
    from dataclasses import replace as _replace

    from ..heights import vertical_energy_j, vertical_s

    if not _uses_orbits(policy):
        return targets
    sc = policy.scenario
    orbits = policy.__dict__.setdefault("_orbits", {})  # person -> the orbit its look is judged by
    planned = policy.__dict__.setdefault("_orbit_plan", {})  # person -> the orbit to fly now
    vels = policy.__dict__.setdefault("_orbit_vel", {})
    flown = getattr(policy, "_flown", {})
    pw = sc.power_model
    out = []
    for t in targets:
        eid = int(t.id)
        p = policy._people.get(eid)
        if eid in flown and eid in orbits and recentre_due(policy, eid, t.xy_m):
            # the estimate moved away from the circle: a new look centred on it (the one being
            # flown heard the person: that is what moved the estimate; it is not judged a miss)
            del flown[eid]
            orbits.pop(eid, None)
            if p is not None:
                p.looks += 1
        if eid in flown and eid in orbits:  # being orbited: the rest of the same orbit
            old = orbits[eid]
            left = max(flown[eid] + old.flown_s - t_s, 0.0)
            orb = _replace(old, dwell_s=left)
            svc = left
        else:
            r95 = policy._radius95(p) if p is not None and p.estimate is not None and policy._ok(p) else math.inf
            spread = r95 / 2.45 if math.isfinite(r95) else float(sc.horizontal_range_m)  # 95 % of a 2-D normal
            # (a BLE identity's look is planned for its beacons: uavloc_gcs.radios.ble_view)
            orb = plan_orbit(policy.scenario_for(eid), t.xy_m, spread)
            # the whole circle within the area and its stated margin (aiming's _inside_reach): a
            # person predicted outside is orbited from the edge, not chased (the field demo flew
            # an orbit centred 250 m south of the area)
            c = policy._inside_reach(np.asarray(orb.centre_xy_m, float), inset_m=orb.radius_m)[0]
            orb = _replace(orb, centre_xy_m=(float(c[0]), float(c[1])))
            orbits[eid] = orb
            svc = orb.flown_s
        # a look below the survey altitude: its descent and climb back in time and energy (both 0
        # at the survey altitude, so the looks of before are served as before)
        v_s, v_j = vertical_s(sc, orb.alt_m), vertical_energy_j(sc, orb.alt_m)
        planned[eid], vels[eid] = orb, tuple(t.velocity_m_s)
        out.append(_replace(t, xy_m=np.asarray(orb.centre_xy_m, float), radius_m=orb.radius_m,
                            service_s=svc + v_s if v_s else svc,
                            service_energy_j=float(pw.power_w(orb.speed_m_s)) * svc + v_j if v_j
                            else float(pw.power_w(orb.speed_m_s)) * svc))
    return out


def recentre_due(policy, eid: int, centre_xy_m) -> bool:
    """Whether the orbit flown at ``eid`` is off the person's current estimate ``centre_xy_m`` by
    more than RECENTRE_FRACTION of its radius (ADAPTIVE_ORBITS)."""
    if not (ADAPTIVE_ORBITS and _uses_orbits(policy)):
        return False
    orb = getattr(policy, "_orbits", {}).get(int(eid))
    if orb is None or int(eid) not in getattr(policy, "_flown", {}):
        return False
    off = float(np.hypot(*(np.asarray(centre_xy_m, float)[:2] - np.asarray(orb.centre_xy_m, float))))
    return off > max(RECENTRE_MIN_M, RECENTRE_FRACTION * orb.radius_m)


def attach_orbits(policy, plan):
    """``plan`` (a SearchPlan) with each task's ``orbits``: the OrbitLook of every target (centred
    where the person is predicted at the planned access time), None for a fly-by."""
    from dataclasses import replace as _replace

    orbits = getattr(policy, "_orbit_plan", None)
    if not _uses_orbits(policy) or not orbits:
        return plan
    vels = getattr(policy, "_orbit_vel", {})
    t0 = plan.t0_s
    tasks = []
    for task in plan.tasks:
        row = []
        for k, eid in enumerate(task.target_ids):
            orb = orbits.get(int(eid))
            if orb is None:
                row.append(None)
                continue
            ta = task.access_times_s[k] if k < len(task.access_times_s) else t0
            vx, vy = vels.get(int(eid), (0.0, 0.0))
            c = np.array([orb.centre_xy_m[0] + vx * (ta - t0), orb.centre_xy_m[1] + vy * (ta - t0)])
            if vx or vy:  # a walker's drift may take the circle out again
                c = policy._inside_reach(c, inset_m=orb.radius_m)[0]
            row.append(_replace(orb, centre_xy_m=(float(c[0]), float(c[1]))))
        tasks.append(_replace(task, orbits=tuple(row)))
    return _replace(plan, tasks=tuple(tasks))


def orbit_dwell_s(policy, eid: int) -> float:
    """Seconds a planned look at ``eid`` lasts beyond its access time (its orbit; 0 for a fly-by)."""
    orb = getattr(policy, "_orbits", {}).get(int(eid)) if _uses_orbits(policy) else None
    return 0.0 if orb is None else float(orb.flown_s)


def judge_orbit(policy, eid: int, p, heard: bool) -> str | None:
    """After an orbit look at ``eid`` was judged: None when it was no orbit (the policy's fly-by
    rules apply), "" to keep looking, or the reason the person is given up."""
    orb = getattr(policy, "_orbits", {}).pop(int(eid), None) if _uses_orbits(policy) else None
    if orb is None:
        return None
    n = policy.__dict__.setdefault("_orbit_looks", {})
    n[int(eid)] = k = n.get(int(eid), 0) + 1
    quiet = policy.__dict__.setdefault("_silent_orbits", {})  # silent orbits in a row, per person
    quiet[int(eid)] = silent = 0 if heard else quiet.get(int(eid), 0) + 1
    cap = policy.scenario.search.max_orbit_looks
    capped = cap is not None and k >= cap
    if heard and not capped:  # the phone is there: look again while a vehicle has the energy
        return ""
    if not heard and silent < SILENT_ORBIT_LOOKS and not capped:
        return ""
    r95 = policy._radius95(p) if p.estimate is not None else math.nan
    if heard:  # the phone is there: what ends the looks is the cap, and the sentence says so
        return (f"not located after {k} orbit looks of {orb.flown_s:.0f} s (heard on the last one; 95 % "
                f"radius {r95:.0f} m): the orbits did not narrow it to the accuracy asked for, and the "
                f"scenario flies at most {cap} for one person ([search] max_orbit_looks)")
    if silent < SILENT_ORBIT_LOOKS:  # the cap came first: one silent orbit is no evidence of anything
        return (f"not located after {k} orbit look(s) of {orb.flown_s:.0f} s (not heard on the last one; 95 % "
                f"radius {r95:.0f} m): the scenario flies at most {cap} for one person ([search] max_orbit_looks)")
    return (f"not located after {k} orbit looks (not heard on the last {silent}, of {orb.flown_s:.0f} s "
            f"the last; 95 % radius {r95:.0f} m); its phone may be in a long silence or gone")
