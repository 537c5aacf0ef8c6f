"""Measure how each SITL autopilot reports its landing (issue 42 item 1; docs/guide/daemon.md).

    .venv/bin/python -m tests.sitl.landing_measure [ardupilot|px4 ...]

One vehicle takes off to 20 m, flies 40 m north and returns (RTL). From the RTL on, every
HEARTBEAT (armed, mode), EXTENDED_SYS_STATE (landed state) and GLOBAL_POSITION_INT (relative
altitude, climb rate, ground speed) is kept with the autopilot's boot time, and the landing is
summarised: when the old height-and-speed rule (below 1.5 m, and disarmed or under 0.5 m/s over
ground) first said "on the ground", when the landed state first said ON_GROUND, when the HEARTBEAT
first said disarmed, the altitude and climb rate at each, and whether the height-and-speed rule
flipped back to "airborne" while the vehicle was still armed (the "landed" -> "airborne again"
flip of issue 42).
"""

from __future__ import annotations

import argparse
import asyncio
import math
import sys

from uavloc_gcs.link import flavour_for, open_link, request_streams, return_home, start_mission_from, upload_mission
from uavloc_gcs.mission import flight_mission, to_wire

from . import harness
from .flying import Watch

ALT_M = 20.0
K_LAT = 111_320.0
OLD_LANDED_ALT_M = 1.5  # the rule the daemon used before issue 42 (service/vehicle.py)
LANDED_STATES = {0: "UNDEFINED", 1: "ON_GROUND", 2: "IN_AIR", 3: "TAKEOFF", 4: "LANDING"}


def old_rule(armed: bool, alt_m: float, ground_speed_m_s: float) -> bool:
    return math.isfinite(alt_m) and alt_m < OLD_LANDED_ALT_M and (not armed or ground_speed_m_s < 0.5)


async def fly(sitl, kind: str) -> dict:
    rows: list[dict] = []  # one per GLOBAL_POSITION_INT after the RTL: the state then
    state = {"armed": None, "mode": "?", "landed": None, "rtl": False}
    async with await open_link(sitl.connection) as link:
        hb = await link.wait_heartbeat(sitl.sysid, timeout_s=30)
        system = hb.get_srcSystem()
        watch = Watch(link, system)
        flavour = flavour_for(hb.autopilot)
        await request_streams(link, system, flavour, {"SYSTEM_TIME": 1.0, "GLOBAL_POSITION_INT": 10.0,
                                                      "MISSION_CURRENT": 2.0, "EXTENDED_SYS_STATE": 5.0})
        await watch.until("position", lambda: all(k in watch.last for k in ("GLOBAL_POSITION_INT", "MISSION_CURRENT", "HEARTBEAT")), 30)

        def on_msg(msg) -> None:
            kind_ = msg.get_type()
            if kind_ == "HEARTBEAT" and msg.autopilot != 8:
                state["armed"] = bool(msg.base_mode & 128)
                state["mode"] = flavour.mode_name(msg.custom_mode, msg.type)
            elif kind_ == "EXTENDED_SYS_STATE":
                state["landed"] = int(msg.landed_state)
            elif kind_ == "GLOBAL_POSITION_INT" and state["rtl"]:
                rows.append(dict(t_s=msg.time_boot_ms / 1000.0, alt_m=msg.relative_alt / 1000.0,
                                 vz_m_s=-msg.vz / 100.0, gs_m_s=math.hypot(msg.vx, msg.vy) / 100.0,
                                 armed=state["armed"], mode=state["mode"], landed=state["landed"]))

        sub = link.subscribe(None, source_system=system, callback=on_msg)
        lat0, lon0 = watch.latlon
        wire = to_wire(flight_mission([(lat0 + 40.0 / K_LAT, lon0)], alt_m=ALT_M, speed_m_s=5.0, autopilot=kind,
                                      home_latlon_deg=(lat0, lon0), include_takeoff=True), kind)
        await upload_mission(link, system, 1, wire, verify=True, autopilot=flavour)
        await start_mission_from(link, system, 1, flavour, flavour.first_mission_seq, armed=watch.armed, mode=watch.mode)
        await watch.until("take-off", lambda: watch.armed and watch.rel_alt_m > ALT_M - 3, 120)
        await watch.until("the waypoint", lambda: math.hypot(watch.latlon[0] - lat0 - 40.0 / K_LAT, 0) * K_LAT < 5, 120)
        state["rtl"] = True
        await return_home(link, system, 1)
        await watch.until("disarm", lambda: not watch.armed, 200)
        await asyncio.sleep(3.0)  # and a little after it
        sub.close()
        watch.close()
    return summarise(kind, rows)


def rows_before_disarm(rows: list[dict], seconds: float = 10.0) -> list[dict]:
    end = next((r["t_s"] for r in rows if r["armed"] is False), rows[-1]["t_s"] if rows else 0.0)
    return [r for r in rows if end - seconds <= r["t_s"] <= end + 1.0]


def summarise(kind: str, rows: list[dict]) -> dict:
    def first(pred):
        return next((r for r in rows if pred(r)), None)

    old = first(lambda r: old_rule(bool(r["armed"]), r["alt_m"], r["gs_m_s"]))
    ground = first(lambda r: r["landed"] == 1)
    disarmed = first(lambda r: r["armed"] is False)
    flips = 0
    said = False
    for r in rows:
        now = old_rule(bool(r["armed"]), r["alt_m"], r["gs_m_s"])
        if said and not now and r["armed"]:
            flips += 1
        said = now
    fmt = (lambda r: "never" if r is None else
           f"t={r['t_s']:.1f} s alt {r['alt_m']:.2f} m climb {r['vz_m_s']:+.2f} m/s {'armed' if r['armed'] else 'disarmed'} "
           f"{r['mode']} landed state {LANDED_STATES.get(r['landed'], r['landed'])}")
    out = {"kind": kind, "rows": rows, "old rule said on the ground": fmt(old), "landed state ON_GROUND": fmt(ground),
           "disarmed": fmt(disarmed), "old rule flipped back while armed": flips,
           "seconds old rule before disarm": (disarmed["t_s"] - old["t_s"]) if old and disarmed else math.nan,
           "seconds ON_GROUND before disarm": (disarmed["t_s"] - ground["t_s"]) if ground and disarmed else math.nan}
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("kinds", nargs="*", default=["ardupilot", "px4"])
    p.add_argument("--rows", action="store_true", help="also print every position of the last 10 s before the disarm")
    args = p.parse_args(argv)
    for kind in args.kinds:
        reason = harness.skip_reason(kind)
        if reason:
            print(f"{kind}: {reason}", file=sys.stderr)
            return 2
        starter = harness.start_arducopter if kind == "ardupilot" else harness.start_px4
        with starter() as sitl:
            res = harness.run(fly(sitl, kind), 400)
        rows = res.pop("rows")
        for k, v in res.items():
            print(f"{kind}: {k}: {v}")
        if args.rows:
            for r in rows_before_disarm(rows):
                print(f"{kind}:   t={r['t_s']:.1f} alt {r['alt_m']:.2f} climb {r['vz_m_s']:+.2f} "
                      f"{'armed' if r['armed'] else 'disarmed'} {r['mode']} {LANDED_STATES.get(r['landed'])}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
