"""How a fake vehicle answers a mission start on the ground, as the real autopilots do (issue 26):
ArduCopter refuses AUTO armed and landed unless the mission goes on with a take-off
(ModeAuto::init: "Auto: Missing Takeoff Cmd", MISSION_START -> FAILED); PX4 arms by MISSION_START
(Commander: "switch to AUTO_MISSION and ARM") and climbs to fly a mission without a take-off."""

from __future__ import annotations

from uavloc_gcs.dialect import mavlink as mav
from uavloc_gcs.geo import LocalFrame
from uavloc_gcs.mission import flight_mission, to_wire
from sim_link.vehicles.flavour import ARDUPILOT, PX4
from sim_link.vehicles.mission_server import Peer
from sim_link.vehicles.vehicle import FakeVehicle, VehicleConfig

GCS = Peer(("127.0.0.1", 1), 245, 190)
FRAME = LocalFrame(42.625, 13.283)


def _vehicle(flavour, *, takeoff: bool) -> FakeVehicle:
    v = FakeVehicle(VehicleConfig(1, flavour, FRAME, arm_refused_after_boot_s=0.0))
    plan = flight_mission([(42.626, 13.284), (42.627, 13.284)], alt_m=50, speed_m_s=10, autopilot=flavour.name,
                          home_latlon_deg=(42.625, 13.283), include_takeoff=takeoff)
    v.mission.stores[0] = list(to_wire(plan, flavour.name))
    v._on_mission_changed(0)
    return v


def _command(v: FakeVehicle, command: int, *params: float):
    p = list(params) + [0.0] * (7 - len(params))
    replies = v.handle(mav.MAVLink_command_long_message(1, 1, command, 0, *p), GCS, 0.0)
    ack = next(r.msg for r in replies if r.msg.get_type() == "COMMAND_ACK")
    return ack.result, replies


def _texts(v: FakeVehicle, replies) -> list[str]:
    out = list(replies) + v.advance(v.t_s + 0.1)
    return [r.msg.text for r in out if r.msg.get_type() == "STATUSTEXT"]


def _armed_on_ground(flavour, *, takeoff: bool) -> FakeVehicle:
    v = _vehicle(flavour, takeoff=takeoff)
    assert v.set_mode("GUIDED") and v.arm()
    return v


def test_ardupilot_refuses_a_mission_start_on_the_ground_without_a_takeoff():
    v = _armed_on_ground(ARDUPILOT, takeoff=False)
    result, replies = _command(v, mav.MAV_CMD_MISSION_START)
    assert result == mav.MAV_RESULT_FAILED
    assert "Auto: Missing Takeoff Cmd" in _texts(v, replies)
    assert v.mode == "GUIDED" and v.landed
    v.advance(5.0)
    assert v.landed and v.kin.pos[2] == 0.0


def test_ardupilot_refuses_auto_resuming_a_stopped_mission_at_a_waypoint():
    """The second search on the same vehicles: the previous scan, stopped by RTL at item 11, is
    resumed there by MISSION_START (ArduPilot keeps its item index across an upload)."""
    v = _armed_on_ground(ARDUPILOT, takeoff=True)
    v.executor.current, v.executor.started = 3, True  # a waypoint of the mission stopped earlier
    result, _ = _command(v, mav.MAV_CMD_MISSION_START)
    assert result == mav.MAV_RESULT_FAILED
    result, _ = _command(v, mav.MAV_CMD_DO_SET_MISSION_CURRENT, 1)  # back to the take-off
    assert result == mav.MAV_RESULT_ACCEPTED
    result, _ = _command(v, mav.MAV_CMD_MISSION_START)
    assert result == mav.MAV_RESULT_ACCEPTED and v.mode == "AUTO"
    v.advance(3.0)
    assert not v.landed and v.kin.pos[2] > 1.0


def test_ardupilot_accepts_auto_disarmed_or_with_a_takeoff():
    v = _vehicle(ARDUPILOT, takeoff=False)  # disarmed: ModeAuto::init checks only armed and landed
    assert v.set_mode("AUTO")
    assert _armed_on_ground(ARDUPILOT, takeoff=True).set_mode("AUTO")


def test_px4_arms_by_mission_start_and_climbs_even_without_a_takeoff():
    v = _vehicle(PX4, takeoff=False)
    assert not v.armed and v.landed
    result, _ = _command(v, mav.MAV_CMD_MISSION_START)  # at once after the upload: still checked
    assert result == mav.MAV_RESULT_DENIED and not v.armed
    v.advance(PX4.mission_valid_after_upload_s)
    result, _ = _command(v, mav.MAV_CMD_MISSION_START)
    assert result == mav.MAV_RESULT_ACCEPTED and v.armed and v.mode == "AUTO"
    v.advance(3.0)
    assert v.kin.pos[2] > 1.0, "it took off by itself: why the ground station must never do this"


def test_px4_mission_start_is_denied_when_it_cannot_arm():
    v = FakeVehicle(VehicleConfig(1, PX4, FRAME, arm_refused_after_boot_s=10.0))
    v.mission.stores[0] = list(_vehicle(PX4, takeoff=True).mission_items)
    result, _ = _command(v, mav.MAV_CMD_MISSION_START)
    assert result == mav.MAV_RESULT_DENIED and not v.armed
