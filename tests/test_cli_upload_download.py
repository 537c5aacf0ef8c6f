"""``uavloc upload`` / ``uavloc download`` as a user runs them, against the fake vehicles."""

import math
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from mission_io import plan as plan_file
from mission_io import waypoints as waypoints_file
from sim_link.vehicles.fleet import FakeFleet
from uavloc_gcs.mission import flight_mission
from uavloc_gcs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
KEY_HEX = "a5" * 32


def uavloc(*args, timeout=60):
    return subprocess.run([sys.executable, "-m", "uavloc_gcs", *args], capture_output=True, text=True,
                          timeout=timeout, cwd=ROOT)


@pytest.fixture(params=["ardupilot", "px4"])
def fleet(request):
    sc = load_scenario(ROOT / "examples" / "small.toml")
    sc = sc.replace(fleet={"autopilot": request.param, "vehicles": 1})
    f = FakeFleet(sc, speedup=1, seed=1, base_port=0).start_in_thread()
    yield request.param, f
    f.stop()


def _mission(autopilot, n=12):
    pts = [(47.3977 + 0.0002 * i, 8.5456 + 0.0001 * (i % 3)) for i in range(n)]
    return flight_mission(pts, alt_m=40.0, speed_m_s=8.0, autopilot=autopilot,
                          home_latlon_deg=(47.3977, 8.5456), home_alt_amsl_m=488.0)


def test_upload_then_download_round_trips_through_a_fake_vehicle(fleet, tmp_path):
    autopilot, f = fleet
    (_, conn), = f.endpoints
    plan = _mission(autopilot)
    plan_file.write(tmp_path / "m.plan", plan)

    up = uavloc("upload", str(tmp_path / "m.plan"), "--to", conn)
    assert up.returncode == 0, up.stderr
    assert f"Uploaded {len(plan.items)} mission items" in up.stdout and "verified" in up.stdout
    assert "upload:" in up.stderr and "verify:" in up.stderr  # progress (not a terminal: plain lines)
    label = {"ardupilot": "ArduPilot", "px4": "PX4"}[autopilot]
    assert f"({label})" in up.stdout
    assert len(f.vehicle(1).mission_items) == len(plan.items) + (autopilot == "ardupilot")

    out = tmp_path / ("back.waypoints" if autopilot == "ardupilot" else "back.plan")
    down = uavloc("download", "--from", conn, "--out", str(out))
    assert down.returncode == 0, down.stderr
    assert f"Downloaded {len(plan.items)} mission items" in down.stdout
    back = waypoints_file.read(out, autopilot=autopilot) if out.suffix == ".waypoints" else plan_file.read(out)
    assert back.same_as(plan)  # every item, to the precision of the encodings
    if autopilot == "ardupilot":  # the vehicle reports its own home at seq 0
        assert not math.isnan(back.home_lat_deg)


def test_unreachable_vehicle_is_one_sentence_and_exit_3(tmp_path):
    plan_file.write(tmp_path / "m.plan", _mission("px4", 3))
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))  # a port where nothing answers
        port = s.getsockname()[1]
        r = uavloc("upload", str(tmp_path / "m.plan"), "--to", f"udpout:127.0.0.1:{port}", "--timeout", "1")
    assert r.returncode == 3
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "no heartbeat" in lines[0] and f"127.0.0.1:{port}" in lines[0]


@pytest.mark.parametrize("args, needle", [
    (["upload", "missing.plan", "--to", "udpout:127.0.0.1:25999"], "missing.plan"),
    (["upload", "x.kml", "--to", "udpout:127.0.0.1:25999"], ".plan or .waypoints"),
    (["download", "--from", "udp:127.0.0.1:25999", "--out", "x.plan"], "connection"),
    (["download", "--from", "udpout:127.0.0.1:25999", "--out", "x.csv"], ".plan or .waypoints"),
    (["download", "--from", "udpout:127.0.0.1:25999", "--out", "x.plan", "--signing-key", "12"], "signing key"),
])
def test_bad_input_is_one_sentence_and_exit_2(tmp_path, monkeypatch, capsys, args, needle):
    # in-process (the same main() the console script runs) to keep the suite fast
    from uavloc_gcs.cli import main
    (tmp_path / "x.kml").write_text("<kml/>")
    monkeypatch.chdir(tmp_path)
    assert main(args) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and needle in err


def test_signed_fleet_needs_the_key(tmp_path):
    sc = load_scenario(ROOT / "examples" / "small.toml").replace(fleet={"vehicles": 1})
    f = FakeFleet(sc, speedup=1, seed=2, base_port=0, signing_key=bytes.fromhex(KEY_HEX)).start_in_thread()
    try:
        (_, conn), = f.endpoints
        plan_file.write(tmp_path / "m.plan", _mission("px4", 4))
        no_key = uavloc("upload", str(tmp_path / "m.plan"), "--to", conn, "--timeout", "1.5")
        assert no_key.returncode == 3 and "no heartbeat" in no_key.stderr
        good = uavloc("upload", str(tmp_path / "m.plan"), "--to", conn, "--signing-key", KEY_HEX)
        assert good.returncode == 0, good.stderr
        assert len(f.vehicle(1).mission_items) == len(_mission("px4", 4).items)
    finally:
        f.stop()


FILES = ROOT / "tests" / "data" / "files"


def test_qgc4_survey_with_null_coordinates_uploads_and_verifies(fleet):
    autopilot, f = fleet
    (_, conn), = f.endpoints
    up = uavloc("upload", str(FILES / "survey_qgc4.plan"), "--to", conn)
    assert up.returncode == 0, up.stderr
    assert "Uploaded 11 mission items" in up.stdout and "verified" in up.stdout and "Traceback" not in up.stderr
    stored = f.vehicle(1).mission_items
    cams = [w for w in stored if w.command == 206]
    assert len(cams) == 4 and all((w.x, w.y) == (0, 0) for w in cams)


def test_do_jump_reaches_the_vehicle_with_its_autopilot_numbering(fleet):
    autopilot, f = fleet
    (_, conn), = f.endpoints
    up = uavloc("upload", str(FILES / "do_jump_px4.plan"), "--to", conn)
    assert up.returncode == 0, up.stderr
    stored = f.vehicle(1).mission_items
    jump = next(w for w in stored if w.command == 177)
    target = stored[int(jump.param1)]
    assert (target.command, target.x) == (16, 473985000)  # the first waypoint on either autopilot


@pytest.mark.parametrize("name", ["fence_circle.waypoints", "rally.waypoints"])
def test_fence_and_rally_files_are_refused_before_touching_the_vehicle(fleet, name):
    autopilot, f = fleet
    (_, conn), = f.endpoints
    before = list(f.vehicle(1).mission_items)
    r = uavloc("upload", str(FILES / name), "--to", conn)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "not a mission" in lines[0] and name in lines[0]
    assert f.vehicle(1).mission_items == before


def test_mission_planner_file_uploads_to_either_autopilot(fleet):
    autopilot, f = fleet
    (_, conn), = f.endpoints
    up = uavloc("upload", str(FILES / "mp_placeholders.waypoints"), "--to", conn)
    assert up.returncode == 0, up.stderr
    stored = f.vehicle(1).mission_items
    takeoff = next(w for w in stored if w.command == 22)
    # ArduPilot keeps 0, 0 ("here"); PX4 gets the planned home, where the vehicle takes off
    assert (takeoff.x, takeoff.y) == ((0, 0) if autopilot == "ardupilot" else (473977420, 85455940))
    if autopilot == "px4":
        assert all(w.frame == 2 for w in stored if w.command in (178, 206, 20))
        r = uavloc("upload", str(FILES / "line0_takeoff.waypoints"), "--to", conn)  # LAND at 0, 0; no home
        assert r.returncode == 2 and "PX4 would fly to 0 N 0 E" in r.stderr and len(r.stderr.strip().splitlines()) == 1
