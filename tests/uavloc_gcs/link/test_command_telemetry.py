"""Commands with COMMAND_ACK and the telemetry tracker, against the scripted vehicles."""

import asyncio

import pytest

from uavloc_gcs.dialect import mavlink as M
from uavloc_gcs.errors import CommandError
from uavloc_gcs.link import (VehicleTracker, arm, command, command_long, open_link, return_to_launch,
                             set_current_item, set_mode, start_mission, takeoff, upload_mission)

from .conftest import run, survey_items
from .scripted_vehicle import ARDUPILOT, PX4, Faults, ScriptedVehicle


@pytest.mark.parametrize("style, mode, expected_custom, shown", [
    (ARDUPILOT, "AUTO", 3, "AUTO"), (ARDUPILOT, "GUIDED", 4, "GUIDED"),
    (PX4, "AUTO", 4 << 16 | 4 << 24, "AUTO.MISSION"), (PX4, "RTL", 4 << 16 | 5 << 24, "AUTO.RTL"),
], ids=lambda x: getattr(x, "name", str(x)))
def test_set_mode_and_arm_show_up_in_telemetry(style, mode, expected_custom, shown):
    async def go():
        async with ScriptedVehicle(style, telemetry_interval_s=0.05) as v:
            async with await open_link(v.connection) as link:
                tracker = VehicleTracker(link)
                await link.wait_heartbeat(timeout_s=5)
                assert await set_mode(link, 1, 1, mode) == M.MAV_RESULT_ACCEPTED
                await arm(link, 1, 1)
                await asyncio.sleep(0.2)
                return v.state.custom_mode, tracker[1]

    custom, state = run(go())
    assert custom == expected_custom
    assert state.mode == shown and state.armed and state.autopilot == style.name


def test_telemetry_fields_and_lost_found_events():
    events = []

    async def go():
        async with ScriptedVehicle(PX4, telemetry_interval_s=0.05) as v:
            async with await open_link(v.connection) as link:
                tracker = VehicleTracker(link, lost_after_s=0.4, on_event=lambda e, s: events.append((e, s.system_id)))
                async with asyncio.TaskGroup() as tg:
                    watcher = tg.create_task(tracker.run())
                    await link.wait_heartbeat(timeout_s=5)
                    await asyncio.sleep(0.2)
                    s = tracker[1].snapshot()
                    v.silent = True  # link drop
                    await asyncio.sleep(0.8)
                    lost_during_drop = tracker.is_lost(1)
                    v.silent = False
                    await asyncio.sleep(0.3)
                    watcher.cancel()
                return s, lost_during_drop, tracker.is_lost(1)

    s, lost_during_drop, lost_after = run(go())
    assert (s.lat_deg, s.lon_deg, s.relative_alt_m) == (47.397742, 8.545594, 12.0)
    assert s.battery_pct == 87 and s.battery_v == pytest.approx(15.8)
    assert s.mission_seq == 0 and s.heading_deg == 90.0
    assert lost_during_drop and not lost_after
    assert events == [("new", 1), ("lost", 1), ("found", 1)]


def test_denied_command_names_the_command_and_result():
    async def go():
        async with ScriptedVehicle(PX4, command_results={M.MAV_CMD_COMPONENT_ARM_DISARM: M.MAV_RESULT_DENIED}) as v:
            async with await open_link(v.connection) as link:
                await link.wait_heartbeat(timeout_s=5)
                await arm(link, 1, 1)

    with pytest.raises(CommandError, match="MAV_CMD_COMPONENT_ARM_DISARM refused: MAV_RESULT_DENIED") as info:
        run(go())
    assert "vehicle 1" in str(info.value)


def test_unanswered_command_is_retried_then_reported():
    async def go():
        async with ScriptedVehicle(PX4) as v:
            async with await open_link(v.connection) as link:
                await link.wait_heartbeat(timeout_s=5)
                v.silent = True
                try:
                    await command_long(link, 1, 1, M.MAV_CMD_NAV_RETURN_TO_LAUNCH, timeout_s=0.1, retries=2)
                finally:
                    v.silent = False
                    sent = [m for m in v.received if m.get_type() == "COMMAND_LONG"]
                return sent

    with pytest.raises(CommandError, match="MAV_CMD_NAV_RETURN_TO_LAUNCH: no COMMAND_ACK after 3 tries"):
        run(go())


def test_commands_survive_loss_and_resends_carry_confirmation():
    async def go():
        async with ScriptedVehicle(ARDUPILOT, faults=Faults(loss=0.3, seed=3)) as v:
            async with await open_link(v.connection) as link:
                await link.wait_heartbeat(timeout_s=10)
                for _ in range(5):
                    await command_long(link, 1, 1, M.MAV_CMD_NAV_RETURN_TO_LAUNCH, timeout_s=0.2, retries=10)
                return [m.confirmation for m in v.received if m.get_type() == "COMMAND_LONG"]

    confirmations = run(go())
    assert max(confirmations) > 0  # some were re-sent, with confirmation counting up
    assert len(confirmations) >= 5 and confirmations.count(0) <= 5


def test_mission_helpers_and_set_current_fallback():
    async def go():
        unsupported = {M.MAV_CMD_DO_SET_MISSION_CURRENT: M.MAV_RESULT_UNSUPPORTED}  # PX4 before 2026
        async with ScriptedVehicle(PX4, command_results=unsupported, telemetry_interval_s=0.5) as v:
            async with await open_link(v.connection) as link:
                await link.wait_heartbeat(timeout_s=5)
                await upload_mission(link, 1, 1, survey_items(6, "px4"))
                await takeoff(link, 1, 1, 30.0)
                await start_mission(link, 1, 1)
                await set_current_item(link, 1, 1, 4)
                await return_to_launch(link, 1, 1)
                cmds = [m.command for m in v.received if m.get_type() == "COMMAND_LONG"]
                return v.state.current_seq, cmds, [m for m in v.received if m.get_type() == "MISSION_SET_CURRENT"]

    current, cmds, legacy = run(go())
    assert current == 4 and legacy and legacy[0].seq == 4
    assert cmds == [M.MAV_CMD_NAV_TAKEOFF, M.MAV_CMD_MISSION_START, M.MAV_CMD_DO_SET_MISSION_CURRENT,
                    M.MAV_CMD_NAV_RETURN_TO_LAUNCH]


def test_unknown_mode_is_a_clear_error():
    from uavloc_gcs.errors import ConfigError
    from uavloc_gcs.link import ARDUPILOT as AP
    with pytest.raises(ConfigError, match="unknown ArduPilot mode 'WARP'"):
        AP.mode_params("WARP")
    assert command.command_name(400) == "MAV_CMD_COMPONENT_ARM_DISARM"


def _arm_given_up(texts):
    """The CommandError of an arm given up on against a PX4-style vehicle that refuses every arm
    and sends ``texts`` (delay after the ACK, severity, text) after each refusal."""
    from uavloc_gcs.link import arm_when_ready

    async def go():
        async with ScriptedVehicle(PX4, command_results={M.MAV_CMD_COMPONENT_ARM_DISARM: M.MAV_RESULT_DENIED},
                                   command_texts={M.MAV_CMD_COMPONENT_ARM_DISARM: texts}) as v:
            async with await open_link(v.connection) as link:
                await link.wait_heartbeat(timeout_s=5)
                with pytest.raises(CommandError) as caught:
                    await arm_when_ready(link, 1, 1, timeout_s=0.1)
                return caught.value

    return run(go())


@pytest.mark.parametrize("chatter", [True, False], ids=["info-text-first", "denial-only"])
def test_refused_arm_is_explained_by_the_denial_not_by_chatter(chatter):
    """CI on PX4 SITL: right after boot PX4's "[logger] ./log/<date>/<time>.ulg" (INFO) arrived
    between the arm refusal's ACK and "Arming denied: ..." (CRITICAL, 0.6 s later, in two chunks),
    and the given-up arm named the log file as its reason. Timings and texts as measured there."""
    denial = "Arming denied: Resolve system health failures first"
    texts = [(0.6, M.MAV_SEVERITY_CRITICAL, denial)]
    if chatter:
        texts.insert(0, (0.05, M.MAV_SEVERITY_INFO, "[logger] ./log/2026-11-24/21_08_04.ulg"))
    err = _arm_given_up(texts)
    assert err.reason == denial and denial in str(err)


def test_a_refusal_with_only_chatter_names_no_reason():
    """When the vehicle says nothing that could explain the refusal, the error says none rather
    than quoting an unrelated INFO text."""
    err = _arm_given_up([(0.05, M.MAV_SEVERITY_INFO, "[logger] ./log/x.ulg")])
    assert err.reason is None and "logger" not in str(err)
    assert "MAV_RESULT_DENIED" in str(err)
