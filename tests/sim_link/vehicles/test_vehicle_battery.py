"""A fake vehicle's battery (sim_link/vehicles/battery.py, issue 38): it drains with the energy
model, reports SYS_STATUS and BATTERY_STATUS as each autopilot does on SITL, takes a fresh pack the
ways each one does, and refuses to arm on a pack its autopilot would refuse."""

from __future__ import annotations

import asyncio

import pytest

from sim_link.vehicles.battery import EMPTY_V, FULL_V, MAV_CMD_BATTERY_RESET
from sim_link.vehicles.flavour import ARDUPILOT, PX4
from sim_link.vehicles.mission_server import Peer
from sim_link.vehicles.vehicle import FakeVehicle, VehicleConfig
from uavloc_gcs.dialect import mavlink as mav
from uavloc_gcs.geo import LocalFrame
from uavloc_gcs.link.battery import BatteryReading, PackLimits, judge_pack

GCS = Peer(("127.0.0.1", 1), 245, 190)
FRAME = LocalFrame(42.625, 13.283)
BUDGET_J = 60_000.0


def _vehicle(flavour, **kw) -> FakeVehicle:
    return FakeVehicle(VehicleConfig(1, flavour, FRAME, energy_budget_j=BUDGET_J, arm_refused_after_boot_s=0.0, **kw))


def _command(v: FakeVehicle, command: int, *params: float) -> int:
    p = list(params) + [0.0] * (7 - len(params))
    replies = v.handle(mav.MAVLink_command_long_message(1, 1, command, 0, *p), GCS, 0.0)
    return next(r.msg for r in replies if r.msg.get_type() == "COMMAND_ACK").result


def _message(v: FakeVehicle, name: str):
    p = [float(getattr(mav, f"MAVLINK_MSG_ID_{name}"))] + [0.0] * 6
    replies = v.handle(mav.MAVLink_command_long_message(1, 1, mav.MAV_CMD_REQUEST_MESSAGE, 0, *p), GCS, 0.0)
    return next(r.msg for r in replies if r.msg.get_type() == name)


def _fly(v: FakeVehicle, seconds: float) -> None:
    """Take off to 20 m and hover for ``seconds`` of simulated time."""
    assert v.set_mode("GUIDED" if v.flavour.name == "ardupilot" else "LOITER") and v.arm() and v.takeoff(20.0)
    v.advance(v.t_s + seconds)


def _land(v: FakeVehicle) -> None:
    """Land, disarm, and hold in the mode the next sortie arms in."""
    assert v.set_mode("LAND")
    v.advance(v.t_s + 60.0)
    assert v.landed and not v.armed
    assert v.set_mode("GUIDED" if v.flavour.name == "ardupilot" else "LOITER")


def _reading(v: FakeVehicle) -> BatteryReading:
    return BatteryReading.from_messages(_message(v, "BATTERY_STATUS"), _message(v, "SYS_STATUS"))


def _limits(v: FakeVehicle) -> PackLimits:
    p = v.params
    if v.flavour.name == "px4":
        return PackLimits(p["BAT1_N_CELLS"] * p["BAT1_V_CHARGED"], p["BAT1_N_CELLS"] * p["BAT1_V_EMPTY"], "px4")
    return PackLimits(p["MOT_BAT_VOLT_MAX"], p["MOT_BAT_VOLT_MIN"], "ardupilot")


@pytest.mark.parametrize("flavour", [ARDUPILOT, PX4], ids=["ardupilot", "px4"])
def test_the_pack_drains_with_the_energy_model_in_the_air_only(flavour):
    v = _vehicle(flavour)
    v.advance(30.0)
    assert v.energy_used_j == 0.0 and _reading(v).remaining_pct == 100.0  # on the ground
    _fly(v, 120.0)
    hover = v.cfg.power.power_w(0.0)
    # a climb to 20 m at 5 m/s, then hover: about the hover power for the time in the air
    assert v.energy_used_j == pytest.approx(hover * 120.0, rel=0.05)
    r = _reading(v)
    assert r.remaining_pct == pytest.approx(100 * (1 - v.energy_used_j / BUDGET_J), abs=0.51)
    assert r.voltage_v == pytest.approx(EMPTY_V + (FULL_V - EMPTY_V) * (1 - v.energy_used_j / BUDGET_J), abs=0.001)
    sys_status = _message(v, "SYS_STATUS")
    assert sys_status.battery_remaining == round(r.remaining_pct)


def test_each_autopilot_fills_battery_status_as_its_sitl_does():
    """Measured on ../shared/sitl (docs/guide/sitl.md, "Battery"): ArduCopter id 0, function 0,
    type 0, voltages[0] the pack, current, consumed mAh and hJ; PX4 SIH function 1, type 1, current
    -100 cA in both messages, consumed 0 mAh and -1 hJ."""
    ap, px4 = _vehicle(ARDUPILOT), _vehicle(PX4)
    for v in (ap, px4):
        _fly(v, 60.0)
    a = _message(ap, "BATTERY_STATUS")
    assert (a.id, a.battery_function, a.type) == (0, 0, 0) and list(a.voltages[1:]) == [65535] * 9
    assert a.current_battery > 1000 and a.current_consumed > 0 and a.energy_consumed > 0
    assert a.energy_consumed == round(ap.energy_used_j / 100) and a.charge_state == mav.MAV_BATTERY_CHARGE_STATE_OK
    p = _message(px4, "BATTERY_STATUS")
    assert (p.id, p.battery_function, p.type) == (0, 1, 1)
    assert (p.current_battery, p.current_consumed, p.energy_consumed) == (-100, 0, -1)
    assert _message(px4, "SYS_STATUS").current_battery == -100
    assert BatteryReading.from_messages(p).current_a is None  # "-1 A": not measured


def test_ardupilot_battery_reset_sets_the_remaining_but_not_the_pack():
    v = _vehicle(ARDUPILOT)
    _fly(v, 200.0)
    _land(v)
    drained = _reading(v)
    assert drained.remaining_pct < 60 and drained.voltage_v < 15.7
    assert _command(v, MAV_CMD_BATTERY_RESET, 0, 100) == mav.MAV_RESULT_FAILED  # no battery in the mask
    assert _command(v, MAV_CMD_BATTERY_RESET, 1, 100) == mav.MAV_RESULT_ACCEPTED
    reset = _reading(v)
    assert reset.remaining_pct == 100.0 and reset.voltage_v == pytest.approx(drained.voltage_v)
    assert _message(v, "BATTERY_STATUS").current_consumed == 0
    # the remaining says fresh, the voltage does not: the judge is not fooled
    verdict = judge_pack(reset, _limits(v))
    assert not verdict.fresh and "below" in verdict.reason
    # SITL's simulated pack: SIM_BATT_VOLTAGE starts it again at that voltage
    v.handle(mav.MAVLink_param_set_message(1, 1, b"SIM_BATT_VOLTAGE", FULL_V, mav.MAV_PARAM_TYPE_REAL32), GCS, 0.0)
    assert judge_pack(_reading(v), _limits(v)).fresh


def test_px4_refuses_battery_reset_as_its_sitl_does():
    assert _command(_vehicle(PX4), MAV_CMD_BATTERY_RESET, 1, 100) == mav.MAV_RESULT_UNSUPPORTED


def test_a_swap_is_seen_at_once_by_px4_and_by_ardupilot_after_its_reboot():
    for flavour in (ARDUPILOT, PX4):
        v = _vehicle(flavour)
        _fly(v, 200.0)
        _land(v)
        assert not judge_pack(_reading(v), _limits(v)).fresh
        v.swap_pack()
        r = _reading(v)
        assert r.voltage_v == pytest.approx(FULL_V)
        if flavour is PX4:
            assert r.remaining_pct == 100.0 and judge_pack(r, _limits(v)).fresh
        else:  # its monitor still counts the old pack until it restarts (as the pack swap makes it)
            assert r.remaining_pct < 60 and not judge_pack(r, _limits(v)).fresh
            v.reboot()
            assert judge_pack(_reading(v), _limits(v)).fresh


def test_ardupilot_reboot_with_the_used_pack_says_100_percent_and_only_the_voltage_tells():
    v = _vehicle(ARDUPILOT)
    _fly(v, 200.0)
    _land(v)
    v.reboot()
    r = _reading(v)
    assert r.remaining_pct == 100.0 and r.voltage_v < 15.7
    verdict = judge_pack(r, _limits(v), vehicle="uav1")
    assert not verdict.fresh and verdict.reason.startswith("uav1 reports 100 % remaining, ")


def test_arming_is_refused_on_a_pack_the_autopilot_refuses():
    v = _vehicle(ARDUPILOT)
    v.params["BATT_LOW_VOLT"] = 16.0  # a 4S pack below 4.0 V a cell: the low-voltage failsafe
    _fly(v, 200.0)
    _land(v)
    assert v.battery.failsafe and _message(v, "BATTERY_STATUS").charge_state == mav.MAV_BATTERY_CHARGE_STATE_LOW
    assert _command(v, mav.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mav.MAV_RESULT_FAILED
    texts = [r.msg.text for r in v.advance(v.t_s + 0.5) if r.msg.get_type() == "STATUSTEXT"]
    assert "Arm: Battery failsafe" in texts
    assert not (_message(v, "SYS_STATUS").onboard_control_sensors_health & mav.MAV_SYS_STATUS_PREARM_CHECK)
    v.swap_pack()
    assert _command(v, mav.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mav.MAV_RESULT_FAILED  # latched until a reboot
    v.reboot()
    assert _command(v, mav.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mav.MAV_RESULT_ACCEPTED
    # on the ground below BATT_LOW_VOLT (for BATT_LOW_TIMER s): refused until the voltage is back
    g = _vehicle(ARDUPILOT)
    g.energy_used_j = 0.8 * BUDGET_J  # 14.56 V
    g.params["BATT_LOW_VOLT"] = 15.0
    g.advance(g.t_s + 12.0)
    assert g.set_mode("GUIDED") and _command(g, mav.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mav.MAV_RESULT_FAILED
    assert "Arm: Battery 1 low voltage failsafe" in [
        r.msg.text for r in g.advance(g.t_s + 0.5) if r.msg.get_type() == "STATUSTEXT"]
    g.swap_pack()
    g.advance(g.t_s + 0.5)
    assert _command(g, mav.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mav.MAV_RESULT_ACCEPTED  # not latched on the ground
    # BATT_ARM_VOLT: below it, no arming
    w = _vehicle(ARDUPILOT)
    w.params["BATT_ARM_VOLT"] = 16.5
    _fly(w, 100.0)
    _land(w)
    assert _command(w, mav.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mav.MAV_RESULT_FAILED
    assert "Arm: Battery 1 below minimum arming voltage" in [
        r.msg.text for r in w.advance(w.t_s + 0.5) if r.msg.get_type() == "STATUSTEXT"]
    # PX4: at its critical charge (7 %) and below
    p = _vehicle(PX4)
    p.energy_used_j = 0.94 * BUDGET_J
    assert _command(p, mav.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mav.MAV_RESULT_TEMPORARILY_REJECTED
    assert "Critical battery" in [r.msg.text for r in p.advance(p.t_s + 1.0) if r.msg.get_type() == "STATUSTEXT"]
    assert _message(p, "BATTERY_STATUS").charge_state == mav.MAV_BATTERY_CHARGE_STATE_CRITICAL


def test_px4_sih_refill_on_disarm_is_an_option():
    v = _vehicle(PX4, refill_on_disarm=True)
    _fly(v, 200.0)
    assert v.energy_used_j > 0
    _land(v)
    assert v.energy_used_j == 0.0 and _reading(v).remaining_pct == 100.0


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_the_link_tells_a_fresh_pack_from_a_used_one_over_mavlink(autopilot, tmp_path):
    """check_fresh_pack over real MAVLink 2 on UDP against a FakeFleet vehicle: fresh at boot,
    not after a drain, fresh after the team's swap (which reboots it)."""
    from pathlib import Path

    from sim_link.vehicles.fleet import FakeFleet
    from uavloc_gcs.link import check_fresh_pack, flavour_named, open_link, pack_limits
    from uavloc_gcs.scenario import load_scenario

    sc = load_scenario(Path(__file__).resolve().parents[3] / "examples" / "small.toml").replace(
        fleet={"autopilot": autopilot, "vehicles": 1}, simulation={"people": 0})

    async def go():
        async with FakeFleet(sc, speedup=5, seed=1, base_port=0) as fleet:
            async with await open_link(fleet.endpoints[0][1]) as link:
                await link.wait_heartbeat(1, timeout_s=10)
                flavour = flavour_named(autopilot)
                limits = await pack_limits(link, 1, flavour)
                fresh = await check_fresh_pack(link, 1, flavour, limits=limits)
                fleet.vehicle(1).energy_used_j = 0.5 * sc.fleet.energy_budget_j  # half a pack flown
                fleet.vehicle(1).battery.consumed_j = 0.5 * sc.fleet.energy_budget_j
                used = await check_fresh_pack(link, 1, flavour, limits=limits)
                fleet.swap_pack(1)
                await asyncio.sleep(1.0)  # the reboot's silence (2 s of mission time at 5x)
                await link.wait_heartbeat(1, timeout_s=10)
                swapped = await check_fresh_pack(link, 1, flavour, limits=limits)
                return limits, fresh, used, swapped

    limits, fresh, used, swapped = asyncio.run(asyncio.wait_for(go(), 60))
    assert limits is not None and limits.full_v == pytest.approx(FULL_V)
    assert fresh.fresh and "BATTERY_STATUS" in fresh.reading.source, fresh.reason
    assert not used.fresh and used.reading.remaining_pct == pytest.approx(50, abs=1), used.reason
    assert swapped.fresh, swapped.reason


def test_the_fake_team_swaps_a_landed_used_pack_after_the_swap_time_while_it_has_spares():
    """FakeFleet(team_swaps=True), what `uavloc demo` runs with several packs: a vehicle landed and
    disarmed on a pack at most half charged gets a fresh one battery_swap_s later (with the swap's
    reboot), as many times as it has spares."""
    from pathlib import Path

    from sim_link.vehicles.fleet import FakeFleet
    from uavloc_gcs.scenario import load_scenario

    sc = load_scenario(Path(__file__).resolve().parents[3] / "examples" / "small.toml").replace(
        fleet={"vehicles": 1, "batteries": 2, "battery_swap_s": 60.0}, simulation={"people": 0})
    fleet = FakeFleet(sc, speedup=1, seed=1, base_port=0, team_swaps=True)
    v = fleet.vehicle(1)
    assert v.landed and not v.armed
    fleet._team(10.0)
    fleet._team(100.0)
    assert v.battery.charge == 1.0 and fleet.spare_packs == [1]  # a fresh pack is left in
    v.battery.used_j = 0.6 * v.battery.capacity_j
    fleet._team(100.0)
    fleet._team(159.0)
    assert v.battery.charge == pytest.approx(0.4) and fleet.spare_packs == [1]  # not before the swap time
    fleet._team(160.0)
    assert v.battery.charge == 1.0 and fleet.spare_packs == [0]
    v.battery.used_j = 0.9 * v.battery.capacity_j
    for t in (200.0, 300.0, 400.0):
        fleet._team(t)
    assert v.battery.charge == pytest.approx(0.1), "no spare left: the pack stays"
