"""Arming a freshly booted autopilot: it refuses for a while (ArduCopter: "Arm: Accels
inconsistent", EKF not yet using GPS); uavloc retries with backoff and, when it gives up, says the
autopilot's own reason from its latest STATUSTEXT."""

from __future__ import annotations

import asyncio
import time

import pytest

from uavloc_gcs.errors import CommandError
from uavloc_gcs.link import arm, arm_when_ready, open_link

from . import harness
from .flying import Watch


@pytest.mark.parametrize("kind", ["ardupilot", "px4"])
def test_arm_waits_until_ready_after_boot(kind, sitl):
    proc = sitl(kind, wait="heartbeat" if kind == "ardupilot" else "none")

    async def scenario():
        async with await open_link(proc.connection) as link:
            await link.wait_heartbeat(proc.sysid, timeout_s=60)
            watch = Watch(link, proc.sysid)
            refused = None
            try:
                await arm(link, proc.sysid, 1)  # straight after boot: a real autopilot says no
            except CommandError as err:
                refused = err
            if refused is None:
                return None, None, 0.0
            quick = None
            try:
                await arm_when_ready(link, proc.sysid, 1, timeout_s=0.5)
            except CommandError as err:
                quick = err
            started = time.monotonic()
            if quick is not None:
                await arm_when_ready(link, proc.sysid, 1)
            await watch.until("armed heartbeat", lambda: watch.armed, 30)
            return refused, quick, time.monotonic() - started
    refused, quick, waited = harness.run(scenario(), 180)
    if kind == "ardupilot":
        assert refused is not None and quick is not None, "ArduCopter armed right after boot"
    if quick is not None:
        # the final error carries the autopilot's own words, not just MAV_RESULT_FAILED
        assert quick.reason and quick.reason in str(quick)
        assert any(w in quick.reason.lower() for w in ("arm", "prearm", "preflight", "gps", "ekf")), quick.reason
    print(f"{kind}: first arm {'refused: ' + str(refused) if refused else 'accepted'}; "
          f"{'reason ' + repr(quick.reason) + '; ' if quick else ''}armed after {waited:.1f} s of retries")


def test_mission_started_right_after_boot_takes_off(sitl):
    """The daemon started together with a fresh ArduCopter: arming succeeded before the EKF used
    GPS, MISSION_START was then refused ("Mode change to Auto failed: requires position") until
    the vehicle disarmed by itself, and the retried start left it in AUTO, disarmed, on the
    ground for good (measured). The start now waits for the vehicle to know its position."""
    from uavloc_gcs.link import ARDUPILOT, request_streams, start_mission_from, upload_mission
    from uavloc_gcs.mission import flight_mission, to_wire

    proc = sitl("ardupilot", wait="heartbeat")

    async def scenario():
        async with await open_link(proc.connection) as link:
            await link.wait_heartbeat(proc.sysid, timeout_s=60)
            await request_streams(link, proc.sysid, ARDUPILOT)
            watch = Watch(link, proc.sysid)
            await asyncio.sleep(3.0)  # in its first second it answers uploads MAV_MISSION_NO_SPACE
            lat, lon = proc.home[:2]
            plan = flight_mission([(lat + 0.0005, lon)], alt_m=15.0, speed_m_s=5.0, autopilot="ardupilot",
                                  home_latlon_deg=(lat, lon), include_takeoff=True)
            await upload_mission(link, proc.sysid, 1, to_wire(plan, "ardupilot"), verify=True, autopilot="ardupilot")
            await watch.until("a heartbeat", lambda: "HEARTBEAT" in watch.last, 10)
            await start_mission_from(link, proc.sysid, 1, ARDUPILOT, 1, armed=watch.armed, mode=watch.mode)
            await watch.until("the take-off (armed, above 5 m)", lambda: watch.armed and watch.rel_alt_m > 5.0, 90)
            return list(watch.texts)

    texts = harness.run(scenario(), 240)
    print("ArduCopter said:", "; ".join(texts[-12:]))
