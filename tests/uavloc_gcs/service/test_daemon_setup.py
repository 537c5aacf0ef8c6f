"""Connect-time set-up against fake vehicles over UDP: the streams asked for, the ground clock when no
vehicle gives its time, and the speed the fleet is planned at."""

import asyncio

from sim_link.vehicles.fleet import FakeFleet
from tests.e2e_helpers import small_scenario
from uavloc_gcs.service import setup
from uavloc_gcs.service.daemon import Daemon, DaemonOptions
from uavloc_gcs.service.store import Store, StoreReader


async def _connect(tmp_path, sc, *, wp_spd=None, consent=False, result=None):
    async with FakeFleet(sc, speedup=1, seed=3, base_port=0,
                         vehicle_options={"realistic_streams": True}) as fleet:  # no SYSTEM_TIME until asked
        if wp_spd is not None:
            fleet.vehicle(2).params["WP_SPD"] = wp_spd  # one vehicle is limited below the scenario's speed
        conns = [(i + 1, c) for i, (_n, c) in enumerate(fleet.endpoints)]
        d = Daemon(sc, conns, DaemonOptions(store_path=tmp_path / "s.sqlite", connect_timeout_s=3.0,
                                            set_speed_params=consent))
        d.store = Store(tmp_path / "s.sqlite")
        try:
            await d._connect_all()
            if result is not None:
                return result(d, fleet)
            return d._ground_clock, d.epoch_unix_s
        finally:
            await d._close_links()
            d.store.close()


def test_the_daemon_asks_for_the_vehicles_clock(tmp_path):
    ground, epoch = asyncio.run(_connect(tmp_path, small_scenario("px4")))
    assert not ground and epoch is not None


def test_without_the_vehicles_clock_the_search_goes_on_with_the_ground_clock_and_says_so(tmp_path, monkeypatch):
    async def ask_nothing(link, sysid, flavour):
        return []
    monkeypatch.setattr(setup, "request_streams", ask_nothing)  # as a vehicle that cannot give its time
    ground, epoch = asyncio.run(_connect(tmp_path, small_scenario("px4")))
    assert ground and epoch is not None
    with StoreReader(tmp_path / "s.sqlite") as rd:
        warnings = [e.text for e in rd.events("warning")]
    assert any("SYSTEM_TIME" in w and "ground station's clock" in w for w in warnings), warnings


def test_the_fleet_is_planned_at_the_speed_the_slowest_vehicle_really_flies(tmp_path):
    sc = small_scenario("ardupilot")  # 15 m/s
    speed, policy_speed = asyncio.run(_connect(tmp_path, sc, wp_spd=9.0,
                                               result=lambda d, f: (d.sc.fleet.speed_m_s, d.policy.speed_m_s)))
    assert speed == 9.0 and policy_speed == 9.0
    with StoreReader(tmp_path / "s.sqlite") as rd:
        notes = [e.text for e in rd.events("speed")]
    assert any("vehicle 2 flies at most 9 m/s" in n and "set_speed_params" in n for n in notes), notes


def test_with_the_operators_consent_the_speed_parameters_are_raised(tmp_path):
    sc = small_scenario("ardupilot")
    speed, flown = asyncio.run(_connect(tmp_path, sc, wp_spd=9.0, consent=True,
                                        result=lambda d, f: (d.sc.fleet.speed_m_s, f.vehicle(2).params["WP_SPD"])))
    assert speed == 15.0 and flown == 15.0
