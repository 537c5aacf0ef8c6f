"""Issue 40: a mission longer than the autopilot holds is refused before it is sent, and the
figures in uavloc_gcs/link/mission_capacity.py are the real autopilots' (ArduCopter SITL: 650
items, a 16 KB board; PX4 SITL: 10,000, its CONFIG_NUM_MISSION_ITMES_SUPPORTED)."""

from __future__ import annotations

import asyncio
import subprocess
import sys
import time

import pytest

from mission_io import plan as plan_file
from uavloc_gcs.link import open_link
from uavloc_gcs.mission import flight_mission, to_wire

from . import harness

SITL_CAPACITY = {"ardupilot": 650, "px4": 10_000}  # what the shared SITL builds hold (measured)


def _plan(tmp_path, kind: str, wire_items: int):
    """A .plan of ``wire_items`` items on the wire for ``kind`` (ArduPilot's home at seq 0 counted)."""
    lat, lon = harness.HOME[:2]
    n = wire_items - len(to_wire(flight_mission([(lat, lon)], alt_m=25.0, speed_m_s=8.0, autopilot=kind,
                                                home_latlon_deg=(lat, lon)), kind)) + 1
    pts = [(lat + 1e-5 * (k % 50), lon + 1e-5 * (k // 50)) for k in range(n)]
    plan = flight_mission(pts, alt_m=25.0, speed_m_s=8.0, autopilot=kind, home_latlon_deg=(lat, lon))
    assert len(to_wire(plan, kind)) == wire_items
    path = tmp_path / f"{kind}-{wire_items}.plan"
    plan_file.write(path, plan)
    return path


async def _answer_to_count(connection: str, sysid: int, count: int) -> str:
    """What the vehicle answers MISSION_COUNT ``count`` with: a request for item 0, or the ACK's result."""
    async with await open_link(connection) as link:
        await link.wait_heartbeat(sysid, timeout_s=60)
        with link.subscribe(("MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK"), source_system=sysid) as sub:
            await link.send(link.mav.mission_count_encode(sysid, 1, count, 0))
            msg = await sub.get(10.0)
        if msg.get_type() != "MISSION_ACK":
            return f"request {msg.seq}"  # the transfer it began times out on its own
        from uavloc_gcs.link.mission_wire import result_name

        return result_name(msg.type)


@pytest.mark.parametrize("kind", ["ardupilot", "px4"])
def test_the_sitl_holds_what_mission_capacity_says(sitl, kind):
    proc = sitl(kind, wait="heartbeat" if kind == "ardupilot" else "ready")
    if kind == "ardupilot":
        time.sleep(3.0)  # in its first second ArduCopter answers every upload NO_SPACE
    cap = SITL_CAPACITY[kind]
    # the refusal first: PX4 keeps re-requesting item 0 of an accepted transfer for a while
    assert asyncio.run(_answer_to_count(proc.connection, proc.sysid, cap + 1)) == "MAV_MISSION_NO_SPACE"
    assert asyncio.run(_answer_to_count(proc.connection, proc.sysid, cap)) == "request 0"


def _upload(path, connection):
    return subprocess.run([sys.executable, "-m", "uavloc_gcs", "upload", str(path), "--to", connection,
                           "--no-verify"], capture_output=True, text=True, timeout=300)


def test_arducopter_with_no_room_is_bad_input_in_its_own_words(sitl, tmp_path):
    proc = sitl("ardupilot", wait="heartbeat")
    time.sleep(3.0)
    r = _upload(_plan(tmp_path, "ardupilot", 651), proc.connection)
    assert r.returncode == 2, r.stderr
    line, = [ln for ln in r.stderr.splitlines() if ln.startswith("uavloc ")]
    assert "has no room for 651 mission items (it says \"Only 650 items are supported\")" in line, line
    assert "Traceback" not in r.stderr


def test_px4_beyond_any_build_is_refused_before_mission_count(sitl, tmp_path):
    proc = sitl("px4")
    r = _upload(_plan(tmp_path, "px4", 10_001), proc.connection)
    assert r.returncode == 2, r.stderr
    line, = [ln for ln in r.stderr.splitlines() if ln.startswith("uavloc ")]
    assert "10,001 mission items (on the wire) are more than any PX4 vehicle holds (10,000" in line, line
    assert not [ln for ln in r.stderr.splitlines() if ln.startswith("upload:")]  # no MISSION_COUNT went out
    # (the progress lines start with it)
