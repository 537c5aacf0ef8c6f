"""JSON form of a routing instance and of a planning result (``uavloc route``).

Instance (metres, seconds, joules)::

    {"speed_m_s": 25, "t0_s": 0,
     "vehicles": [{"id": "uav1", "start_xy_m": [x, y], "home_xy_m": [x, y], "energy_j": E}],
     "targets": [{"id": "p1", "xy_m": [x, y], "velocity_m_s": [vx, vy], "radius_m": r}]}

``t0_s`` and a target's ``velocity_m_s`` and ``radius_m`` are optional (0, [0, 0], 0). Sorties
(issue 38), optional: a vehicle's ``"spare_packs": k, "pack_energy_j": E`` and the instance's
``"battery_swap_s": s``; the result's routes then say ``swaps_before`` (indices into ``targets``)
and ``sortie_energy_j``.
"""

from __future__ import annotations

import json
import math
from typing import Any

from ..errors import FileFormatError
from .problem import PlanResult, RoutingProblem, Target, VehicleState


def _num(obj: dict, key: str, where: str, path: str, default: float | None = None) -> float:
    if key not in obj:
        if default is not None:
            return default
        raise FileFormatError("missing number", path=path, field=f"{where}{key}")
    v = obj[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise FileFormatError(f"expected a finite number, got {v!r}", path=path, field=f"{where}{key}")
    return float(v)


def _pair(obj: dict, key: str, where: str, path: str, default=None) -> tuple[float, float]:
    if key not in obj:
        if default is not None:
            return default
        raise FileFormatError("missing [x, y] pair", path=path, field=f"{where}{key}")
    v = obj[key]
    if (not isinstance(v, list) or len(v) != 2
            or any(isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x)
                   for x in v)):
        raise FileFormatError(f"expected [x, y] with two finite numbers, got {v!r}", path=path,
                              field=f"{where}{key}")
    if key.endswith("xy_m") and max(abs(v[0]), abs(v[1])) > MAX_COORDINATE_M:
        raise FileFormatError(f"{v[0]:.6g}, {v[1]:.6g} m is more than {MAX_COORDINATE_M / 1000:g} km from the local "
                              "frame's origin (the launch point); a search area is at most 50 km across", path=path,
                              field=f"{where}{key}")
    return float(v[0]), float(v[1])


def _id(obj: dict, where: str, path: str) -> str:
    v = obj.get("id")
    if not isinstance(v, str) or not v:
        raise FileFormatError(f"expected a non-empty string, got {v!r}", path=path, field=f"{where}id")
    return v


def _list(doc: dict, key: str, path: str) -> list:
    v = doc.get(key)
    if not isinstance(v, list):
        raise FileFormatError(f"expected a list, got {type(v).__name__}", path=path, field=key)
    return v


MAX_SPEED_M_S = 60.0  # as scenario.py's fleet.speed_m_s
MAX_COORDINATE_M = 1_000_000.0  # local east/north metres about the launch point


def loads_problem(text: str, path: str = "<string>") -> RoutingProblem:
    """Parse an instance; FileFormatError names the file and the field (e.g. vehicles[1].energy_j)."""
    try:
        doc: Any = json.loads(text)
    except json.JSONDecodeError as err:
        raise FileFormatError(f"not valid JSON: {err.msg}", path=path, line=err.lineno) from None
    if not isinstance(doc, dict):
        raise FileFormatError("expected a JSON object at the top level", path=path)
    vehicles = []
    for k, v in enumerate(_list(doc, "vehicles", path)):
        w = f"vehicles[{k}]."
        if not isinstance(v, dict):
            raise FileFormatError("expected an object", path=path, field=w[:-1])
        energy = _num(v, "energy_j", w, path)
        if energy < 0:
            raise FileFormatError(f"energy must be >= 0, got {energy}", path=path, field=w + "energy_j")
        spare = v.get("spare_packs", 0)
        if isinstance(spare, bool) or not isinstance(spare, int) or spare < 0:
            raise FileFormatError(f"expected a whole number of packs, 0 or more, got {spare!r}", path=path,
                                  field=w + "spare_packs")
        pack = _num(v, "pack_energy_j", w, path, 0.0)
        if spare and pack <= 0:
            raise FileFormatError(f"a spare pack's usable energy must be > 0 J, got {pack}", path=path,
                                  field=w + "pack_energy_j")
        vehicles.append(VehicleState(_id(v, w, path), _pair(v, "start_xy_m", w, path),
                                     _pair(v, "home_xy_m", w, path), energy, spare, pack))
    targets = []
    for k, t in enumerate(_list(doc, "targets", path)):
        w = f"targets[{k}]."
        if not isinstance(t, dict):
            raise FileFormatError("expected an object", path=path, field=w[:-1])
        radius = _num(t, "radius_m", w, path, 0.0)
        if not 0 <= radius <= MAX_COORDINATE_M:
            raise FileFormatError(f"radius must be 0 to {MAX_COORDINATE_M:g} m, got {radius:g}", path=path,
                                  field=w + "radius_m")
        targets.append(Target(_id(t, w, path), _pair(t, "xy_m", w, path),
                              _pair(t, "velocity_m_s", w, path, (0.0, 0.0)), radius))
    speed = _num(doc, "speed_m_s", "", path)
    if speed <= 0:
        raise FileFormatError(f"speed must be > 0, got {speed}", path=path, field="speed_m_s")
    if speed > MAX_SPEED_M_S:  # the power model's cube of it overflowed into "needs nan J"
        raise FileFormatError(f"{speed:g} m/s is beyond any multirotor (at most {MAX_SPEED_M_S:g}, as a scenario's "
                              "fleet.speed_m_s)", path=path, field="speed_m_s")
    swap = _num(doc, "battery_swap_s", "", path, 0.0)
    if swap < 0:
        raise FileFormatError(f"swap time must be >= 0 s, got {swap}", path=path, field="battery_swap_s")
    return RoutingProblem(tuple(vehicles), tuple(targets), speed, _num(doc, "t0_s", "", path, 0.0),
                          battery_swap_s=swap)


def dumps_problem(problem: RoutingProblem) -> str:
    doc = {
        "speed_m_s": problem.speed_m_s,
        "t0_s": problem.t0_s,
        "vehicles": [{"id": v.id, "start_xy_m": list(v.start_xy_m), "home_xy_m": list(v.home_xy_m),
                      "energy_j": v.energy_j,
                      **({"spare_packs": v.spare_packs, "pack_energy_j": v.pack_energy_j} if v.spare_packs else {})}
                     for v in problem.vehicles],
        "targets": [{"id": t.id, "xy_m": list(t.xy_m), "velocity_m_s": list(t.velocity_m_s),
                     "radius_m": t.radius_m} for t in problem.targets],
    }
    if problem.has_sorties:
        doc["battery_swap_s"] = problem.battery_swap_s
    return json.dumps(doc, indent=2) + "\n"


def result_to_dict(result: PlanResult, solver: str) -> dict:
    plan = result.plan
    return {
        "makespan_s": round(plan.makespan_s, 6),
        "lower_bound_s": round(plan.lower_bound_s, 6),
        "solver": solver,
        "runtime_s": round(result.runtime_s, 4),
        "success": result.success,
        "message": result.message,
        "routes": [
            {
                "vehicle": r.vehicle_id,
                "targets": list(r.target_ids),
                "access_points_xy_m": [[round(float(x), 3), round(float(y), 3)]
                                       for x, y in r.access_points_xy_m],
                "access_times_s": [round(float(t), 3) for t in r.access_times_s],
                "duration_s": round(r.duration_s, 6),
                "energy_j": round(r.energy_j, 3),
                **({"swaps_before": list(r.swaps_before),
                    "sortie_energy_j": [round(e, 3) for e in r.sortie_energy_j]} if r.sortie_energy_j else {}),
            }
            for r in plan.routes
        ],
    }


def dumps_result(result: PlanResult, solver: str) -> str:
    return json.dumps(result_to_dict(result, solver), indent=2) + "\n"
