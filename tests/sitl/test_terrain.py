"""ArduCopter SITL over Mount Washington's flank (issue 28): the terrain-following scan ``uavloc plan``
writes from the shipped SRTM crop (absolute altitudes, waypoints added where the ground rises) is
flown by the real autopilot, and the height above the DEM it actually flew -- its reported AMSL
altitude minus the DEM under its reported position -- never falls below the clearance."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from mission_io import plan as plan_file
from uavloc_gcs.geo import LocalFrame
from uavloc_gcs.link import flavour_for, open_link, request_streams, start_mission_from, upload_mission
from uavloc_gcs.mission import to_wire
from uavloc_gcs.terrain import load_dem

from . import harness
from .flying import Watch

ROOT = Path(__file__).resolve().parents[2]
DEM = ROOT / "uavloc_gcs" / "examples" / "mount_washington_srtm3.tif"
LAT, LON = 44.2620, -71.3180  # the area's corner and launch point, 1456 m on SRTM3
ALT_M, CLEARANCE_M, SPEED_M_S = 50.0, 30.0, 8.0
TRACKING_M = 8.0  # the autopilot's vertical tracking error we allow below the planned line

SCENARIO = f"""\
name = "sitl-terrain"
[area]
origin_lat_deg = {LAT}
origin_lon_deg = {LON}
width_m = 300.0
height_m = 150.0
[fleet]
vehicles = 1
autopilot = "ardupilot"
altitude_m = {ALT_M}
speed_m_s = {SPEED_M_S}
comm_range_m = 100.0
energy_budget_j = 150000.0
[terrain]
dem = "{DEM}"
min_clearance_m = {CLEARANCE_M}
max_climb_m_s = 2.5
max_descent_m_s = 1.5
"""

pytestmark = pytest.mark.skipif(harness.skip_reason("ardupilot") is not None,
                                reason=harness.skip_reason("ardupilot") or "")


def test_arducopter_flies_the_terrain_following_scan_above_the_clearance(tmp_path):
    scenario = tmp_path / "scenario.toml"
    scenario.write_text(SCENARIO)
    out = tmp_path / "plans"
    r = subprocess.run([sys.executable, "-m", "uavloc_gcs", "plan", str(scenario), "--out", str(out)],
                       capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    dem = load_dem(DEM, LocalFrame(LAT, LON))
    home_amsl = dem.height_at(0.0, 0.0)
    mission = plan_file.read(out / "uav1.plan")
    assert {it.frame for it in mission.items if it.command == 16} == {0}  # absolute altitudes
    with harness.start_arducopter(home=(LAT, LON, home_amsl, 0.0)) as sitl:
        track = harness.run(_fly(sitl, mission), timeout_s=900)
    lat, lon, alt, rel = track.T
    xy = dem.frame.to_local_xy(np.column_stack([lat, lon]))
    agl = alt - dem.height_xy(xy, clamp=True)
    cruising = (np.hypot(xy[:, 0], xy[:, 1]) > 25.0) & (rel > 10.0)  # not taking off or landing at home
    assert cruising.sum() > 100, cruising.sum()
    rise = float(dem.height_xy(xy[cruising]).max() - home_amsl)
    assert rise > ALT_M  # the ground under the flown track rose more than the flight altitude
    assert alt[cruising].max() - home_amsl > rise + CLEARANCE_M - TRACKING_M  # it climbed with it
    print(f"height above the DEM flown: min {agl[cruising].min():.1f} m, median {np.median(agl[cruising]):.1f} m, "
          f"ground rose {rise:.0f} m over {cruising.sum()} samples")
    assert agl[cruising].min() >= CLEARANCE_M - TRACKING_M, agl[cruising].min()


async def _fly(sitl, mission) -> np.ndarray:
    """Upload and fly ``mission`` to its landing; the GLOBAL_POSITION_INT track (lat, lon, alt
    AMSL, alt above home) as flown."""
    samples = []
    async with await open_link(sitl.connection) as link:
        hb = await link.wait_heartbeat(sitl.sysid, timeout_s=30)
        system = hb.get_srcSystem()
        watch = Watch(link, system)
        sub = link.subscribe("GLOBAL_POSITION_INT", source_system=system, callback=lambda m: samples.append(
            (m.lat / 1e7, m.lon / 1e7, m.alt / 1000.0, m.relative_alt / 1000.0)))
        flavour = flavour_for(hb.autopilot)
        await request_streams(link, system, flavour)
        await watch.until("position stream", lambda: "GLOBAL_POSITION_INT" in watch.last, 30)
        wire = to_wire(mission, "ardupilot")
        await upload_mission(link, system, 1, wire, verify=True, autopilot=flavour)
        await start_mission_from(link, system, 1, flavour, flavour.first_mission_seq, armed=watch.armed,
                                 mode=watch.mode)
        await watch.until("take-off", lambda: watch.armed and watch.rel_alt_m > 10.0, 120)
        t0 = time.monotonic()
        await watch.until("the scan, the way home and the landing", lambda: watch.landed, 780)
        sub.close()
        watch.close()
        print(f"flown in {time.monotonic() - t0:.0f} s wall")
    return np.array(samples, dtype=float)
