import json

import pytest

from uavloc_gcs.errors import FileFormatError
from uavloc_gcs.planning import solve
from uavloc_gcs.planning.jsonio import dumps_problem, dumps_result, loads_problem

from .helpers import random_problem

GOOD = {
    "speed_m_s": 25, "t0_s": 3,
    "vehicles": [{"id": "uav1", "start_xy_m": [0, 0], "home_xy_m": [0, 0], "energy_j": 150000}],
    "targets": [{"id": "p1", "xy_m": [100, 50], "velocity_m_s": [1, 0], "radius_m": 30},
                {"id": "p2", "xy_m": [-80, 20]}],
}


def test_round_trip_and_defaults():
    p = loads_problem(json.dumps(GOOD))
    assert p.t0_s == 3 and p.targets[1].radius_m == 0 and p.targets[1].velocity_m_s == (0.0, 0.0)
    assert loads_problem(dumps_problem(p)) == p


def test_result_json_has_the_documented_fields():
    p = random_problem(5, 2)
    res = solve(p, time_limit_s=0.2)
    doc = json.loads(dumps_result(res, "epso"))
    assert set(doc) >= {"makespan_s", "lower_bound_s", "solver", "runtime_s", "routes"}
    assert set(doc["routes"][0]) >= {"vehicle", "targets", "access_points_xy_m", "duration_s", "energy_j"}
    assert sum(len(r["targets"]) for r in doc["routes"]) == 5


@pytest.mark.parametrize("edit, field", [
    (lambda d: d["vehicles"][0].pop("energy_j"), "vehicles[0].energy_j"),
    (lambda d: d["vehicles"][0].update(start_xy_m=[0]), "vehicles[0].start_xy_m"),
    (lambda d: d["targets"][1].update(radius_m=-1), "targets[1].radius_m"),
    (lambda d: d["targets"][0].update(xy_m=["a", 1]), "targets[0].xy_m"),
    (lambda d: d["targets"][0].update(id=7), "targets[0].id"),
    (lambda d: d.update(speed_m_s=True), "speed_m_s"),
    (lambda d: d.update(targets={}), "targets"),
])
def test_bad_fields_are_named(edit, field):
    d = json.loads(json.dumps(GOOD))
    edit(d)
    with pytest.raises(FileFormatError) as err:
        loads_problem(json.dumps(d), path="inst.json")
    assert f"inst.json, field '{field}':" in str(err.value)


def test_not_json_names_the_line():
    with pytest.raises(FileFormatError, match="inst.json, line 2: not valid JSON"):
        loads_problem('{"speed_m_s": 25,\n ]', path="inst.json")
