"""Measure what each SITL autopilot flies for an orbit look (docs/science/looks.md).

    .venv/bin/python -m tests.sitl.orbit_measure [ardupilot|px4 ...] [--radius 60] [--speed 10]

One vehicle takes off to 30 m and flies, 150 m north of home, (A) NAV_LOITER_TURNS of 2 turns at
``--radius`` around a centre and then, 150 m south of home, (B) a ring of 12 pass-through waypoints
on a circle of the same radius, twice round, then returns. Positions (GLOBAL_POSITION_INT at 10 Hz,
the autopilot's own boot time) are split by MISSION_CURRENT and summarised per part: distance to
the centre (mean, 5-95 %), ground speed, time per turn (angle swept over time), direction, where the
vehicle left the loiter. Prints one line of figures per part and writes the raw track as CSV
(``--out DIR``).
"""

from __future__ import annotations

import argparse
import asyncio
import csv
import math
import sys
from pathlib import Path

import numpy as np

from uavloc_gcs.link import flavour_for, open_link, request_streams, return_home, start_mission_from, upload_mission
from uavloc_gcs.link.mission_download import download_mission
from uavloc_gcs.mission import (FRAME_GLOBAL_RELATIVE_ALT, NAV_WAYPOINT, MissionItem, MissionPlan, change_speed,
                                pass_through_waypoint, return_to_launch, takeoff, to_wire)

from . import harness
from .flying import Watch

NAV_LOITER_TURNS = 18
ALT_M = 30.0
K_LAT = 111_320.0


def offset(lat: float, lon: float, north_m: float, east_m: float) -> tuple[float, float]:
    return lat + north_m / K_LAT, lon + east_m / (K_LAT * math.cos(math.radians(lat)))


def build(home, radius_m: float, speed_m_s: float, ring_points: int, turns: int,
          loiter: bool = True) -> tuple[MissionPlan, dict]:
    lat0, lon0 = home
    ca = offset(lat0, lon0, 150.0, 0.0)
    cb = offset(lat0, lon0, -150.0, 0.0)
    items = [takeoff(ALT_M, lat0, lon0), change_speed(speed_m_s)]
    if loiter:
        items.append(MissionItem(NAV_LOITER_TURNS, FRAME_GLOBAL_RELATIVE_ALT, (float(turns), 0.0, radius_m, 0.0),
                                 ca[0], ca[1], ALT_M))
    ring = []
    for k in range(ring_points * turns + 1):
        a = 2 * math.pi * k / ring_points  # counter-clockwise from east
        ring.append(offset(*cb, radius_m * math.sin(a), radius_m * math.cos(a)))
    items += [pass_through_waypoint(lat, lon, ALT_M) for lat, lon in ring]
    items.append(return_to_launch())
    # seq numbers of the parts in the model (1-based item number = ArduPilot seq)
    first = 4 if loiter else 3
    parts = {"loiter_turns": (3, 3) if loiter else (-9, -9), "ring": (first, first - 1 + len(ring))}
    return MissionPlan(tuple(items), lat0, lon0, autopilot="ardupilot"), {"A": ca, "B": cb, "parts": parts}


def summarise(rows, centre, radius_m: float) -> dict:
    t = np.array([r[0] for r in rows])
    lat = np.array([r[2] for r in rows])
    lon = np.array([r[3] for r in rows])
    n = (lat - centre[0]) * K_LAT
    e = (lon - centre[1]) * K_LAT * math.cos(math.radians(centre[0]))
    d = np.hypot(n, e)
    speed = np.array([math.hypot(r[5], r[6]) for r in rows])
    on = d > 0.5 * radius_m  # on the circle (not the approach from far or the centre)
    ang = np.unwrap(np.arctan2(n, e))
    swept = ang[-1] - ang[0]
    # the circle part: from the first time within 15 % of the radius
    near = np.nonzero(np.abs(d - radius_m) < 0.15 * radius_m)[0]
    out = {"duration_s": float(t[-1] - t[0]), "samples": len(rows)}
    if len(near):
        i0 = near[0]
        ts, angs = t[i0:], ang[i0:]
        sw = angs[-1] - angs[0]
        out.update(
            circle_s=float(ts[-1] - ts[0]), swept_turns=float(sw / (2 * math.pi)),
            direction="counter-clockwise" if sw > 0 else "clockwise",
            s_per_turn=float((ts[-1] - ts[0]) / max(abs(sw) / (2 * math.pi), 1e-9)),
            dist_mean_m=float(d[i0:].mean()), dist_p5_m=float(np.percentile(d[i0:], 5)),
            dist_p95_m=float(np.percentile(d[i0:], 95)), speed_mean_m_s=float(speed[i0:].mean()),
            speed_p5_m_s=float(np.percentile(speed[i0:], 5)), speed_p95_m_s=float(np.percentile(speed[i0:], 95)),
            entry_bearing_deg=float(math.degrees(math.atan2(e[i0], n[i0])) % 360),
            exit_bearing_deg=float(math.degrees(math.atan2(e[-1], n[-1])) % 360), exit_dist_m=float(d[-1]))
    else:
        out.update(dist_mean_m=float(d.mean()), dist_max_m=float(d.max()), speed_mean_m_s=float(speed.mean()),
                   swept_turns=float(swept / (2 * math.pi)), on_circle_share=float(on.mean()))
    return out


async def fly(sitl, kind: str, radius_m: float, speed_m_s: float, out: Path | None, ring_points: int = 12) -> dict:
    rows: list[tuple] = []
    async with await open_link(sitl.connection) as link:
        hb = await link.wait_heartbeat(sitl.sysid, timeout_s=30)
        system = hb.get_srcSystem()
        watch = Watch(link, system)
        flavour = flavour_for(hb.autopilot)
        streams = {"SYSTEM_TIME": 1.0, "GLOBAL_POSITION_INT": 10.0, "MISSION_CURRENT": 2.0, "HOME_POSITION": 0.5,
                   "EXTENDED_SYS_STATE": 1.0}
        await request_streams(link, system, flavour, streams)
        await watch.until("position", lambda: "GLOBAL_POSITION_INT" in watch.last and "MISSION_CURRENT" in watch.last, 30)

        def on_pos(msg):
            rows.append((msg.time_boot_ms / 1000.0, watch.mission_seq, msg.lat / 1e7, msg.lon / 1e7,
                         msg.relative_alt / 1000.0, msg.vx / 100.0, msg.vy / 100.0))
        sub = link.subscribe("GLOBAL_POSITION_INT", source_system=system, callback=on_pos)
        home = watch.latlon
        plan, geo = build(home, radius_m, speed_m_s, ring_points=ring_points, turns=2)
        wire = to_wire(plan, kind)
        stored_note = "verified"
        watch.mark_upload()
        try:
            await upload_mission(link, system, 1, wire, verify=True, autopilot=flavour)
        except Exception as exc:  # refused or stored differently: record it, fly the ring alone
            stored_note = f"NAV_LOITER_TURNS: {exc}"
            plan, geo = build(home, radius_m, speed_m_s, ring_points=ring_points, turns=2, loiter=False)
            wire = to_wire(plan, kind)
            await upload_mission(link, system, 1, wire, verify=True, autopilot=flavour)
        back = await download_mission(link, system, 1)
        loiter_back = [w for w in back if w.command == NAV_LOITER_TURNS]
        await start_mission_from(link, system, 1, flavour, flavour.first_mission_seq, armed=watch.armed, mode=watch.mode)
        last_seq = max(w.seq for w in wire)
        await watch.until("mission end", lambda: (watch.mission_seq or 0) >= last_seq or watch.mode in ("RTL", "AUTO.RTL"),
                          600, poll_s=0.5)
        await return_home(link, system, 1)
        await watch.until("landing", lambda: watch.landed, 200)
        sub.close()
        watch.close()
    shift = 0 if flavour.home_at_seq0 else 1  # model item k is wire seq k (AP) or k-1 (PX4)
    (a0, a1), (b0, b1) = geo["parts"]["loiter_turns"], geo["parts"]["ring"]
    part_a = [r for r in rows if r[1] is not None and a0 - shift <= r[1] <= a1 - shift]
    # the ring: from reaching its first waypoint to reaching its last
    part_b = [r for r in rows if r[1] is not None and b0 + 1 - shift <= r[1] <= b1 - shift]
    res = {"kind": kind, "stored": stored_note,
           "loiter_item_back": [(w.param1, w.param2, w.param3, w.param4) for w in loiter_back],
           "A_loiter_turns": summarise(part_a, geo["A"], radius_m) if part_a else None,
           "B_ring": summarise(part_b, geo["B"], radius_m) if part_b else None}
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        with open(out / f"orbit-{kind}-r{radius_m:g}-n{ring_points}.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["t_boot_s", "mission_seq", "lat", "lon", "rel_alt_m", "vn_m_s", "ve_m_s"])
            w.writerows(rows)
    return res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("kinds", nargs="*", default=["ardupilot", "px4"])
    ap.add_argument("--radius", type=float, default=60.0)
    ap.add_argument("--speed", type=float, default=10.0)
    ap.add_argument("--ring-points", type=int, default=12)
    ap.add_argument("--out", type=Path, default=None)
    a = ap.parse_args(argv)
    for kind in a.kinds:
        reason = harness.skip_reason(kind)
        if reason:
            print(f"{kind}: {reason}", file=sys.stderr)
            return 2
        starter = harness.start_arducopter if kind == "ardupilot" else harness.start_px4
        with starter() as sitl:
            res = harness.run(fly(sitl, kind, a.radius, a.speed, a.out, a.ring_points), timeout_s=900)
        for k, v in res.items():
            if isinstance(v, dict):
                v = ", ".join(f"{kk} {vv:.1f}" if isinstance(vv, float) else f"{kk} {vv}" for kk, vv in v.items())
            print(f"{kind} {k}: {v}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
