"""Point-mass multirotor kinematics with bounded acceleration, in the local ENU frame.

Horizontal motion is a coordinated turn: the velocity vector turns towards the target with a
lateral acceleration of at most ``max_accel_m_s2`` and the speed changes with what is left of
that budget, so a pass-through waypoint is flown through at cruise speed on a rounded path
instead of stopping (a sharp corner at 25 m/s and 5 m/s^2 has a 125 m turn radius). Below 2 m/s
(hover, take-off) the velocity simply moves straight towards the desired one. Vertical motion is a
rate-limited proportional climb/descent. All numbers are metres, seconds, m/s, m/s^2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

SLOW_M_S = 2.0  # below this the heading is free (hovering multirotor)


@dataclass
class Kinematics:
    max_accel_m_s2: float = 5.0
    climb_rate_m_s: float = 5.0
    descent_rate_m_s: float = 3.0
    vertical_gain_1_s: float = 1.0
    pos: np.ndarray = field(default_factory=lambda: np.zeros(3))
    vel: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @property
    def ground_speed_m_s(self) -> float:
        return float(math.hypot(self.vel[0], self.vel[1]))

    def stop(self) -> None:
        self.vel = np.zeros(3)

    def step(self, dt_s: float, target_xyz_m, speed_m_s: float, *, stop_at_target: bool) -> None:
        """Advance ``dt_s`` flying towards ``target_xyz_m`` at ``speed_m_s``; when
        ``stop_at_target`` the vehicle brakes so that it arrives at rest."""
        a = self.max_accel_m_s2
        target = np.asarray(target_xyz_m, dtype=float)
        d = target[:2] - self.pos[:2]
        dist = float(math.hypot(d[0], d[1]))
        v_des = speed_m_s
        if stop_at_target:
            # brake with 80 % of the budget so the arrival is not an overshoot
            v_des = min(speed_m_s, math.sqrt(max(0.0, 2.0 * 0.8 * a * dist)))
            if dist < 0.05:
                v_des = 0.0
        vh = self.vel[:2].copy()
        s = float(math.hypot(vh[0], vh[1]))
        behind = False
        if dist > 1e-9 and s >= SLOW_M_S:
            # A target beside or behind the vehicle is only reachable by slowing down: the circle
            # tangent to the velocity through the target has radius dist / (2 sin|err|), which
            # bounds the speed at sqrt(a r). Otherwise the vehicle would orbit the target.
            err0 = (math.atan2(d[1], d[0]) - math.atan2(vh[1], vh[0]) + math.pi) % (2.0 * math.pi) - math.pi
            behind = abs(err0) > math.pi / 2 and dist < s * s / a
            if abs(err0) > 1e-3:
                radius = dist / (2.0 * math.sin(min(abs(err0), math.pi / 2)))
                v_des = min(v_des, max(SLOW_M_S, math.sqrt(0.8 * a * radius)))
        if dist < 1e-9:
            want = np.zeros(2)
        else:
            want = d / dist * v_des
        if s < SLOW_M_S or v_des < SLOW_M_S or behind:
            dv = want - vh
            n = float(math.hypot(dv[0], dv[1]))
            lim = a * dt_s
            vh = vh + (dv if n <= lim else dv * (lim / n))
        else:
            heading = math.atan2(vh[1], vh[0])
            desired = math.atan2(want[1], want[0]) if dist > 1e-9 else heading
            err = (desired - heading + math.pi) % (2.0 * math.pi) - math.pi
            if v_des < s:
                # Braking first: slowing down also tightens the turn.
                a_tan = min(a, (s - v_des) / dt_s)
                a_lat = min(math.sqrt(max(0.0, a * a - a_tan * a_tan)), s * abs(err) / dt_s)
            else:
                a_lat = min(a, s * abs(err) / dt_s)
                a_tan = math.sqrt(max(0.0, a * a - a_lat * a_lat))
            heading += math.copysign(a_lat * dt_s / s, err)
            s = s + max(-a_tan * dt_s, min(a_tan * dt_s, v_des - s))
            vh = np.array([math.cos(heading), math.sin(heading)]) * max(s, 0.0)
        dz = target[2] - self.pos[2]
        vz_des = max(-self.descent_rate_m_s, min(self.climb_rate_m_s, self.vertical_gain_1_s * dz))
        vz = self.vel[2] + max(-a * dt_s, min(a * dt_s, vz_des - self.vel[2]))
        new_vel = np.array([vh[0], vh[1], vz])
        self.pos = self.pos + 0.5 * (self.vel + new_vel) * dt_s
        self.vel = new_vel

    def descend(self, dt_s: float, rate_m_s: float) -> None:
        """Brake horizontally and descend at ``rate_m_s`` (landing); stops at the ground (z = 0)."""
        target = np.array([self.pos[0], self.pos[1], -1e6])
        saved = self.descent_rate_m_s
        self.descent_rate_m_s = rate_m_s
        self.step(dt_s, target, 0.0, stop_at_target=True)
        self.descent_rate_m_s = saved
        if self.pos[2] <= 0.0:
            self.pos[2] = 0.0
            self.vel = np.zeros(3)
