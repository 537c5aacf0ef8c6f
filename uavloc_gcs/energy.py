"""Rotary-wing propulsion power (Zeng, Xu, Zhang, IEEE TWC 18(4), 2019), correct V^4 form.

    P(V) = P0 (1 + 3 V^2/U^2) + Pi (sqrt(1 + V^4/(4 v0^4)) - V^2/(2 v0^2))^(1/2) + 1/2 d0 rho s A V^3

The seed paper prints V^2 inside the inner root, which goes negative above ~5.7 m/s; not copied.
Energy of a leg flown at constant V is P(V) * length / V (turns and accelerations are not modelled).

Climbing (terrain, issue 28): climbing at rate v_c takes the work against gravity on top of the
level-flight power, P_climb = W v_c (W the vehicle's weight, Zeng's Table I: 20 N), so a climb of
dh metres costs W dh joules whatever its rate. This is the potential-energy term m g (h(T) - h(0))
of the heuristic 3-D extension Zeng, Xu and Zhang give beside their level-flight model; the change
of induced power with the climb rate is left out (small at the few m/s missions climb). Descents
are given no credit: the rotors still lift the vehicle, and no energy is recovered.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar


@dataclass(frozen=True)
class RotorcraftPower:
    """Parameters of Zeng's model; defaults are Zeng's Table I."""

    blade_profile_w: float = 79.856  # P0 = (delta/8) rho s A Omega^3 R^3
    induced_w: float = 88.628  # Pi = (1+k) W^1.5 / sqrt(2 rho A)
    tip_speed_m_s: float = 120.0  # U_tip
    mean_induced_velocity_m_s: float = 4.03  # v0
    fuselage_drag_ratio: float = 0.6  # d0
    air_density_kg_m3: float = 1.225  # rho
    rotor_solidity: float = 0.05  # s
    rotor_disc_area_m2: float = 0.503  # A
    weight_n: float = 20.0  # W (Zeng's Table I), for the climb power W v_c

    def power_w(self, speed_m_s):
        """Propulsion power [W] in level flight at ``speed_m_s`` (scalar or array)."""
        v = np.asarray(speed_m_s, dtype=float)
        v0 = self.mean_induced_velocity_m_s
        blade = self.blade_profile_w * (1.0 + 3.0 * v**2 / self.tip_speed_m_s**2)
        inner = np.sqrt(1.0 + v**4 / (4.0 * v0**4)) - v**2 / (2.0 * v0**2)
        induced = self.induced_w * np.sqrt(inner)
        parasite = (
            0.5
            * self.fuselage_drag_ratio
            * self.air_density_kg_m3
            * self.rotor_solidity
            * self.rotor_disc_area_m2
            * v**3
        )
        p = blade + induced + parasite
        return float(p) if np.ndim(p) == 0 else p

    def climb_power_w(self, climb_rate_m_s) -> float:
        """Power [W] on top of the level-flight power to climb at ``climb_rate_m_s`` (W v_c; none
        for a descent, which recovers nothing)."""
        r = np.maximum(np.asarray(climb_rate_m_s, dtype=float), 0.0)
        p = self.weight_n * r
        return float(p) if np.ndim(p) == 0 else p

    def climb_energy_j(self, heights_m) -> float:
        """Energy [J] of the climbs along a sequence of heights [m]: W times the metres climbed
        (descents free), the integral of :meth:`climb_power_w` over any climb rate."""
        h = np.asarray(heights_m, dtype=float).reshape(-1)
        return float(self.weight_n * np.sum(np.maximum(np.diff(h), 0.0))) if len(h) > 1 else 0.0

    def hover_power_w(self) -> float:
        return float(self.power_w(0.0))

    def energy_per_m_j(self, speed_m_s) -> float:
        """Energy per metre [J/m] at constant speed (> 0)."""
        return self.power_w(speed_m_s) / np.asarray(speed_m_s, dtype=float)

    def leg_energy_j(self, length_m, speed_m_s):
        """Energy [J] of a leg of ``length_m`` flown at constant ``speed_m_s``."""
        return self.power_w(speed_m_s) * np.asarray(length_m, dtype=float) / speed_m_s

    def hover_energy_j(self, duration_s) -> float:
        return self.hover_power_w() * duration_s

    def max_endurance_speed_m_s(self) -> float:
        """Speed minimizing power (longest time aloft)."""
        r = minimize_scalar(lambda v: self.power_w(v), bounds=(0.1, 60.0), method="bounded",
                            options={"xatol": 1e-6})
        return float(r.x)

    def max_range_speed_m_s(self) -> float:
        """Speed minimizing energy per metre (longest distance)."""
        r = minimize_scalar(lambda v: self.power_w(v) / v, bounds=(0.5, 60.0), method="bounded",
                            options={"xatol": 1e-6})
        return float(r.x)


ZENG_2019 = RotorcraftPower()


def path_length_m(xy_m: np.ndarray) -> float:
    """Length of a polyline given as an (N, 2) or (N, 3) array of metres."""
    a = np.asarray(xy_m, dtype=float)
    if len(a) < 2:
        return 0.0
    return float(np.sum(np.linalg.norm(np.diff(a, axis=0), axis=1)))


@dataclass(frozen=True)
class RouteCost:
    length_m: float
    duration_s: float
    energy_j: float


def route_cost(xy_m: np.ndarray, speed_m_s: float, power: RotorcraftPower = ZENG_2019) -> RouteCost:
    """Length, time and energy of a polyline flown at constant ``speed_m_s``."""
    if speed_m_s <= 0:
        raise ValueError(f"speed must be positive, got {speed_m_s} m/s")
    length = path_length_m(xy_m)
    return RouteCost(length, length / speed_m_s, float(power.leg_energy_j(length, speed_m_s)))
