"""Issue 26: a daemon restarted after its vehicle landed by itself mid-scan.

The sequence reported: the daemon stops mid-scan, the vehicle comes home by itself (a failsafe,
here an RTL from another ground station) and lands; a daemon restarted on the same store re-flew
the WHOLE scan, logged "still flies its scan mission (item 0)" for a disarmed vehicle and
"unexpected move scanning -> starting", and reported "0/0/0" uploads. Now: only the unflown part
is flown (from the leg it was on), the resume says the vehicle is on the ground, the state machine
makes no odd move, and the upload counts go on from the store.
"""

import asyncio
import time

import pytest

from tests.e2e_helpers import small_scenario
from uavloc_gcs.cli._fleet import start_fleet_process
from uavloc_gcs.mission import NAV_WAYPOINT
from uavloc_gcs.service.daemon import Daemon, DaemonOptions
from uavloc_gcs.service.store import StoreReader, wire_items_from_json

pytestmark = pytest.mark.slow  # a whole search or demo: `pytest -m 'not slow and not sitl'` leaves it out


def _waypoints(items) -> int:
    return sum(1 for it in items if it.command == NAV_WAYPOINT and it.seq > 0)


async def _rtl_and_wait_landed(conn: str, vehicle: int, timeout_s: float) -> None:
    """Another ground station sends the vehicle home; wait until it reports disarmed."""
    from uavloc_gcs.dialect import mavlink
    from uavloc_gcs.link import return_home
    from uavloc_gcs.link.connection import open_link

    link = await open_link(conn, source_system=251)
    try:
        await link.wait_heartbeat(vehicle, timeout_s=30.0)
        await return_home(link, vehicle, 1)
        armed = [True]

        def beat(m):
            if m.autopilot != mavlink.MAV_AUTOPILOT_INVALID:
                armed[0] = bool(m.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)

        with link.subscribe("HEARTBEAT", source_system=vehicle, callback=beat):
            deadline = time.monotonic() + timeout_s
            while armed[0] and time.monotonic() < deadline:
                await asyncio.sleep(0.1)
        assert not armed[0], "the vehicle landed and disarmed after its RTL"
    finally:
        await link.close()


def test_restart_after_the_vehicle_landed_by_itself_flies_only_the_unflown_scan(tmp_path, monkeypatch):
    import uavloc_gcs.cli._fleet as fleet_mod

    monkeypatch.setattr(fleet_mod, "START_TIMEOUT_S", 120.0)  # a spawned child on a loaded machine
    sc = small_scenario("ardupilot").replace(fleet={"vehicles": 1})
    fleet = start_fleet_process(sc, speedup=sc.simulation.speedup, seed=sc.simulation.seed, base_port=0)
    store = tmp_path / "search.sqlite"
    conns = [(1, fleet.endpoints[0][1])]
    try:
        async def first_run() -> tuple[int, int]:
            d = Daemon(sc, conns, DaemonOptions(store_path=store, resume=False, on_stop="continue"))
            task = asyncio.ensure_future(d.run())
            deadline = time.monotonic() + 90
            while time.monotonic() < deadline:
                await asyncio.sleep(0.05)
                v = d.vehicles[1]
                seq = v.agent.tel.mission_seq if v.agent else None
                if v.phase == "scanning" and v.mission and seq is not None and v.flew \
                        and seq >= v.hold_seq * 0.5:
                    break
            else:
                raise AssertionError("the first daemon's vehicle never got half way through its scan")
            task.cancel()  # the daemon stops; on_stop = "continue": nothing is sent
            try:
                await task
            except asyncio.CancelledError:
                pass
            return seq, _waypoints(d.vehicles[1].mission)

        seq_at_stop, scan_waypoints = asyncio.run(first_run())
        asyncio.run(_rtl_and_wait_landed(conns[0][1], 1, timeout_s=60.0))

        async def second_run():
            d = Daemon(sc, conns, DaemonOptions(store_path=store, resume=True))
            outcome = await asyncio.wait_for(d.run(), 240)
            return d, outcome

        d2, outcome = asyncio.run(second_run())
    finally:
        fleet.stop()

    with StoreReader(store) as rd:
        resumed = [e.text for e in rd.events("resume")]
        scan_items = [wire_items_from_json(j) for (j,) in rd._conn.execute(
            "SELECT items_json FROM missions WHERE vehicle = 1 AND purpose = 'scan' ORDER BY rowid")]
        scans = [e.text for e in rd.events("upload") if "scan mission" in e.text]
    assert not any("still flies" in t for t in resumed), resumed
    assert any("on the ground" in t and "resum" in t for t in resumed), resumed
    assert d2.vehicles[1].odd_moves == [], d2.vehicles[1].odd_moves
    assert len(scans) == 2, scans  # the scan, then its unflown rest
    assert len(scan_items) == 2 and _waypoints(scan_items[0]) == scan_waypoints
    # the rest: from the leg it was on when it stopped (at most one leg before), not the whole scan
    assert _waypoints(scan_items[1]) <= min(scan_waypoints - 1, scan_waypoints - (seq_at_stop - 4)), \
        (seq_at_stop, scan_waypoints, resumed, [(it.seq, it.command) for it in scan_items[0]])
    # upload counts go on from the store: the first run's scan and the resumed rest at least
    (vid, _plans, uploads, _skipped), = outcome.uploads
    assert vid == 1 and uploads >= 2, outcome
