"""The link layer against the simulator's fake vehicles (sim_link.FakeFleet), several at once,
on a link losing 20 % of the datagrams each way (plus duplication and reordering)."""

import asyncio
from pathlib import Path

import pytest

from sim_link.vehicles.faults import FaultConfig
from sim_link.vehicles.fleet import FakeFleet
from uavloc_gcs.link import VehicleTracker, open_link, set_mode, upload_mission
from uavloc_gcs.scenario import load_scenario

from .conftest import identical, run, survey_items

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"


@pytest.mark.slow
@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_every_vehicle_gets_its_mission_through_20_percent_loss(autopilot):
    sc = load_scenario(EXAMPLES / "small.toml").replace(fleet={"autopilot": autopilot, "vehicles": 2})
    faults = FaultConfig(loss=0.2, duplicate=0.05, reorder=0.05)
    missions = {i: survey_items(4, autopilot, seed=i) for i in (1, 2)}

    async def one(fleet, i, conn):
        async with await open_link(conn) as link:
            tracker = VehicleTracker(link)
            await link.wait_heartbeat(i, timeout_s=10)
            result = await upload_mission(link, i, 1, missions[i])
            await set_mode(link, i, 1, "AUTO")  # mode names from the HEARTBEAT's autopilot type
            while tracker[i].mode not in ("AUTO", "AUTO.MISSION"):  # until a heartbeat shows it
                await link.recv_match(types="HEARTBEAT", source_system=i, timeout_s=5)
            return result, tracker[i].mode, fleet.vehicle(i).mission_items

    async def go():
        async with FakeFleet(sc, speedup=1, seed=3, base_port=0, faults=faults) as fleet:
            async with asyncio.TaskGroup() as tg:  # one bad vehicle must not hide the others
                tasks = [tg.create_task(one(fleet, i, conn)) for i, (_, conn) in enumerate(fleet.endpoints, 1)]
            return [t.result() for t in tasks]

    results = run(go(), timeout_s=90)
    for i, (result, mode, stored) in enumerate(results, 1):
        assert result.verified
        assert mode in ("AUTO", "AUTO.MISSION")
        start = 1 if autopilot == "ardupilot" else 0
        assert identical(stored[start:], missions[i][start:])


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_an_arm_given_up_on_says_the_autopilots_whole_reason(autopilot):
    """Like the real ones (measured on SITL), the fakes refuse to arm after boot and say why in a
    STATUSTEXT; PX4's comes about 0.6 s after the refusing ACK and in two chunks. The error names
    the whole sentence, not a missing or cut reason."""
    from sim_link.vehicles.flavour import FLAVOURS
    from uavloc_gcs.errors import CommandError
    from uavloc_gcs.link import arm_when_ready

    sc = load_scenario(EXAMPLES / "small.toml").replace(fleet={"autopilot": autopilot, "vehicles": 1})
    expected = FLAVOURS[autopilot].arm_refusal[1]

    async def go():
        async with FakeFleet(sc, speedup=1, seed=1, base_port=0,
                             vehicle_options={"arm_refused_after_boot_s": 600.0}) as fleet:
            async with await open_link(fleet.endpoints[0][1]) as link:
                await link.wait_heartbeat(1, timeout_s=10)
                with pytest.raises(CommandError) as caught:
                    await arm_when_ready(link, 1, 1, timeout_s=0.3)
                return caught.value

    err = run(go(), timeout_s=30)
    assert err.reason == expected
    assert expected in str(err)
