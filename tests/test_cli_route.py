"""``uavloc route`` end to end, through the real entry point."""

import json
import subprocess
import sys

import pytest

INSTANCE = {
    "speed_m_s": 25, "t0_s": 0,
    "vehicles": [{"id": "uav1", "start_xy_m": [0, 0], "home_xy_m": [0, 0], "energy_j": 200000},
                 {"id": "uav2", "start_xy_m": [100, 50], "home_xy_m": [0, 0], "energy_j": 200000}],
    "targets": [{"id": "p1", "xy_m": [300, 200], "velocity_m_s": [1, 0], "radius_m": 40},
                {"id": "p2", "xy_m": [-300, 100], "velocity_m_s": [0, 0], "radius_m": 60},
                {"id": "p3", "xy_m": [-200, -250], "velocity_m_s": [0, 1.5], "radius_m": 30},
                {"id": "p4", "xy_m": [400, -100], "velocity_m_s": [0, 0], "radius_m": 50}],
}


def _run(*args):
    return subprocess.run([sys.executable, "-m", "uavloc_gcs", "route", *args], capture_output=True,
                          text=True, timeout=120)


@pytest.mark.parametrize("solver", ["epso", "ga", "ortools"])
def test_route_writes_json_and_png(tmp_path, solver):
    inst = tmp_path / "inst.json"
    inst.write_text(json.dumps(INSTANCE))
    out, png = tmp_path / "plan.json", tmp_path / "plan.png"
    r = _run(str(inst), "--solver", solver, "--time-limit", "0.3", "--seed", "1", "--out", str(out),
             "--png", str(png))
    assert r.returncode == 0, r.stderr
    assert r.stdout == ""
    doc = json.loads(out.read_text())
    assert doc["solver"] == solver
    assert sorted(t for route in doc["routes"] for t in route["targets"]) == ["p1", "p2", "p3", "p4"]
    assert doc["makespan_s"] >= doc["lower_bound_s"] > 0
    assert png.read_bytes()[:4] == b"\x89PNG"
    assert "makespan" in r.stderr and "uav1" in r.stderr


def test_route_to_stdout(tmp_path):
    inst = tmp_path / "inst.json"
    inst.write_text(json.dumps(INSTANCE))
    r = _run(str(inst), "--time-limit", "0.2", "--no-local-search")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["routes"][1]["vehicle"] == "uav2"


def test_bad_instance_is_one_sentence_and_exit_2(tmp_path):
    bad = json.loads(json.dumps(INSTANCE))
    bad["targets"][2]["radius_m"] = "wide"
    inst = tmp_path / "bad.json"
    inst.write_text(json.dumps(bad))
    r = _run(str(inst))
    assert r.returncode == 2
    assert "field 'targets[2].radius_m'" in r.stderr and "bad.json" in r.stderr
    assert "Traceback" not in r.stderr


def test_unreachable_target_exit_2(tmp_path):
    bad = json.loads(json.dumps(INSTANCE))
    bad["targets"][0]["xy_m"] = [50000, 0]
    inst = tmp_path / "far.json"
    inst.write_text(json.dumps(bad))
    r = _run(str(inst))
    assert r.returncode == 2
    assert "target p1" in r.stderr and "out of reach" in r.stderr


def test_the_shipped_example_instance_solves():
    from pathlib import Path

    example = Path(__file__).resolve().parents[1] / "examples" / "route_paper.json"
    proc = subprocess.run([sys.executable, "-m", "uavloc_gcs", "route", str(example), "--solver", "epso",
                           "--time-limit", "0.3", "--seed", "1"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert out["makespan_s"] >= out["lower_bound_s"] > 0
    assert sorted(t for r in out["routes"] for t in r["targets"]) == sorted(f"p{i}" for i in range(1, 13))
