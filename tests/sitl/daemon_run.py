"""A whole ``uavloc daemon`` search against real SITL autopilots, with the companion emulator
supplying RSSI (sim_link/vehicles/companion.py) -- shared by tests/sitl/test_daemon_*.py.

The scenario is small (300 m x 300 m, 3 static people, 10 m/s) so a search takes a few minutes of
wall time at the harness's speed-up. The daemon runs as the operator runs it (``python -m
uavloc_gcs daemon``, a child process); the companions run in a thread of the test process.
"""

from __future__ import annotations

import asyncio
import csv
import math
import os
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from uavloc_gcs.scenario import loads_scenario

from . import harness

ROOT = Path(__file__).resolve().parents[2]
SPEED_M_S = 10.0  # the stock SITL copter's WPNAV_SPEED; PX4's MPC_XY_VEL_MAX is 12

SCENARIO = """
name = "sitl-{name}"
[area]
origin_lat_deg = {lat}
origin_lon_deg = {lon}
width_m = 300.0
height_m = 300.0
[fleet]
vehicles = {n}
autopilot = "{autopilot}"
speed_m_s = {speed}
altitude_m = 40.0
comm_range_m = 120.0
energy_budget_j = 400000.0
[people]
required_accuracy_m = {required}
[planner]
time_limit_s = 0.2
{scan}
[simulation]
people = 3
seed = {seed}
motion = "static"
[link]
connections = {connections}
rssi_connections = {rssi}
lost_timeout_s = 10.0
"""

# ArduCopter: the companion on serial1 gets position and time streams, and ArduPilot forwards its
# RSSI message (an id it does not know) to the ground only with MAV2_OPTIONS bit 3 on that port.
# A 20 Ah battery: the stock SITL battery is too small for a search.
AP_COMPANION_PARAMS = {"MAV2_POSITION": 10, "MAV2_EXTRA3": 2, "MAV2_OPTIONS": 8, "BATT_CAPACITY": 20000}


@dataclass
class Vehicle:
    sitl: harness.SitlProcess
    companion_url: str  # where the companion emulator talks to the autopilot
    rssi_url: str | None = None  # where the companion sends RSSI beside the autopilot (its udpout)
    daemon_rssi: str = ""  # what the daemon listens on for that RSSI
    connection: str = ""  # the daemon's connection to the autopilot (default: the harness's)

    def __post_init__(self):
        self.connection = self.connection or self.sitl.connection


def start_arducopter(sitl_factory, sysid: int = 1, **kw) -> Vehicle:
    """``kw``: passed to the harness (``wait="heartbeat"`` for a freshly booted vehicle)."""
    port = harness.free_udp_port()
    proc = sitl_factory("ardupilot", sysid=sysid, serial1=f"udpclient:127.0.0.1:{port}", params=AP_COMPANION_PARAMS,
                        **kw)
    return Vehicle(proc, f"udpin:127.0.0.1:{port}")


def start_px4(sitl_factory, **kw) -> Vehicle:
    """PX4 drops the RSSI message, so its companion sends it beside the autopilot."""
    proc = sitl_factory("px4", **kw)
    rport = harness.free_udp_port()
    return Vehicle(proc, f"udpin:127.0.0.1:{14540 + proc.instance}", f"udpout:127.0.0.1:{rport}",
                   f"udpin:127.0.0.1:{rport}")


def scenario_text(name: str, autopilot: str, vehicles: list[Vehicle], seed: int = 3, scan: str = "",
                  required_m: float = 15.0) -> str:
    """``scan``: extra TOML, e.g. a sparser scan (``[scan]\nlane_spacing_m = 150``) that leaves
    people for the look phase; ``required_m``: the accuracy asked for (95 % radius)."""
    lat, lon = vehicles[0].sitl.home[:2]
    q = lambda xs: "[" + ", ".join(f'"{x}"' for x in xs) + "]"  # noqa: E731
    return SCENARIO.format(name=name, lat=lat, lon=lon, n=len(vehicles), autopilot=autopilot, speed=SPEED_M_S,
                           seed=seed, scan=scan, required=required_m, connections=q(v.connection for v in vehicles),
                           rssi=q(v.daemon_rssi for v in vehicles))


class Companions:
    """The companion emulators of a fleet, in a thread with its own event loop."""

    def __init__(self, scenario, vehicles: list[Vehicle]):
        from sim_link.vehicles.companion import CompanionEmulator
        from sim_link.world import World

        world = World(scenario, seed=scenario.simulation.seed)
        self.emulators = [CompanionEmulator(scenario, v.companion_url, world=world, rssi_url=v.rssi_url)
                          for v in vehicles]
        self._loop = asyncio.new_event_loop()
        self._stop: asyncio.Event | None = None
        self._ready = threading.Event()
        self._thread = threading.Thread(target=self._main, daemon=True)
        self.error: BaseException | None = None

    def _main(self) -> None:
        async def go():
            self._stop = asyncio.Event()
            self._ready.set()
            await asyncio.gather(*(e.run(self._stop) for e in self.emulators))
        try:
            self._loop.run_until_complete(go())
        except BaseException as exc:  # noqa: BLE001 - reported by the test
            self.error = exc
            self._ready.set()

    def __enter__(self) -> "Companions":
        self._thread.start()
        self._ready.wait(10)
        return self

    def __exit__(self, *exc) -> None:
        if self._stop is not None:
            self._loop.call_soon_threadsafe(self._stop.set)
        self._thread.join(15)


@dataclass
class SearchRun:
    code: int
    output: str
    wall_s: float
    people: list[dict]
    out: Path


def run_daemon(config: Path, out: Path, timeout_s: float = 900.0, extra: tuple = ()) -> SearchRun:
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    t0 = time.monotonic()
    proc = subprocess.run([sys.executable, "-m", "uavloc_gcs", "daemon", "--config", str(config), "--out", str(out),
                           "--connect-timeout", "60", *extra], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=timeout_s)
    wall = time.monotonic() - t0
    people = []
    if (out / "people.csv").exists():
        with open(out / "people.csv", newline="") as f:
            people = list(csv.DictReader(f))
    return SearchRun(proc.returncode, proc.stdout + proc.stderr, wall, people, out)


COVERAGE: list[tuple[float, float]] = []  # (true error m, 95 % radius m) of every person of every search


def truth_check(scenario, people: list[dict]) -> list[tuple[int, float, float, bool]]:
    """[(person, true error m, 95 % radius m, located)] for every person heard (static people)."""
    from sim_link.world import World

    world = World(scenario, seed=scenario.simulation.seed)
    ids = [int(e) for e in world.emitter_ids]
    xy = world.positions(0.0)
    rows = []
    for p in people:
        eid = int(p["emitter_id"])
        east, north = float(p["east_m"] or "nan"), float(p["north_m"] or "nan")
        i = ids.index(eid)
        rows.append((eid, math.hypot(east - xy[i][0], north - xy[i][1]), float(p["radius95_m"] or "nan"),
                     p["located"] == "1"))
    return rows


async def _vehicle_state(connection: str, sysid: int, seconds: float) -> tuple[bool, float, float, float, int | None]:
    """(armed, relative altitude m, lat, lon, MAV_LANDED_STATE or None) of a vehicle, heard on its
    ground-station link."""
    from uavloc_gcs.link import open_link, set_message_interval

    async with await open_link(connection, source_system=246) as link:
        hb = await link.wait_heartbeat(sysid, timeout_s=seconds)
        try:
            await set_message_interval(link, sysid, 1, 33, 0.2)
        except Exception:  # noqa: BLE001 - it streams it anyway after the daemon asked
            pass
        pos = await link.recv_match(types="GLOBAL_POSITION_INT", source_system=sysid, timeout_s=seconds)
        hb = await link.recv_match(types="HEARTBEAT", source_system=sysid, timeout_s=seconds) or hb
        ext = await link.recv_match(types="EXTENDED_SYS_STATE", source_system=sysid, timeout_s=3.0)
        return (bool(hb.base_mode & 128), pos.relative_alt / 1000.0, pos.lat / 1e7, pos.lon / 1e7,
                None if ext is None else int(ext.landed_state))


def landed_and_disarmed(vehicle: Vehicle, timeout_s: float = 60.0) -> tuple[bool, str]:
    """Whether the vehicle is disarmed on the ground within 10 m of its home (it may take a few
    seconds after landing to disarm). On the ground: under 1 m relative altitude, or the
    autopilot's own landed state (PX4 SITL once landed with its height estimate at 2.2 m)."""
    from uavloc_gcs.dialect import mavlink
    from uavloc_gcs.geo import LocalFrame

    s = vehicle.sitl
    end = time.monotonic() + timeout_s
    state = None
    while time.monotonic() < end:
        state = asyncio.run(_vehicle_state(vehicle.connection, s.sysid, 10.0))
        armed, alt, lat, lon, landed = state
        e, n = LocalFrame(s.home[0], s.home[1]).to_local(lat, lon)
        if not armed and (alt < 1.0 or landed == mavlink.MAV_LANDED_STATE_ON_GROUND) and math.hypot(e, n) < 10.0:
            return True, f"disarmed at {math.hypot(e, n):.1f} m from home, {alt:.1f} m up, landed state {landed}"
        time.sleep(2.0)
    return False, f"not home and disarmed: {state}"


def load(text: str, path: Path):
    path.write_text(text)
    return loads_scenario(text, source=str(path))
