"""Per autopilot, against the real SITL: the scan ``uavloc plan`` writes goes up and comes back
through the CLI, then one vehicle arms, takes off, flies its scan, switches to a follow-up mission
uploaded in flight, returns home, lands and disarms -- all through uavloc's link layer."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

from uavloc_gcs.link import (flavour_for, open_link, request_streams, return_home,
                             start_mission_from, switch_mission, upload_mission)
from uavloc_gcs.mission import NAV_WAYPOINT, flight_mission, to_wire
from mission_io import plan as plan_file

from . import harness
from .flying import Watch, distance_m

ROOT = Path(__file__).resolve().parents[2]
ALT_M = 30.0
SPEED_M_S = 10.0

SCENARIO = """\
name = "sitl-{autopilot}"
[area]
origin_lat_deg = {lat}
origin_lon_deg = {lon}
width_m = 300.0
height_m = 150.0
[fleet]
vehicles = 1
autopilot = "{autopilot}"
altitude_m = {alt}
speed_m_s = {speed}
comm_range_m = 100.0
energy_budget_j = 150000.0
[simulation]
people = 2
seed = 3
"""


def uavloc(*args, timeout=120):
    return subprocess.run([sys.executable, "-m", "uavloc_gcs", *args], capture_output=True, text=True,
                          timeout=timeout, cwd=ROOT)


def planned(tmp_path: Path, autopilot: str) -> Path:
    """``uavloc plan`` of a small area at the SITL's home; returns the output directory."""
    lat, lon = harness.HOME[:2]
    scenario = tmp_path / "scenario.toml"
    scenario.write_text(SCENARIO.format(autopilot=autopilot, lat=lat, lon=lon, alt=ALT_M, speed=SPEED_M_S))
    out = tmp_path / "plans"
    r = uavloc("plan", str(scenario), "--out", str(out))
    assert r.returncode == 0, r.stderr
    return out


def test_cli_upload_download_verify(autopilot, tmp_path):
    kind, sitl = autopilot
    plans = planned(tmp_path, kind)
    for name in ("uav1.plan", "uav1.waypoints"):
        r = uavloc("upload", str(plans / name), "--to", sitl.connection)
        assert r.returncode == 0, f"upload {name}: {r.stderr}"
        assert "read back and verified" in r.stdout
    out = tmp_path / "back.plan"
    r = uavloc("download", "--from", sitl.connection, "--out", str(out))
    assert r.returncode == 0, r.stderr
    sent, back = plan_file.read(plans / "uav1.plan"), plan_file.read(out)
    assert [it.command for it in back.items] == [it.command for it in sent.items]
    # what QGC writes: altitude-relative positions in frame 3, non-positional items in frame 2,
    # the vehicle's home (HOME_POSITION) as the planned home
    doc = json.loads(out.read_text())["mission"]
    assert {it["frame"] for it in doc["items"] if it["command"] == NAV_WAYPOINT} == {3}
    assert {it["frame"] for it in doc["items"] if it["command"] in (178, 20)} == {2}
    home = doc["plannedHomePosition"]
    assert home[0] == pytest.approx(harness.HOME[0], abs=1e-4) and home[1] == pytest.approx(harness.HOME[1], abs=1e-4)
    r = uavloc("download", "--from", sitl.connection, "--out", str(tmp_path / "back.waypoints"))
    assert r.returncode == 0, r.stderr
    r = uavloc("upload", str(tmp_path / "back.waypoints"), "--to", sitl.connection)
    assert r.returncode == 0, f"re-upload of a download: {r.stderr}"


def test_fly_scan_switch_and_return(autopilot, tmp_path):
    kind, sitl = autopilot
    plans = planned(tmp_path, kind)
    harness.run(_fly(sitl, kind, plans / "uav1.plan"), timeout_s=420)


async def _fly(sitl, kind: str, plan_path: Path) -> None:
    t0 = time.monotonic()
    marks = {}
    async with await open_link(sitl.connection) as link:
        hb = await link.wait_heartbeat(sitl.sysid, timeout_s=30)
        system = hb.get_srcSystem()
        watch = Watch(link, system)
        flavour = flavour_for(hb.autopilot)
        accepted = await request_streams(link, system, flavour)
        assert accepted["GLOBAL_POSITION_INT"] and accepted["SYSTEM_TIME"], accepted
        await watch.until("GLOBAL_POSITION_INT, MISSION_CURRENT and SYSTEM_TIME streams",
                          lambda: all(k in watch.last for k in ("HEARTBEAT", "GLOBAL_POSITION_INT",
                                                                "MISSION_CURRENT", "SYSTEM_TIME")), 30)
        home = watch.latlon
        scan = to_wire(plan_file.read(plan_path), kind)
        await upload_mission(link, system, 1, scan, verify=True, autopilot=flavour)
        waypoints = [it.seq for it in scan if it.command == NAV_WAYPOINT and it.seq >= flavour.first_mission_seq]
        await start_mission_from(link, system, 1, flavour, flavour.first_mission_seq, armed=watch.armed,
                                 mode=watch.mode)
        marks["started"] = time.monotonic() - t0
        await watch.until("armed take-off", lambda: watch.armed and watch.rel_alt_m > ALT_M - 5, 90)
        # the scan is flown: MISSION_CURRENT moves on past its second waypoint
        await watch.until("scan progress", lambda: (watch.mission_seq or 0) > waypoints[1], 120)
        marks["scan progressed"] = time.monotonic() - t0

        # a follow-up mission uploaded and switched to while flying
        lat0, lon0 = home
        targets = [(lat0 + 0.0006, lon0 - 0.0004), (lat0 + 0.0002, lon0 - 0.0006)]
        follow = to_wire(flight_mission(targets, alt_m=ALT_M, speed_m_s=SPEED_M_S, autopilot=kind,
                                        home_latlon_deg=home, include_takeoff=False), kind)
        upload_started = time.monotonic()
        await upload_mission(link, system, 1, follow, verify=True, autopilot=flavour)
        await switch_mission(link, system, 1, flavour, flavour.first_mission_seq,
                             in_mission_mode=watch.mode in ("AUTO", "AUTO.MISSION"), mission_state=watch.mission_state)
        marks["switch took"] = time.monotonic() - upload_started
        first_wp = next(it.seq for it in follow if it.command == NAV_WAYPOINT and it.seq >= flavour.first_mission_seq)
        await watch.until("arrival at the follow-up's first waypoint",
                          lambda: distance_m(*watch.latlon, *targets[0]) < 8.0, 120)
        assert watch.mode in ("AUTO", "AUTO.MISSION"), watch.mode
        assert (watch.mission_seq or 0) >= first_wp

        await return_home(link, system, 1)
        await watch.until("landing and disarm", lambda: watch.landed, 150)
        marks["landed"] = time.monotonic() - t0
        assert distance_m(*watch.latlon, *home) < 5.0, (watch.latlon, home)
        watch.close()
    print(f"{kind}: " + ", ".join(f"{k} {v:.1f} s" for k, v in marks.items()))
