"""Per autopilot, against the real SITL (issue 38, item 3): a scan planned in two sorties (one pack
each, uavloc_gcs/sorties.py) is flown as its two missions with a pack swap between them, and the
link's check_fresh_pack judges the pack as the daemon will before each relaunch: fresh at boot,
not fresh in the air or after a sortie that used it (ArduCopter, whose pack sags; PX4 SIH refills
it at the disarm), fresh again after the swap; ArduCopter's MAV_CMD_BATTERY_RESET alone, which
sets only the remaining, does not fool it. One SITL start per autopilot for all of it."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

from uavloc_gcs.errors import CommandError
from uavloc_gcs.link import check_fresh_pack, command_long, flavour_for, open_link, pack_limits, read_battery
from uavloc_gcs.mission import NAV_WAYPOINT, to_wire
from uavloc_gcs.scan import plan_scan
from uavloc_gcs.scenario import loads_scenario
from uavloc_gcs.sorties import scan_sorties, sortie_missions

from . import harness
from .battery import AP_PACK_PARAMS, MAV_CMD_BATTERY_RESET, sitl_swap
from .flying import fly_to_its_return

ALT_M = 30.0

# 120 x 200 m next to home, lanes 50 m apart, one vehicle whose (planned) pack flies about 700 m at
# 10 m/s: the scan needs two sorties.
SCENARIO = """\
name = "sitl-sorties"
[area]
origin_lat_deg = {lat}
origin_lon_deg = {lon}
width_m = 120.0
height_m = 200.0
[fleet]
vehicles = 1
autopilot = "{autopilot}"
altitude_m = {alt}
speed_m_s = 10.0
energy_budget_j = 10000.0
batteries = 2
battery_swap_s = 60.0
[scan]
lane_spacing_m = 50.0
"""


@pytest.mark.parametrize("kind", ["ardupilot", "px4"])
def test_two_sorties_with_a_swap_and_the_pack_judged_before_each(sitl, kind):
    proc = sitl(kind, **({"params": AP_PACK_PARAMS} if kind == "ardupilot" else {}))
    lat, lon = harness.HOME[:2]
    sc = loads_scenario(SCENARIO.format(lat=lat, lon=lon, autopilot=kind, alt=ALT_M))
    plan = plan_scan(sc)
    sorties = scan_sorties(sc, plan)
    assert [sp.packs for sp in sorties] == [2]
    wires = [to_wire(m, kind) for m in sortie_missions(sc, plan, sorties)[0]]
    out = harness.run(_fly(proc, wires), timeout_s=900)
    for k, (rows, wire) in enumerate(zip(out["tracks"], wires), 1):
        # each sortie flew its own waypoints: the track comes within 10 m of every one of them
        wps = [it for it in wire if it.command == NAV_WAYPOINT and (it.seq > 0 or kind == "px4")]
        wp_xy = sc.frame.to_local_xy(np.array([[it.x / 1e7, it.y / 1e7] for it in wps]))
        xy = sc.frame.to_local_xy(np.array([[r[0], r[1]] for r in rows]))
        closest = [float(np.hypot(*(xy - p).T).min()) for p in wp_xy]
        assert max(closest) < 10.0, f"{kind} sortie {k}: closest approach to its waypoints {closest}"
    # sortie 2 begins where sortie 1 left the path
    np.testing.assert_allclose(sorties[0].sorties[1].waypoints_xy_m[0], sorties[0].sorties[0].waypoints_xy_m[-1])
    v = out["verdicts"]
    print(kind, "\n  ".join(f"{what}: {verdict.reason}" for what, verdict in v.items()))
    assert out["limits"] is not None
    assert v["at boot"].fresh and v["after the swap"].fresh and v["before sortie 2"].fresh
    assert not v["in the air"].fresh
    if kind == "ardupilot":
        assert not v["after sortie 1"].fresh and v["after sortie 1"].reading.remaining_pct < 95
        # the reset sets the remaining only; the voltage of the used pack still tells
        assert out["reset"] == "accepted" and v["reset only"].reading.remaining_pct == 100
        assert not v["reset only"].fresh and "below" in v["reset only"].reason
    else:
        assert v["after sortie 1"].fresh  # PX4 SIH: a full pack at every disarm (measured)
        assert out["reset"].startswith("refused") and "UNSUPPORTED" in out["reset"]


async def _fly(proc, wires) -> dict:
    out = {"tracks": [], "verdicts": {}}
    async with await open_link(proc.connection) as link:
        hb = await link.wait_heartbeat(proc.sysid, timeout_s=30)
        system, flavour = hb.get_srcSystem(), flavour_for(hb.autopilot)
        limits = out["limits"] = await pack_limits(link, system, flavour)

        async def judge(what: str) -> None:
            out["verdicts"][what] = await check_fresh_pack(link, system, flavour, limits=limits)

        await judge("at boot")
        for k, wire in enumerate(wires, 1):
            rows: list[tuple] = []
            if k == 2:
                await judge("before sortie 2")

            async def probe():  # the pack in the air, some 40 s of simulated flight after the start
                while len(rows) < 20 or rows[-1][2] < 0.8 * ALT_M:
                    await asyncio.sleep(0.5)
                await asyncio.sleep(40.0 / harness.PX4_SPEEDUP)
                await judge("in the air")

            flight = fly_to_its_return(link, system, flavour, wire,
                                       lambda m, w: rows.append((m.lat / 1e7, m.lon / 1e7, m.relative_alt / 1000.0)),
                                       what=f"sortie {k}'s end", timeout_s=400)
            if k == 1:
                await asyncio.gather(flight, probe())
            else:
                await flight
            out["tracks"].append(rows)
            if k == 1:
                await asyncio.sleep(1.0)
                await judge("after sortie 1")
                try:
                    await command_long(link, system, 1, MAV_CMD_BATTERY_RESET, (1, 100), retries=1)
                    out["reset"] = "accepted"
                except CommandError as err:
                    out["reset"] = f"refused: {err}"
                await judge("reset only")
                await sitl_swap(link, system, flavour)
                await judge("after the swap")
        out["last"] = await read_battery(link, system)
    return out
