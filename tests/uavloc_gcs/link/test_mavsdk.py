"""Against an independent implementation of the mission protocol: MAVSDK (C++ core via ctypes).

* MAVSDK's ``MissionRawServer`` plays the vehicle: what we upload must arrive identical (its
  incoming-mission callback) and read back identical (our download).
* MAVSDK's ``mission_raw`` plays the ground station against the scripted test vehicle: this
  checks the test vehicle itself speaks the protocol as MAVSDK expects, and that our download
  reads exactly what MAVSDK uploaded.
"""

import asyncio

import pytest

from uavloc_gcs.link import download_mission, open_link, upload_mission
from uavloc_gcs.mission import WireItem

from .conftest import identical, run, survey_items
from .scripted_vehicle import ARDUPILOT, PX4, ScriptedVehicle

mavsdk = pytest.importorskip("mavsdk", reason="MAVSDK (the 'test' extra) is the independent peer here")
pytestmark = pytest.mark.mavsdk


def _wire(item) -> WireItem:
    return WireItem(item.seq, item.frame, item.command, item.current, item.autocontinue, item.param1, item.param2,
                    item.param3, item.param4, item.x, item.y, item.z, item.mission_type)


@pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])
def test_upload_to_mavsdk_mission_raw_server_arrives_and_reads_back_identical(autopilot):
    from mavsdk import ComponentType, Configuration, Mavsdk
    from mavsdk.plugins.mission_raw_server import MissionRawServer

    items = survey_items(40, autopilot)

    async def go():
        vehicle = Mavsdk(Configuration.create_with_component_type(ComponentType.AUTOPILOT))
        try:
            async with await open_link("udpin:127.0.0.1:0") as link:
                vehicle.add_any_connection(f"udpout://127.0.0.1:{link.local_address[1]}")
                server = MissionRawServer(vehicle.server_component())
                loop = asyncio.get_running_loop()
                incoming = loop.create_future()

                def on_mission(result, plan, _ud):
                    loop.call_soon_threadsafe(lambda: incoming.done() or incoming.set_result((result, plan)))
                server.subscribe_incoming_mission(on_mission)
                hb = await link.wait_heartbeat(timeout_s=10)
                ts, tc = hb.get_srcSystem(), hb.get_srcComponent()
                # MAVSDK reports MAV_AUTOPILOT_GENERIC: the read-back is compared strictly
                result = await upload_mission(link, ts, tc, items)
                received = await asyncio.wait_for(incoming, 5)
                downloaded = await download_mission(link, ts, tc)
                return result, received, downloaded
        finally:
            vehicle.destroy()

    result, (server_result, plan), downloaded = run(go())
    assert result.verified and result.item_count == len(items)
    assert int(server_result) == 1  # MissionRawServerResult.SUCCESS
    assert identical([_wire(i) for i in plan.mission_items], items)
    assert identical(downloaded, items)


@pytest.mark.parametrize("style", [PX4, ARDUPILOT], ids=lambda s: s.name)
def test_mavsdk_ground_station_uploads_to_the_scripted_vehicle_and_we_read_it_back(style):
    from mavsdk import ComponentType, Configuration, Mavsdk
    from mavsdk.plugins.mission_raw import MissionItem, MissionRaw

    items = survey_items(30, style.name)

    async def go():
        async with ScriptedVehicle(style) as v:
            gcs = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
            try:
                gcs.add_any_connection(f"udpout://127.0.0.1:{v.port}")
                loop = asyncio.get_running_loop()
                system = await loop.run_in_executor(None, gcs.first_autopilot, 10.0)
                assert system is not None
                mission_raw = MissionRaw(system)
                await loop.run_in_executor(None, mission_raw.upload_mission, [MissionItem(
                    w.seq, w.frame, w.command, w.current, w.autocontinue, w.param1, w.param2, w.param3, w.param4,
                    w.x, w.y, w.z, w.mission_type) for w in items])
                stored = list(v.state.mission)
                mavsdk_view = await loop.run_in_executor(None, mission_raw.download_mission)
            finally:
                gcs.destroy()
            async with await open_link(v.connection, source_system=254) as link:
                await link.wait_heartbeat(timeout_s=5)
                ours = await download_mission(link, 1, 1)
            return stored, [_wire(i) for i in mavsdk_view], ours

    stored, mavsdk_view, ours = run(go())
    assert identical(stored, items)
    start = 1 if style is ARDUPILOT else 0  # both readers see the vehicle's home at seq 0
    assert identical(ours, mavsdk_view) and identical(ours[start:], items[start:])
