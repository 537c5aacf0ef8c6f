"""``python -m tests.sitl.battery_measure [ardupilot] [px4]``: each SITL's own battery, measured.

For each autopilot (one SITL each, at the suite's speed-up): its battery parameters; the pack at
rest and what uavloc's ``check_fresh_pack`` makes of it; a hover from take-off with the remaining
and the voltage every few simulated seconds (the drain per simulated minute); the pack after the
landing; whether it arms on it; MAV_CMD_BATTERY_RESET; the swap of ``tests/sitl/battery.py``; and,
on ArduCopter, the low-voltage failsafe and a reboot. Prints one line per step. The figures are in
docs/guide/sitl.md ("Battery").
"""

from __future__ import annotations

import asyncio
import sys
import time

from uavloc_gcs.dialect import mavlink as mav
from uavloc_gcs.errors import CommandError
from uavloc_gcs.link import (arm_when_ready, check_fresh_pack, command_long, flavour_for, open_link, pack_limits,
                             read_battery, request_streams, set_mode, takeoff)
from uavloc_gcs.link.mission_control import StatusWatch
from uavloc_gcs.link.params import read_param_number, set_param

from . import harness
from .battery import AP_PACK_PARAMS, MAV_CMD_BATTERY_RESET, sitl_swap
from .flying import Watch

PARAMS = {"ardupilot": ("BATT_MONITOR", "BATT_CAPACITY", "SIM_BATT_VOLTAGE", "SIM_BATT_CAP_AH", "MOT_BAT_VOLT_MAX",
                        "MOT_BAT_VOLT_MIN", "BATT_LOW_VOLT", "BATT_LOW_TIMER", "BATT_FS_LOW_ACT", "BATT_ARM_VOLT",
                        "BATT_ARM_MAH"),
          "px4": ("SIM_BAT_DRAIN", "SIM_BAT_MIN_PCT", "BAT1_N_CELLS", "BAT1_V_CHARGED", "BAT1_V_EMPTY", "BAT1_CAPACITY",
                  "BAT_LOW_THR", "BAT_CRIT_THR", "BAT_EMERGEN_THR", "COM_ARM_BAT_MIN", "COM_LOW_BAT_ACT")}
HOVER_SIM_S = 120.0


def say(text: str) -> None:
    print(text, flush=True)


def brief(r) -> str:
    parts = [f"{r.remaining_pct:.0f} %" if r.remaining_pct is not None else "remaining ?",
             f"{r.voltage_v:.3f} V" if r.voltage_v is not None else "V ?",
             f"{r.current_a:.1f} A" if r.current_a is not None else "current not measured",
             f"{r.consumed_mah:.0f} mAh" if r.consumed_mah is not None else "",
             f"charge state {r.charge_state}" if r.charge_state is not None else ""]
    return ", ".join(p for p in parts if p)


async def try_arm(link, system: int, kind: str) -> str:
    await set_mode(link, system, 1, "GUIDED" if kind == "ardupilot" else "LOITER")  # a mode it arms in
    with StatusWatch(link, system) as sw:
        sw.mark()
        try:
            await command_long(link, system, 1, mav.MAV_CMD_COMPONENT_ARM_DISARM, (1, 0), retries=1)
        except CommandError as err:
            return f"refused ({err}; says {await sw.reason_soon()!r})"
        await command_long(link, system, 1, mav.MAV_CMD_COMPONENT_ARM_DISARM, (0, 0), retries=1)
        return "armed (and disarmed again)"


async def measure(kind: str) -> None:
    speed = harness.ARDUPILOT_SPEEDUP if kind == "ardupilot" else harness.PX4_SPEEDUP
    proc = harness.start_arducopter(params=AP_PACK_PARAMS) if kind == "ardupilot" else harness.start_px4()
    try:
        async with await open_link(proc.connection) as link:
            hb = await link.wait_heartbeat(proc.sysid, timeout_s=60)
            fl = flavour_for(hb.autopilot)
            watch = Watch(link, proc.sysid)
            await request_streams(link, proc.sysid, fl, {"GLOBAL_POSITION_INT": 2.0, "EXTENDED_SYS_STATE": 1.0})
            say(f"== {kind} SITL (speed-up {speed}x{'; ' + str(AP_PACK_PARAMS) if kind == 'ardupilot' else ''})")
            values = [f"{n} {await read_param_number(link, proc.sysid, 1, n, bytewise=kind == 'px4')!s}"
                      for n in PARAMS[kind]]
            say("parameters: " + ", ".join(values))
            limits = await pack_limits(link, proc.sysid, fl)
            say(f"pack limits: {limits}")
            say(f"at rest: {(await check_fresh_pack(link, proc.sysid, fl, limits=limits)).reason}")
            await arm_when_ready(link, proc.sysid, 1)
            await set_mode(link, proc.sysid, 1, "GUIDED" if kind == "ardupilot" else "LOITER")
            await watch.until("position", lambda: "GLOBAL_POSITION_INT" in watch.last, 30)
            base = 0.0 if kind == "ardupilot" else watch.last["GLOBAL_POSITION_INT"].alt / 1000.0
            r0 = await read_battery(link, proc.sysid)
            await takeoff(link, proc.sysid, 1, base + 20.0)
            t0 = time.monotonic()
            first = None
            for _ in range(int(HOVER_SIM_S / speed / 4)):
                await asyncio.sleep(4.0)
                r = await read_battery(link, proc.sysid)
                first = first or (time.monotonic(), r)
                say(f"  hover, {speed * (time.monotonic() - t0):5.0f} s simulated, {watch.rel_alt_m:5.1f} m: {brief(r)}")
            sim_min = speed * (first[0] - t0) / 60.0
            r1 = first[1]
            if r0.remaining_pct is not None and r1.remaining_pct is not None and sim_min > 0:
                say(f"drain from the take-off to the first reading: {(r0.remaining_pct - r1.remaining_pct) / sim_min:.1f} "
                    f"%/min and {(r0.voltage_v - r1.voltage_v) / sim_min:.3f} V/min simulated")
            await set_mode(link, proc.sysid, 1, "LAND")
            await watch.until("landing", lambda: watch.landed, 200)
            await asyncio.sleep(0.5)
            say(f"landed, disarmed: {(await check_fresh_pack(link, proc.sysid, fl, limits=limits)).reason}")
            await asyncio.sleep(3.0)
            say(f"3 s later: {(await check_fresh_pack(link, proc.sysid, fl, limits=limits)).reason}")
            say(f"arm on this pack: {await try_arm(link, proc.sysid, kind)}")
            try:
                await command_long(link, proc.sysid, 1, MAV_CMD_BATTERY_RESET, (1, 100), retries=1)
                say(f"MAV_CMD_BATTERY_RESET 100 %: accepted; "
                    f"{(await check_fresh_pack(link, proc.sysid, fl, limits=limits)).reason}")
            except CommandError as err:
                say(f"MAV_CMD_BATTERY_RESET: {err}")
            await sitl_swap(link, proc.sysid, fl)
            say(f"after tests/sitl/battery.py's swap: {(await check_fresh_pack(link, proc.sysid, fl, limits=limits)).reason}")
            if kind == "ardupilot":
                r = await read_battery(link, proc.sysid)
                await set_param(link, proc.sysid, 1, "BATT_LOW_VOLT", (r.voltage_v or 12.6) + 0.5)
                await asyncio.sleep(12.0 / speed + 1.0)  # BATT_LOW_TIMER 10 s
                say(f"BATT_LOW_VOLT above the pack for 12 s: {(await check_fresh_pack(link, proc.sysid, fl, limits=limits)).reason}; "
                    f"arm: {await try_arm(link, proc.sysid, kind)}")
                await set_param(link, proc.sysid, 1, "BATT_LOW_VOLT", 10.5)
                await sitl_swap(link, proc.sysid, fl)
                say(f"voltage back, failsafe latched? arm: {await try_arm(link, proc.sysid, kind)}")
            say("texts: " + " | ".join(watch.texts[-12:]))
    finally:
        proc.stop()


def main(argv: list[str]) -> int:
    kinds = argv or ["ardupilot", "px4"]
    for kind in kinds:
        reason = harness.skip_reason(kind)
        if reason:
            say(f"{kind}: {reason}")
            continue
        asyncio.run(measure(kind))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
