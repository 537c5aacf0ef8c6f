"""The routing problem of the accurate-localization stage, and the plan that answers it.

Vehicles start where they are now (``start_xy_m``) at ``t0_s``, fly at ``speed_m_s``, pass within
``radius_m`` of each assigned person's (moving) predicted centre, and end at ``home_xy_m``. The
objective is the makespan: the largest route duration [s] from ``t0_s`` to the last vehicle home.
Every route's propulsion energy (``power.leg_energy_j`` at ``speed_m_s``) must fit the vehicle's
remaining ``energy_j``.

A target may have a *service*: an orbit look (search/orbit.py) keeps the vehicle ``service_s``
seconds on a circle through its access point and spends ``service_energy_j`` there. The makespan,
the access times of the later targets and the energy check count both; ``service_s = 0`` (every
fly-by, the paper) changes nothing.

Sorties (issue 38): a vehicle with ``spare_packs`` > 0 may go home, swap its pack
(``battery_swap_s`` on the ground, counted in the makespan and the later access times) and go on
with a fresh one of ``pack_energy_j``, once per spare pack: a multi-trip routing problem with
reloads at the depot. Each sortie (start or home -> targets -> home) must fit its pack: the first
the vehicle's ``energy_j``, the later ones ``pack_energy_j``. With no spare packs (the default)
the problem is the single-trip one, and every solver computes exactly what it did before.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..energy import ZENG_2019, RotorcraftPower
from ..errors import ConfigError, InfeasibleError


@dataclass(frozen=True)
class VehicleState:
    """A vehicle as the planner sees it: where it is, where it must end, energy left [J] in the pack
    it flies now (beyond its reserve), and the fresh packs waiting at home (each a sortie after a
    swap; ``pack_energy_j`` usable in each)."""

    id: str
    start_xy_m: tuple[float, float]
    home_xy_m: tuple[float, float]
    energy_j: float
    spare_packs: int = 0
    pack_energy_j: float = 0.0


@dataclass(frozen=True)
class Target:
    """A person to look at: centre [m] at ``t0_s`` moving at ``velocity_m_s``; a pass within
    ``radius_m`` of the centre at the time of the pass counts."""

    id: str
    xy_m: tuple[float, float]
    velocity_m_s: tuple[float, float] = (0.0, 0.0)
    radius_m: float = 0.0
    service_s: float = 0.0  # time spent at the access point (an orbit look's dwell) [s]
    service_energy_j: float = 0.0  # energy spent in that time [J]


@dataclass(frozen=True)
class RoutingProblem:
    vehicles: tuple[VehicleState, ...]
    targets: tuple[Target, ...]
    speed_m_s: float
    t0_s: float = 0.0
    power: RotorcraftPower = ZENG_2019
    battery_swap_s: float = 0.0  # time on the ground to swap a pack [s] (vehicles with spare packs)

    def __post_init__(self) -> None:
        object.__setattr__(self, "vehicles", tuple(self.vehicles))
        object.__setattr__(self, "targets", tuple(self.targets))

    # Array views (cheap; recomputed on demand, the dataclass stays hashable-free and frozen).
    @property
    def starts_xy_m(self) -> np.ndarray:
        return np.array([v.start_xy_m for v in self.vehicles], dtype=float).reshape(-1, 2)

    @property
    def homes_xy_m(self) -> np.ndarray:
        return np.array([v.home_xy_m for v in self.vehicles], dtype=float).reshape(-1, 2)

    @property
    def energies_j(self) -> np.ndarray:
        return np.array([v.energy_j for v in self.vehicles], dtype=float)

    @property
    def centres_xy_m(self) -> np.ndarray:
        return np.array([t.xy_m for t in self.targets], dtype=float).reshape(-1, 2)

    @property
    def velocities_m_s(self) -> np.ndarray:
        return np.array([t.velocity_m_s for t in self.targets], dtype=float).reshape(-1, 2)

    @property
    def radii_m(self) -> np.ndarray:
        return np.array([t.radius_m for t in self.targets], dtype=float)

    @property
    def service_s(self) -> np.ndarray:
        return np.array([t.service_s for t in self.targets], dtype=float)

    @property
    def service_energy_j(self) -> np.ndarray:
        return np.array([t.service_energy_j for t in self.targets], dtype=float)

    @property
    def energy_per_m_j(self) -> float:
        return float(self.power.energy_per_m_j(self.speed_m_s))

    @property
    def max_length_m(self) -> np.ndarray:
        """Longest route [m] each vehicle's energy allows at ``speed_m_s`` (its first sortie's, with
        spare packs)."""
        return self.energies_j / self.energy_per_m_j

    @property
    def spare_packs(self) -> np.ndarray:
        return np.array([v.spare_packs for v in self.vehicles], dtype=int)

    @property
    def pack_length_m(self) -> np.ndarray:
        """Longest sortie [m] a fresh pack allows at ``speed_m_s``, per vehicle (0 without spares)."""
        return np.array([v.pack_energy_j if v.spare_packs > 0 else 0.0 for v in self.vehicles]) / self.energy_per_m_j

    @property
    def has_sorties(self) -> bool:
        """Whether some vehicle has a spare pack (the multi-trip problem)."""
        return any(v.spare_packs > 0 for v in self.vehicles)


@dataclass(frozen=True)
class Route:
    """One vehicle's answer: targets in visiting order, where and when each disk is reached."""

    vehicle_id: str
    target_ids: tuple[str, ...]
    access_points_xy_m: np.ndarray  # (k, 2)
    access_times_s: np.ndarray  # (k,), absolute (t0_s + flight time)
    duration_s: float  # start -> accesses -> home (with sorties: the trips home and the swaps too)
    energy_j: float  # of all its sorties
    swaps_before: tuple[int, ...] = ()  # indices k: before target_ids[k] it flies home and swaps its pack
    sortie_energy_j: tuple[float, ...] = ()  # energy of each sortie, in flight order (with spare packs)

    def sorties(self) -> tuple[tuple[str, ...], ...]:
        """The target ids of each sortie in flight order (one sortie without swaps)."""
        cuts = [0, *self.swaps_before, len(self.target_ids)]
        return tuple(tuple(self.target_ids[a:b]) for a, b in zip(cuts, cuts[1:]))


@dataclass(frozen=True)
class Plan:
    routes: tuple[Route, ...]
    makespan_s: float
    lower_bound_s: float

    def assignment(self) -> dict[str, tuple[str, ...]]:
        """vehicle id -> target ids in order."""
        return {r.vehicle_id: r.target_ids for r in self.routes}


@dataclass
class PlanResult:
    """scipy-style result. ``x`` is the best decision vector in the optimizer's own encoding
    (random keys for EPSO/PSO, permutation + route sizes for GA, node order + route sizes for the
    anchors); ``plan`` is authoritative (it includes the final polish); ``fun`` the makespan [s] of
    ``plan``; ``success`` False when no energy-feasible plan was found (``message`` says which
    vehicle lacks how much); ``history`` the best search fitness [s] after each iteration."""

    x: np.ndarray
    fun: float
    nit: int
    nfev: int
    success: bool
    message: str
    plan: Plan
    runtime_s: float = 0.0
    history: list[float] = field(default_factory=list)


def _finite(values: Sequence[float]) -> bool:
    return all(math.isfinite(float(v)) for v in values)


def validate(problem: RoutingProblem) -> None:
    """Raise ConfigError for malformed input, naming the vehicle/target and the numbers."""
    if not problem.vehicles:
        raise ConfigError("the routing problem has no vehicles")
    if not (math.isfinite(problem.speed_m_s) and problem.speed_m_s > 0):
        raise ConfigError(f"speed must be a positive finite number, got {problem.speed_m_s} m/s")
    if not math.isfinite(problem.t0_s):
        raise ConfigError(f"t0 must be finite, got {problem.t0_s} s")
    if not (math.isfinite(problem.battery_swap_s) and problem.battery_swap_s >= 0):
        raise ConfigError(f"battery swap time must be finite and not negative, got {problem.battery_swap_s} s")
    seen: set[str] = set()
    for v in problem.vehicles:
        if v.id in seen:
            raise ConfigError(f"vehicle id {v.id!r} appears twice")
        seen.add(v.id)
        if len(v.start_xy_m) != 2 or len(v.home_xy_m) != 2:
            raise ConfigError(f"vehicle {v.id}: start and home must be [x, y] pairs")
        if not _finite([*v.start_xy_m, *v.home_xy_m, v.energy_j]):
            raise ConfigError(
                f"vehicle {v.id}: non-finite number in start {v.start_xy_m}, home {v.home_xy_m} "
                f"or energy {v.energy_j} J")
        if v.energy_j < 0:
            raise ConfigError(f"vehicle {v.id}: negative energy {v.energy_j} J")
        if isinstance(v.spare_packs, bool) or not isinstance(v.spare_packs, (int, np.integer)) or v.spare_packs < 0:
            raise ConfigError(f"vehicle {v.id}: spare packs must be a whole number, 0 or more, got {v.spare_packs!r}")
        if v.spare_packs > 0 and not (math.isfinite(v.pack_energy_j) and v.pack_energy_j > 0):
            raise ConfigError(f"vehicle {v.id}: {v.spare_packs} spare pack(s) of {v.pack_energy_j} J; a pack's "
                              "usable energy must be a positive number of joules")
    seen = set()
    for t in problem.targets:
        if t.id in seen:
            raise ConfigError(f"target id {t.id!r} appears twice")
        seen.add(t.id)
        if len(t.xy_m) != 2 or len(t.velocity_m_s) != 2:
            raise ConfigError(f"target {t.id}: position and velocity must be [x, y] pairs")
        if not _finite([*t.xy_m, *t.velocity_m_s, t.radius_m]):
            raise ConfigError(
                f"target {t.id}: non-finite number in position {t.xy_m}, velocity "
                f"{t.velocity_m_s} or radius {t.radius_m}")
        if t.radius_m < 0:
            raise ConfigError(f"target {t.id}: negative radius {t.radius_m} m")
        if not (math.isfinite(t.service_s) and math.isfinite(t.service_energy_j)
                and t.service_s >= 0 and t.service_energy_j >= 0):
            raise ConfigError(f"target {t.id}: service time {t.service_s} s and energy {t.service_energy_j} J "
                              "must be finite and not negative")
        speed = math.hypot(*t.velocity_m_s)
        if speed >= 0.5 * problem.speed_m_s:
            raise ConfigError(
                f"target {t.id}: speed {speed:.2f} m/s is not small against the vehicle speed "
                f"{problem.speed_m_s} m/s (the moving-disk model needs it below half)")


def check_reachable(problem: RoutingProblem) -> None:
    """InfeasibleError if some vehicle cannot even get home, or a target no vehicle can reach
    and return from within its energy (measured with the shortest start -> disk -> home detour, or,
    for a vehicle with a spare pack, home -> disk -> home on a fresh one)."""
    from .access import single_visit_length_m  # local: access imports this module

    e_per_m = problem.energy_per_m_j
    max_len = problem.max_length_m
    starts, homes = problem.starts_xy_m, problem.homes_xy_m
    direct = np.linalg.norm(homes - starts, axis=1)
    for v, d, cap in zip(problem.vehicles, direct, max_len):
        if d > cap * (1 + 1e-9):
            if d < 1.0:  # at home already: nothing left to fly with
                if v.spare_packs > 0:
                    continue  # at home: the next sortie starts with a fresh pack
                raise InfeasibleError(f"vehicle {v.id} cannot reach home: its usable energy is spent "
                                      f"({v.energy_j:.0f} J left beyond its reserve)")
            raise InfeasibleError(
                f"vehicle {v.id} cannot reach home: {d:.1f} m need {d * e_per_m:.0f} J, "
                f"it has {v.energy_j:.0f} J")
    if not problem.targets:
        return
    need = single_visit_length_m(problem) + (problem.service_energy_j / e_per_m)[:, None]  # (n, m)
    ok = need <= max_len * (1 + 1e-9)
    if problem.has_sorties:  # or on a fresh pack from home, after a swap (disks where they are at t0)
        fresh = _home_visit_length_m(problem) + (problem.service_energy_j / e_per_m)[:, None]
        ok |= (problem.spare_packs > 0) & (fresh <= problem.pack_length_m * (1 + 1e-9))
    for i, t in enumerate(problem.targets):
        if not ok[i].any():
            best = int(np.argmin(need[i] - max_len))
            v = problem.vehicles[best]
            packs = f" (and {v.pack_energy_j:.0f} J in each of {v.spare_packs} spare packs)" if v.spare_packs else ""
            look = f" with its {t.service_s:.0f} s look" if t.service_s > 0 else ""
            detail = (f"the best vehicle {v.id} needs {need[i, best]:.1f} m = {need[i, best] * e_per_m:.0f} J there "
                      f"and home{look}, it has {v.energy_j:.0f} J{packs}")
            raise InfeasibleError(
                f"target {t.id} at ({t.xy_m[0]:.1f}, {t.xy_m[1]:.1f}) m, radius {t.radius_m:.1f} m "
                f"is out of reach: {detail}",
                target_id=t.id,
                why=f"a look at ({t.xy_m[0]:.0f}, {t.xy_m[1]:.0f}) m{_within(t.radius_m)}: {detail}")


def _within(radius_m: float) -> str:
    """How close a look must pass, for a sentence ("" for a look flown at the point itself; it said
    "radius then 0 m")."""
    return f", passing within {radius_m:.0f} m of it" if radius_m >= 0.5 else ""


def _home_visit_length_m(problem: RoutingProblem) -> np.ndarray:
    """(n, m): home -> disk -> home for each target and vehicle (a sortie on a fresh pack)."""
    c = problem.centres_xy_m[:, None, :]
    d = np.linalg.norm(c - problem.homes_xy_m[None, :, :], axis=2)
    return 2.0 * np.maximum(d - problem.radii_m[:, None], 0.0)
