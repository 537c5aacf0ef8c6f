"""Issue 38: the daemon flies a scan in sorties against fake vehicles over UDP (real MAVLink): home
at its reserve, the vehicle waits on the ground; the team's swap (a fresh pack, a reboot) makes it
ready again and it flies its next sortie; a pack that is not fresh is never launched, whatever the
operator says."""

from __future__ import annotations

import asyncio
from types import SimpleNamespace

import pytest

from sim_link.vehicles.battery import EMPTY_V, FULL_V
from sim_link.vehicles.fleet import FakeFleet
from tests.e2e_helpers import small_scenario
from uavloc_gcs.errors import UavlocError
from uavloc_gcs.service.daemon import Daemon, DaemonOptions
from uavloc_gcs.service.store import StoreReader, request_pack_fresh

SPEEDUP = 25.0
TIMEOUT_S = 60.0  # wall seconds for any one stage (a sortie is ~90 s of mission time: ~4 s here)


def _scenario(autopilot: str):
    # one vehicle whose 1.4 km scan is two sorties of 15 kJ (half of each 30 kJ pack kept for the
    # climb, the descent and the reserve: the cut counts level flight only)
    return small_scenario(autopilot, speedup=SPEEDUP).replace(fleet={
        "vehicles": 1, "batteries": 2, "energy_budget_j": 30_000.0, "energy_reserve_fraction": 0.5,
        "battery_swap_s": 30.0})


class _SearchGoesOn:
    """A search policy that is never done and plans nothing, so that the search lasts while the
    sorties are watched (with the real one, the first sortie can locate everyone and end it)."""

    time_limit_s = 0.1

    def ingest(self, slots) -> None:
        pass

    def update(self, t):
        return set()

    def people(self, t):
        return []

    def done(self, t) -> bool:
        return False

    def needs_replan(self, t, changed) -> bool:
        return False

    def replan(self, t, states):
        return SimpleNamespace(tasks=(), makespan_s=0.0, planner_runtime_s=0.0)


async def _until(cond, what: str, timeout_s: float = TIMEOUT_S) -> None:
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout_s
    while not cond():
        if loop.time() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        await asyncio.sleep(0.02)


def _events(path) -> list[str]:
    with StoreReader(path) as rd:
        return [f"{e.kind}: {e.text}" for e in rd.events()]


async def _stop(task: asyncio.Task) -> None:
    assert not task.done(), f"the search ended: {task.result().statement}"
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task


async def _fly_first_sortie(sc, tmp_path):
    """The fleet, the daemon running, and vehicle 1 home from its first sortie, waiting."""
    fleet = await FakeFleet(sc, speedup=SPEEDUP, seed=1, base_port=0).start()
    (_name, conn), = fleet.endpoints
    d = Daemon(sc, [(1, conn)], DaemonOptions(store_path=tmp_path / "s.sqlite", resume=False, connect_timeout_s=10.0,
                                              lost_timeout_s=5.0), policy=_SearchGoesOn())
    task = asyncio.ensure_future(d.run())
    v, fake = d.vehicles[1], fleet.vehicle(1)
    await _until(lambda: task.done() or fake.armed and not fake.landed, "the first take-off")
    await _until(lambda: task.done() or v.phase == "waiting for pack", "vehicle 1 waiting for a pack")
    assert not task.done(), task.exception()
    assert v.sorties and v.packs_left == 1 and v.packs_flown == 1
    assert fake.landed and not fake.armed
    assert "waiting for a fresh pack" in d.snapshot().vehicles[0].phase
    return fleet, d, task


def test_a_vehicle_home_from_its_first_sortie_flies_its_second_after_the_teams_swap(tmp_path):
    sc = _scenario("px4")

    async def go():
        fleet, d, task = await _fly_first_sortie(sc, tmp_path)
        try:
            v, fake = d.vehicles[1], fleet.vehicle(1)
            left = fake.battery.charge
            assert left < 0.6, f"the first sortie flew its pack down ({left:.0%} left)"
            await asyncio.sleep(1.0)  # a second of waiting (25 s of mission time): not launched on it
            assert not fake.armed and v.phase == "waiting for pack"
            fleet.swap_pack(1)
            await _until(lambda: task.done() or v.sortie == 2 and fake.armed and not fake.landed, "the second sortie")
            assert not task.done(), task.exception()
            # (the vehicle is seen scanning while its start exchange may still be retried after a
            # "Mission start denied": wait for that exchange too, whose end is the start's event)
            await _until(lambda: task.done() or v.phase == "scanning" and v.packs_flown == 2 and v.job is None,
                         "vehicle 1 scanning its second sortie, on its second pack")
            assert v.packs_left == 0 and not v.sorties
            assert fake.battery.charge > 0.9  # it flies the fresh pack
            assert d._packs_text() == "Sorties flown (packs left): vehicle 1 2 (0 left)."
        finally:
            await _stop(task)
            await fleet.aclose()
        return d

    d = asyncio.run(asyncio.wait_for(go(), 4 * TIMEOUT_S))
    events = _events(tmp_path / "s.sqlite")
    waits = [e for e in events if "waits for a fresh pack (1 left)" in e]
    assert waits and "sortie 2 of its scan" in waits[0], events
    assert any("is ready again: vehicle 1 reports" in e and "a fresh pack" in e for e in events), events
    assert any("started sortie 2 of its scan" in e for e in events), events
    with StoreReader(tmp_path / "s.sqlite") as rd:
        scans = [e for e in rd.events("upload") if "scan mission" in e.text]
    assert len(scans) == 2, "each sortie is its own scan mission"
    assert d.vehicles[1].odd_moves == []
    with StoreReader(tmp_path / "s.sqlite") as rd:
        ts = [e.t_s for e in rd.events()]
    # the swap reboots the autopilot: the mission clock must not go back with its boot clock
    # (it went from 192 s back to 26 s)
    assert all(b >= a - 2.0 for a, b in zip(ts, ts[1:])), ts


def test_a_pack_that_is_not_fresh_is_never_launched_whatever_the_operator_says(tmp_path):
    """ArduPilot: after the swap's reboot it counts 100 % of any pack; a used pack shows only in
    its voltage. Neither the operator's word nor that 100 % launches it."""
    sc = _scenario("ardupilot")

    async def go():
        fleet, d, task = await _fly_first_sortie(sc, tmp_path)
        try:
            v, fake = d.vehicles[1], fleet.vehicle(1)
            armed_seen = []

            async def watch():
                while True:
                    if fake.armed:
                        armed_seen.append(fake.t_s)
                    await asyncio.sleep(0.005)

            watcher = asyncio.ensure_future(watch())
            # the operator says so, but it reports the used pack's remaining
            assert "checked before it is launched" in d.pack_fresh(1)
            await _until(lambda: not v.operator_fresh, "the operator's word judged")
            # the team puts in a used pack (half charged): the reboot makes ArduPilot say 100 %
            loop = asyncio.get_running_loop()
            fleet.swap_pack(1)
            loop.call_soon(fake.battery.set_resting_voltage, EMPTY_V + 0.5 * (FULL_V - EMPTY_V))
            await asyncio.sleep(0.5)
            await _until(lambda: fake.battery.remaining > 0.99 and d.vehicles[1].agent.tel.battery_pct == 100.0,
                         "the reboot's 100 %")
            request_pack_fresh(tmp_path / "s.sqlite", 1)  # `uavloc pack-fresh 1`, from another process
            await asyncio.sleep(3.0)  # 75 s of mission time: polled every 2 s
            watcher.cancel()
            assert armed_seen == [], "a vehicle on a pack that is not fresh was armed"
            assert v.phase == "waiting for pack" and v.packs_left == 1 and v.sortie == 1
            with pytest.raises(UavlocError, match="no vehicle 7"):
                d.pack_fresh(7)
        finally:
            await _stop(task)
            await fleet.aclose()

    asyncio.run(asyncio.wait_for(go(), 4 * TIMEOUT_S))
    events = _events(tmp_path / "s.sqlite")
    refused = [e for e in events if "the operator said its pack is fresh, but" in e and "it is not launched" in e]
    assert len(refused) == 2, events
    assert "% remaining" in refused[0] and "not a fresh pack" in refused[0]
    assert "100 % remaining" in refused[1] and "below the" in refused[1], refused[1]  # the voltage tells
    assert not any("started sortie 2" in e for e in events)


def test_the_operators_word_counts_only_where_the_vehicle_reports_nothing_against_it():
    from uavloc_gcs.link.battery import BatteryReading, PackLimits, judge_pack
    from uavloc_gcs.service.swaps import _reported_not_fresh

    limits = PackLimits(FULL_V, EMPTY_V, "test")

    def against(remaining, volts, lim=limits):
        return _reported_not_fresh(judge_pack(BatteryReading(volts, remaining, source="test"), lim))

    assert not _reported_not_fresh(None)  # no battery message at all
    assert not against(None, FULL_V)  # no remaining charge
    assert not against(100.0, None)  # a remaining charge, no voltage to check it against
    assert not against(100.0, FULL_V)  # fresh
    assert against(19.0, None) and against(19.0, FULL_V)  # a used pack by its remaining
    assert against(100.0, EMPTY_V + 0.5 * (FULL_V - EMPTY_V))  # ArduPilot's 100 % after a reboot: the voltage


def test_the_search_ends_at_its_time_limit_with_everyone_home(tmp_path):
    """[search] time_limit_s: when the search's time is up no look is planned, every vehicle is
    sent home mid-scan, and the statement says the limit ended it (the policy here is never done:
    without the limit this search would not end)."""
    sc = small_scenario("ardupilot", speedup=SPEEDUP)
    sc = sc.replace(search={"time_limit_s": 60.0})

    async def go():
        fleet = await FakeFleet(sc, speedup=SPEEDUP, seed=1, base_port=0).start()
        try:
            d = Daemon(sc, [(1, c) for _n, c in fleet.endpoints][:1],
                       DaemonOptions(store_path=tmp_path / "s.sqlite", resume=False, connect_timeout_s=10.0,
                                     lost_timeout_s=5.0), policy=_SearchGoesOn())
            out = await asyncio.wait_for(d.run(), 4 * TIMEOUT_S)
            return d, out, fleet.vehicle(1)
        finally:
            await fleet.aclose()

    d, out, fake = asyncio.run(go())
    assert "time limit (1 min, search.time_limit_s) was reached at" in out.statement, out.statement
    assert 1.0 <= d._time_up_s / 60.0 < 1.5
    assert out.vehicles_home == (1,) and fake.landed and not fake.armed
    events = _events(tmp_path / "s.sqlite")
    assert any("time limit (1 min, search.time_limit_s) is reached: no more looks" in e for e in events), events


def test_a_daemon_restarted_during_a_swap_resumes_the_sorties(tmp_path):
    """Issue 38 item 2: the daemon dies while vehicle 1 waits on the ground for its swap; a new
    daemon on the same store takes the search up where it was (sortie 1 flown, one pack left, the
    vehicle waiting) and flies sortie 2 once the team's fresh pack is in. Before, it refused to
    resume a search flown in sorties."""
    sc = _scenario("ardupilot")

    async def go():
        fleet, d, task = await _fly_first_sortie(sc, tmp_path)
        try:
            await _stop(task)  # the daemon dies (its links close), the vehicle stays on the ground
            (_name, conn), = fleet.endpoints
            again = Daemon(sc, [(1, conn)], DaemonOptions(store_path=tmp_path / "s.sqlite", resume=True,
                                                          connect_timeout_s=10.0, lost_timeout_s=5.0),
                           policy=_SearchGoesOn())
            task2 = asyncio.ensure_future(again.run())
            v, fake = again.vehicles[1], fleet.vehicle(1)
            await _until(lambda: task2.done() or v.phase == "waiting for pack", "vehicle 1 waiting again after the restart")
            assert not task2.done(), task2.exception()
            assert (v.sortie, v.packs_left, v.packs_flown, len(v.sorties)) == (1, 1, 1, 1)
            await asyncio.sleep(1.0)
            assert not fake.armed  # not launched on the pack it flew sortie 1 on
            fleet.swap_pack(1)
            await _until(lambda: task2.done() or v.sortie == 2 and fake.armed and not fake.landed,
                         "the second sortie, flown by the restarted daemon")
            assert not task2.done(), task2.exception()
            await _until(lambda: task2.done() or v.packs_flown == 2 and v.job is None, "sortie 2 under way")
            assert v.packs_left == 0 and not v.sorties
            await _stop(task2)
        finally:
            if not task.done():
                task.cancel()
            await fleet.aclose()

    asyncio.run(asyncio.wait_for(go(), 5 * TIMEOUT_S))
    events = _events(tmp_path / "s.sqlite")
    assert any("sorties resumed: vehicle 1 on sortie 1 (1 pack(s) left)" in e for e in events), events
    assert any("after sortie 1 of its scan: it waits for a fresh pack" in e for e in events), events
    assert any("started sortie 2 of its scan" in e for e in events), events


@pytest.mark.parametrize("packs_flown, pack_counted, sortie, left, want", [
    (1, True, 1, 1, "wait"),  # sortie 1 flown on the pack it has: the swap is due
    (1, False, 1, 1, "start"),  # its pack swapped and judged fresh, sortie 2 not uploaded yet: sortie 2
    (1, False, 2, 0, "start"),  # sortie 2 uploaded on the fresh pack, not flown: started
    (2, True, 2, 0, None),  # its last sortie flown: resumed as a scan is
])
def test_a_restart_finds_a_landed_vehicle_where_its_sorties_say(packs_flown, pack_counted, sortie, left, want):
    """Which sortie a vehicle found on the ground after a restart flies (a sortie flies on a pack
    of its own: flown when as many packs were flown as its number)."""
    from uavloc_gcs.service.swaps import PackSwaps

    said, uploads = [], []

    class Fake(PackSwaps):
        def _adopt(self, v, purpose, items):
            v.purpose = purpose

        def _event(self, kind, text, vehicle=None):
            said.append(text)

        async def _upload(self, v, purpose, items, first_seq=None):
            uploads.append(items)

    v = SimpleNamespace(id=1, packs_flown=packs_flown, pack_counted=pack_counted, sortie=sortie,
                        sorties=[["sortie 2"]] * left, phase="landed", home=True, pack_flown=False)
    got = asyncio.run(Fake()._resume_landed_sortie(v, ["on board"]))
    assert got == want, said
    if want == "wait":
        assert v.pack_flown and v.home and v.sortie == 1 and not uploads
    elif want == "start" and sortie == 1:
        assert v.sortie == 2 and uploads == [["sortie 2"]] and not v.sorties
    elif want == "start":
        assert v.sortie == 2 and not uploads  # the sortie on board is the one to fly
