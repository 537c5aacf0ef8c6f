"""Flying a stored mission (AUTO / PX4 Mission mode): which item is current, where to fly, when an
item counts as reached.

Rules (``reference/mavlink.md`` §2.3-§2.4): a NAV_WAYPOINT with hold 0 followed by another
waypoint is flown through without stopping -- it is reached inside the acceptance radius or when
the vehicle crosses the plane through the waypoint perpendicular to the leg (so a turn wider than
the radius still counts); otherwise the vehicle stops there and holds ``param1`` seconds.
DO_CHANGE_SPEED takes effect at once; DO_JUMP repeats; TAKEOFF climbs; RTL and LAND end the
mission on the ground.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from uavloc_gcs.geo import LocalFrame
from uavloc_gcs.mission import WireItem

from .mission_server import POSITIONAL

NAV_WAYPOINT, LOITER_UNLIM, LOITER_TURNS, LOITER_TIME, RTL, LAND, TAKEOFF = 16, 17, 18, 19, 20, 21, 22
DO_JUMP, DO_CHANGE_SPEED = 177, 178
PASS_THROUGH_NEXT = frozenset({NAV_WAYPOINT, LOITER_UNLIM, LOITER_TIME})  # ArduCopter set_next_wp
NAV_COMMANDS = frozenset(POSITIONAL | {RTL})
_RELATIVE_FRAMES = frozenset({3, 6, 10, 11})
CIRCLE_RADIUS_DEFAULT_M = 10.0  # ArduCopter CIRCLE_RADIUS default (1000 cm)
# ArduCopter flies a NAV_LOITER_TURNS circle at about sqrt(a r): 7.9 m/s around 60 m measured on
# SITL (docs/science/looks.md, uavloc_gcs.search.orbit.ORBIT_SPEED_M_S), a = 1.04 m/s^2
CIRCLE_ACCEL_M_S2 = 7.9 * 7.9 / 60.0


@dataclass
class Target:
    """What the flight controller should do this step."""

    kind: str  # "fly", "takeoff", "rtl", "land", "done"
    xyz_m: np.ndarray | None = None
    stop: bool = True
    hold_s: float = 0.0
    next_xyz_m: np.ndarray | None = None  # the following waypoint of a pass-through one
    prev_xyz_m: np.ndarray | None = None  # where the leg to this waypoint starts
    # "circle" (ArduCopter's NAV_LOITER_TURNS): centre xyz_m, radius, turns, counter-clockwise
    radius_m: float = 0.0
    turns: float = 0.0
    ccw: bool = False


def corner(leg_in_xy, leg_out_xy, speed_m_s: float, accel_m_s2: float, cut_m: float) -> tuple[float, float]:
    """Speed [m/s] through a pass-through corner and how far before it the turn starts [m].

    The turn is a circular arc tangent to both legs that passes at most ``cut_m`` from the
    waypoint (as PX4's acceptance radius and ArduCopter's WPNAV_RADIUS bound the rounded corner),
    flown at the speed whose radius v^2/a fits: a 90 deg corner with cut 10 m and 5 m/s^2 is taken
    at 11 m/s starting 24 m before the waypoint; a small heading change at full speed.
    Returns (0, 0) for a reversal or when the next item is at the waypoint (the vehicle stops there).
    """
    a, b = np.asarray(leg_in_xy, float), np.asarray(leg_out_xy, float)
    na, nb = float(np.hypot(*a)), float(np.hypot(*b))
    if nb < 1e-6:  # the next item is here (a loiter at the waypoint): arrive and stop, as ArduCopter's
        return 0.0, 0.0  # S-curve does for a zero-length next leg (the fake flew 37 m past it)
    if na < 1e-6:
        return speed_m_s, 0.0
    cos_t = max(-1.0, min(1.0, float(a @ b) / (na * nb)))
    theta = math.acos(cos_t)  # heading change
    if theta > math.radians(175.0):
        return 0.0, 0.0
    half = theta / 2.0
    r_cut = cut_m / (1.0 / math.cos(half) - 1.0) if theta > 1e-6 else math.inf
    r = min(r_cut, speed_m_s**2 / accel_m_s2)
    return math.sqrt(accel_m_s2 * r), min(r * math.tan(half), na)


@dataclass
class MissionExecutor:
    frame: LocalFrame
    home_alt_amsl_m: float
    first_seq: int  # 1 on ArduPilot (0 is home), 0 on PX4
    current: int = 0
    leg_start_xyz_m: np.ndarray | None = None
    hold_until_s: float | None = None
    jumps_done: dict = field(default_factory=dict)
    started: bool = False
    complete: bool = False
    came_from: int | None = None  # seq of the item reached just before the current one
    flying: WireItem | None = None  # the navigation item being flown (target's last answer)
    # ArduPilot: a mission uploaded in flight that ends before the current index leaves the item
    # being flown running (measured on SITL: flying the RTL at seq 4, a 4-item upload -> still
    # active at seq 4, flying home); it is kept here until reached.
    carried: WireItem | None = None
    circled_rad: float | None = None  # a NAV_LOITER_TURNS being circled: the angle flown so far

    def reset(self, seq: int | None = None) -> None:
        self.current = self.first_seq if seq is None else seq
        self.came_from = None
        self.carried = None
        self.leg_start_xyz_m = None
        self.hold_until_s = None
        self.circled_rad = None
        self.complete = False

    def position_of(self, it: WireItem, here_xyz_m: np.ndarray) -> np.ndarray:
        """Local ENU position of a positional item (lat/lon 0 = current position, as Copter)."""
        if it.x == 0 and it.y == 0:
            e, n = here_xyz_m[0], here_xyz_m[1]
        else:
            e, n = self.frame.to_local(it.x / 1e7, it.y / 1e7)
        z = it.z if it.frame in _RELATIVE_FRAMES else it.z - self.home_alt_amsl_m
        return np.array([float(e), float(n), float(z)])

    def advance_instant_items(self, items: list[WireItem], on_speed) -> None:
        """Execute DO_* items at the current index until a navigation command is current."""
        for _ in range(len(items) + 1):
            if self.current >= len(items):
                self.complete = self.carried is None
                return
            it = items[self.current]
            if it.command in NAV_COMMANDS:
                return
            if it.command == DO_CHANGE_SPEED and it.param2 > 0:
                on_speed(float(it.param2))
            if it.command == DO_JUMP:
                target, repeat = int(it.param1), int(it.param2)
                done = self.jumps_done.get(self.current, 0)
                if (repeat < 0 or done < repeat) and 0 <= target < len(items):
                    self.jumps_done[self.current] = done + 1
                    self.current = target
                    self.leg_start_xyz_m = None
                    continue
            self.current += 1
            self.leg_start_xyz_m = None

    def next_nav(self, items: list[WireItem], after: int) -> WireItem | None:
        for it in items[after + 1:]:
            if it.command in NAV_COMMANDS:
                return it
            if it.command == DO_JUMP:
                return None  # do not look through jumps: stop, as Copter does for unknown next items
        return None

    def target(self, items: list[WireItem], here_xyz_m: np.ndarray) -> Target:
        """Target for the current item (call :meth:`advance_instant_items` first)."""
        if self.complete or (self.current >= len(items) and self.carried is None):
            self.complete = True
            return Target("done")
        it = items[self.current] if self.current < len(items) else self.carried
        self.flying = it
        if self.leg_start_xyz_m is None:
            self.leg_start_xyz_m = here_xyz_m.copy()
        if it.command == TAKEOFF:
            z = it.z if it.frame in _RELATIVE_FRAMES else it.z - self.home_alt_amsl_m
            return Target("takeoff", np.array([here_xyz_m[0], here_xyz_m[1], max(z, 1.0)]))
        if it.command == RTL:
            return Target("rtl")
        if it.command == LAND:
            xyz = self.position_of(it, here_xyz_m)
            return Target("land", np.array([xyz[0], xyz[1], here_xyz_m[2]]))
        xyz = self.position_of(it, here_xyz_m)
        if it.command == NAV_WAYPOINT:
            nxt = self.next_nav(items, self.current)
            passing = it.param1 <= 0 and nxt is not None and nxt.command in PASS_THROUGH_NEXT
            nxt_xyz = self.position_of(nxt, xyz) if passing else None
            return Target("fly", xyz, stop=not passing, hold_s=max(0.0, float(it.param1)), next_xyz_m=nxt_xyz,
                          prev_xyz_m=self._previous_waypoint(items))
        if it.command == LOITER_TIME:
            return Target("fly", xyz, stop=True, hold_s=max(0.0, float(it.param1)))
        if it.command == LOITER_TURNS:
            # ArduCopter: param1 turns, param3 radius [m] (negative: counter-clockwise; 0: its
            # CIRCLE_RADIUS default of 10 m); the vehicle goes to the circle's edge, circles, goes on
            r = abs(float(it.param3)) or CIRCLE_RADIUS_DEFAULT_M
            return Target("circle", xyz, stop=True, radius_m=r, turns=max(float(it.param1), 0.0),
                          ccw=float(it.param3) < 0)
        if it.command == LOITER_UNLIM:
            return Target("fly", xyz, stop=True, hold_s=math.inf)
        return Target("fly", xyz, stop=True)

    def _previous_waypoint(self, items: list[WireItem]) -> np.ndarray:
        """The waypoint flown before the current one (the leg's true direction), else where the
        vehicle was when this leg began (after takeoff, a jump or a set-current)."""
        if self.current > 0:
            prev = items[self.current - 1] if self.current - 1 < len(items) else None
            k = self.current - 1
            while prev is not None and prev.command not in NAV_COMMANDS and k > 0:
                k -= 1
                prev = items[k]
            if prev is not None and prev.command == NAV_WAYPOINT and self.came_from == k:
                return self.position_of(prev, self.leg_start_xyz_m)
        return self.leg_start_xyz_m

    def reached(self, tgt: Target, here_xyz_m: np.ndarray, speed_m_s: float, t_s: float,
                acceptance_m: float) -> bool:
        """Whether the current positional item is done (including any hold time)."""
        if tgt.kind != "fly":
            return False
        d = tgt.xyz_m - here_xyz_m
        dist = float(np.linalg.norm(d))
        if not tgt.stop:
            if dist <= acceptance_m:
                return True
            leg = tgt.xyz_m[:2] - self.leg_start_xyz_m[:2]
            return float(np.dot(leg, -d[:2])) >= 0.0 and float(np.dot(leg, leg)) > 1e-6
        if self.hold_until_s is None:
            if dist <= max(0.5, min(acceptance_m, 1.0)) and speed_m_s < 0.5:
                self.hold_until_s = t_s + tgt.hold_s
            else:
                return False
        return t_s >= self.hold_until_s

    def next(self) -> int:
        """Mark the current item reached; returns its seq."""
        seq = self.current
        self.came_from = seq
        self.carried = None
        self.current += 1
        self.leg_start_xyz_m = None
        self.hold_until_s = None
        self.circled_rad = None
        return seq
