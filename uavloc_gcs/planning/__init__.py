"""Route planning for the accurate-localization stage (SPEC §2.3): assign people to vehicles and
order them so the last vehicle is home as early as possible, passing within each person's access
disk, within each vehicle's energy.

    from uavloc_gcs.planning import RoutingProblem, VehicleState, Target, solve
    result = solve(problem, method="epso", rng=1, time_limit_s=1.0)
    result.plan.routes[0].access_points_xy_m

Modules: ``problem`` (model, validation), ``access`` (edge access on disks), ``fitness`` (the
shared vectorized fitness), ``swarm`` (EPSO/PSO), ``ga`` (GA), ``localsearch``, ``bounds``
(lower bound), ``anchors`` (OR-Tools / PyVRP, optional), ``solve`` (entry point).
"""

from .bounds import lower_bound_s
from .problem import Plan, PlanResult, Route, RoutingProblem, Target, VehicleState
from .solve import METHODS, Progress, solve

__all__ = [
    "METHODS",
    "Plan",
    "PlanResult",
    "Progress",
    "Route",
    "RoutingProblem",
    "Target",
    "VehicleState",
    "lower_bound_s",
    "solve",
]
