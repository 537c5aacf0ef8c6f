"""What an upload costs a flying vehicle, measured on the real SITL autopilots.

The vehicle flies a 300 m square at 10 m/s (four equal legs, same turns). Half-way along the third
leg it gets what the daemon sends a flying vehicle with new looks: a mission of the remaining
corners (speed item, waypoints, RTL; no takeoff), uploaded, then switched to at its first item
(the speed item; ArduPilot's seq 1 after home) and started where the autopilot needs it. The cost
is that leg's time minus the mean of the second and fourth legs (no upload), in simulated
seconds, with corners "reached" within REACHED_M.

    PYTHONPATH=. python -m benchmarks.upload_cost ardupilot px4

It starts its own SITL instance through tests/sitl/harness.py (needs ../shared/sitl or the
UAVLOC_SITL_* variables). The result is the constant UPLOAD_COST_S in uavloc_gcs/search/uploads.py.
"""

from __future__ import annotations

import asyncio
import math
import sys
import time

from uavloc_gcs.geo import LocalFrame
from uavloc_gcs.link import (arm, open_link, set_message_interval, set_mode, start_mission,
                             upload_mission)
from uavloc_gcs.mission import flight_mission, to_wire
from uavloc_gcs.service.vehicle import VehicleAgent

SIDE_M = 300.0
SPEED_M_S = 10.0
ALT_M = 30.0
REACHED_M = 8.0
MSG = {"GLOBAL_POSITION_INT": 33, "MISSION_CURRENT": 42, "SYSTEM_TIME": 2}


class _Track:
    def __init__(self, link, sysid):
        self.t_s = 0.0
        self.seq = None
        self.changes: list[tuple[int, float]] = []
        self.alt_m = math.nan
        self.track: list[tuple[float, float, float]] = []  # (t, lat, lon)
        self.armed = False
        self.texts: list[str] = []
        link.subscribe(None, source_system=sysid, callback=self._on)

    def _on(self, m):
        kind = m.get_type()
        if kind == "GLOBAL_POSITION_INT":
            self.t_s = m.time_boot_ms / 1000.0
            self.alt_m = m.relative_alt / 1000.0
            self.track.append((self.t_s, m.lat / 1e7, m.lon / 1e7))
        elif kind == "MISSION_CURRENT" and m.seq != self.seq:
            self.seq = int(m.seq)
            self.changes.append((self.seq, self.t_s))
        elif kind == "HEARTBEAT" and m.get_srcComponent() == 1:
            self.armed = bool(m.base_mode & 128)
        elif kind == "STATUSTEXT":
            self.texts.append(str(m.text))


async def _until(pred, timeout_s: float, what: str) -> None:
    end = time.monotonic() + timeout_s
    while not pred():
        if time.monotonic() > end:
            raise TimeoutError(what)
        await asyncio.sleep(0.05)


async def measure(sitl) -> dict:
    ap = sitl.kind
    frame = LocalFrame(sitl.home[0], sitl.home[1])
    square = [(0.0, SIDE_M), (SIDE_M, SIDE_M), (SIDE_M, 0.0), (0.0, 0.0), (0.0, SIDE_M)]
    latlon = frame.to_wgs84_latlon(__import__("numpy").array(square, dtype=float)).tolist()
    plan = flight_mission(latlon, alt_m=ALT_M, speed_m_s=SPEED_M_S, autopilot=ap,
                          home_latlon_deg=sitl.home[:2], home_alt_amsl_m=sitl.home[2])
    items = to_wire(plan, ap)
    wp = [it.seq for it in items if it.command == 16 and (it.seq > 0 or ap == "px4")]  # the 5 corners
    async with await open_link(sitl.connection, source_system=245) as link:
        await link.wait_heartbeat(sitl.sysid, timeout_s=60)
        tr = _Track(link, sitl.sysid)
        for name, mid in MSG.items():
            try:
                await set_message_interval(link, sitl.sysid, 1, mid, 0.1 if mid == 33 else 0.5)
            except Exception as exc:  # noqa: BLE001 - PX4 refuses some; it streams them anyway
                print(f"  {name}: {exc}")
        await upload_mission(link, sitl.sysid, 1, items, verify=False, autopilot=ap)
        for _ in range(120):  # until the autopilot is ready to arm
            try:
                if ap == "ardupilot":
                    await set_mode(link, sitl.sysid, 1, "GUIDED", autopilot=ap)
                await arm(link, sitl.sysid, 1)
                break
            except Exception:  # noqa: BLE001 - pre-arm checks not passed yet
                await asyncio.sleep(1.0)
        await start_mission(link, sitl.sysid, 1, 0)
        await _until(lambda: tr.seq == wp[3], 600, "third leg")
        t_leg3 = tr.t_s
        # half-way along the leg (simulated time): the daemon's look upload and switch
        await _until(lambda: tr.t_s >= t_leg3 + 0.5 * SIDE_M / SPEED_M_S, 120, "mid-leg")
        rest = flight_mission(latlon[3:], alt_m=ALT_M, speed_m_s=SPEED_M_S, autopilot=ap,
                              home_latlon_deg=sitl.home[:2], home_alt_amsl_m=sitl.home[2], include_takeoff=False)
        look = to_wire(rest, ap)
        first = 1 if ap == "ardupilot" else 0
        agent = VehicleAgent(sitl.sysid, link, frame, autopilot=ap, epoch_unix_s=lambda: None)
        agent.tel.armed, agent.tel.mode = True, "AUTO" if ap == "ardupilot" else "AUTO.MISSION"
        w0 = time.monotonic()
        await upload_mission(link, sitl.sysid, 1, look, verify=False, autopilot=ap)
        await agent.switch_to(first, on_ground=False)  # the daemon's own sequence
        switch_wall_s = time.monotonic() - w0
        last = [it.seq for it in look if it.command == 16][-1]
        n_before = len(tr.changes)  # the seq reported before the switch is the old mission's
        await _until(lambda: any(s > last for s, _ in tr.changes[n_before:]), 300, "end of the fourth leg")
    frame_xy = [frame.to_local(lat, lon) for _, lat, lon in tr.track]
    times = [t for t, _, _ in tr.track]
    at, k = [], 0
    for corner in square:
        while k < len(times) and math.dist(frame_xy[k], corner) > REACHED_M:
            k += 1
        at.append(times[k] if k < len(times) else math.nan)
    legs = [b - a for a, b in zip(at, at[1:])]
    for c in square:
        d = [math.dist(xy, c) for xy in frame_xy]
        i = min(range(len(d)), key=d.__getitem__)
        print(f"  corner {c}: closest {d[i]:.1f} m at {times[i]:.1f} s")
    print(f"  last position {frame_xy[-1]} at {times[-1]:.1f} s, alt {tr.alt_m:.1f} m")
    return {"autopilot": ap, "legs_s": legs, "switch_wall_s": switch_wall_s,
            "cost_s": legs[2] - 0.5 * (legs[1] + legs[3]), "changes": tr.changes}


def main(argv: list[str]) -> int:
    from tests.sitl import harness  # noqa: PLC0415

    for ap in argv or ["ardupilot", "px4"]:
        start = harness.start_arducopter if ap == "ardupilot" else harness.start_px4
        with start(home=harness.HOME) as sitl:
            r = asyncio.run(measure(sitl))
        print(f"{ap}: legs {', '.join(f'{x:.1f}' for x in r['legs_s'])} s; upload+switch took "
              f"{r['switch_wall_s']:.2f} s wall; cost of the upload {r['cost_s']:.1f} s of flight")
        print("  MISSION_CURRENT changes (seq, sim s):", r["changes"])
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
