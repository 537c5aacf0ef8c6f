"""Mission upload / download / clear against the scripted ArduPilot- and PX4-style vehicles,
on a clean link and with loss, duplication and reordering."""

import pytest

from uavloc_gcs.dialect import mavlink as M
from uavloc_gcs.errors import MissionTransferError
from uavloc_gcs.link import clear_mission, download_mission, open_link, upload_mission

from .conftest import identical, run, survey_items
from .scripted_vehicle import ARDUPILOT, PX4, Faults, ScriptedVehicle


async def _upload_and_read_back(style, items, faults=None, **vehicle_kw):
    async with ScriptedVehicle(style, faults=faults, **vehicle_kw) as v:
        async with await open_link(v.connection) as link:
            await link.wait_heartbeat(timeout_s=5)
            result = await upload_mission(link, 1, 1, items)
            got = await download_mission(link, 1, 1)
            return result, got, v


@pytest.mark.parametrize("style", [ARDUPILOT, PX4], ids=lambda s: s.name)
def test_clean_upload_is_stored_exactly_and_verified(style):
    items = survey_items(30, style.name)
    result, got, v = run(_upload_and_read_back(style, items))
    assert result.verified and result.item_count == len(items) and result.resends == 0
    # the vehicle holds exactly what was sent, field by field (seq 0 of ArduPilot is its home)
    assert identical(v.state.mission, items)
    start = 1 if style is ARDUPILOT else 0
    assert identical(got[start:], items[start:])
    # the vehicle asked in its own style and we always answered with MISSION_ITEM_INT
    assert {m.get_type() for m in v.received} >= {"MISSION_COUNT", "MISSION_ITEM_INT"}
    assert "MISSION_ITEM" not in {m.get_type() for m in v.received}


@pytest.mark.slow
@pytest.mark.parametrize("style", [ARDUPILOT, PX4], ids=lambda s: s.name)
def test_upload_survives_loss_duplication_and_reordering(style):
    items = survey_items(6, style.name)
    faults = Faults(loss=0.2, duplicate=0.1, reorder=0.1, seed=7)
    result, got, v = run(_upload_and_read_back(style, items, faults), timeout_s=80)
    assert result.verified
    assert identical(v.state.mission, items)
    assert result.resends > 0  # the faults really happened
    if style is ARDUPILOT:
        assert result.nacks_ignored > 0  # INVALID_SEQUENCE NACKs were tolerated


def test_rejected_item_names_vehicle_item_and_result():
    items = survey_items(10, "px4")
    with pytest.raises(MissionTransferError) as info:
        run(_upload_and_read_back(PX4, items, reject_item=(4, M.MAV_MISSION_UNSUPPORTED_FRAME)))
    err = info.value
    assert err.seq == 4 and err.result == M.MAV_MISSION_UNSUPPORTED_FRAME
    assert err.result_name == "MAV_MISSION_UNSUPPORTED_FRAME"
    assert "vehicle 1" in str(err) and "item 4" in str(err) and "MAV_MISSION_UNSUPPORTED_FRAME" in str(err)


def test_silent_vehicle_gives_up_with_typed_error(monkeypatch):
    from uavloc_gcs.link import mission_upload
    monkeypatch.setattr(mission_upload, "GIVE_UP_S", 0.6)

    async def go():
        async with ScriptedVehicle(PX4) as v:
            async with await open_link(v.connection) as link:
                await link.wait_heartbeat(timeout_s=5)
                v.silent = True
                await upload_mission(link, 1, 1, survey_items(5, "px4"))

    with pytest.raises(MissionTransferError) as info:
        run(go())
    assert info.value.operation == "mission upload" and info.value.seq == 0


def test_verification_catches_a_vehicle_that_stores_something_else():
    items = survey_items(8, "px4")

    async def go():
        async with ScriptedVehicle(PX4) as v:
            async with await open_link(v.connection) as link:
                await link.wait_heartbeat(timeout_s=5)
                orig = v._on_mission_item_int

                def corrupt(msg):  # a vehicle that stores item 5 about 1 m further north
                    if msg.seq == 5:
                        msg.x += 90
                    orig(msg)
                v._on_mission_item_int = corrupt
                await upload_mission(link, 1, 1, items)

    with pytest.raises(MissionTransferError) as info:
        run(go())
    assert info.value.seq == 5 and info.value.operation == "mission verify"


@pytest.mark.parametrize("style", [ARDUPILOT, PX4], ids=lambda s: s.name)
def test_clear_then_download_is_empty(style):
    async def go():
        async with ScriptedVehicle(style) as v:
            async with await open_link(v.connection) as link:
                await link.wait_heartbeat(timeout_s=5)
                await upload_mission(link, 1, 1, survey_items(5, style.name))
                assert len(await download_mission(link, 1, 1)) > 0
                await clear_mission(link, 1, 1)
                return await download_mission(link, 1, 1)

    assert run(go()) == []


def test_empty_upload_is_a_clear():
    async def go():
        async with ScriptedVehicle(PX4) as v:
            v.state.mission = survey_items(3, "px4")
            async with await open_link(v.connection) as link:
                await link.wait_heartbeat(timeout_s=5)
                r = await upload_mission(link, 1, 1, [])
                return r, v.state.mission

    r, stored = run(go())
    assert r.item_count == 0 and r.verified and stored == []


def test_misnumbered_items_are_refused_before_sending():
    items = survey_items(3, "px4")
    bad = [items[0], items[2], items[1]]

    async def go():
        async with ScriptedVehicle(PX4) as v:
            async with await open_link(v.connection) as link:
                await upload_mission(link, 1, 1, bad)

    with pytest.raises(MissionTransferError, match="numbered"):
        run(go())


def test_download_restarts_when_px4_aborts_on_a_stale_request():
    """A late duplicate of an old MISSION_REQUEST_INT makes PX4 abort the download with
    MAV_MISSION_ERROR; the download starts again and completes."""
    items = survey_items(8, "px4")

    async def go():
        async with ScriptedVehicle(PX4) as v:
            v.state.mission = list(items)
            orig = v._on_mission_request_int
            injected = []

            def with_stale_duplicate(msg):
                if msg.seq == 6 and not injected:
                    injected.append(True)
                    stale = v.mav.mission_request_int_encode(1, 1, 2, 0)
                    stale._header = msg._header
                    orig(stale)  # arrives just before the real request for 6
                orig(msg)
            v._on_mission_request_int = with_stale_duplicate
            async with await open_link(v.connection) as link:
                await link.wait_heartbeat(timeout_s=5)
                got = await download_mission(link, 1, 1)
            return got, sum(m.get_type() == "MISSION_REQUEST_LIST" for m in v.received)

    got, request_lists = run(go())
    assert identical(got, items) and request_lists >= 2  # (the in-flight request may abort once more)


def test_upload_carries_on_after_px4_rejects_a_late_duplicate_count_as_busy():
    items = survey_items(8, "px4")

    async def go():
        async with ScriptedVehicle(PX4) as v:
            orig = v._on_mission_item_int

            def with_duplicate_count(msg):
                orig(msg)
                if msg.seq == 3:  # the duplicate MISSION_COUNT shows up mid-transfer
                    count = v.mav.mission_count_encode(1, 1, len(items), 0)
                    count._header = msg._header
                    v._on_mission_count(count)
            v._on_mission_item_int = with_duplicate_count
            async with await open_link(v.connection) as link:
                await link.wait_heartbeat(timeout_s=5)
                result = await upload_mission(link, 1, 1, items)
            return result, v.state.mission

    result, stored = run(go())
    assert result.verified and identical(stored, items)
