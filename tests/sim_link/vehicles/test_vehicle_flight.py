"""A fake vehicle flies the paper scenario's scan mission (in-process, no sockets, fixed steps)."""

from __future__ import annotations

import math
import numpy as np
import pytest

from uavloc_gcs.dialect import mavlink as mav
from uavloc_gcs.dialect.rssi import decode_rssi_batches
from uavloc_gcs.mission import to_wire
from uavloc_gcs.scan import plan_scan, scan_missions
from uavloc_gcs.scenario import load_scenario
from sim_link.vehicles.executor import corner
from sim_link.vehicles.flavour import FLAVOURS
from sim_link.vehicles.mission_server import Peer, Reply
from sim_link.vehicles.vehicle import PHYSICS_DT_S, FakeVehicle, VehicleConfig
from sim_link.world import World

PAPER = load_scenario("examples/paper.toml")
GCS = Peer(("127.0.0.1", 1), 255, 190)
EPOCH = 1_800_000_000.0


def _vehicle(sc, sysid=1, world=None, seed=1):
    f = sc.fleet
    cfg = VehicleConfig(sysid, FLAVOURS[f.autopilot], sc.frame, cruise_speed_m_s=f.speed_m_s,
                        max_accel_m_s2=f.max_acceleration_m_s2, energy_budget_j=f.energy_budget_j,
                        slot_s=sc.channel.slot_s, epoch_unix_s=EPOCH)
    return FakeVehicle(cfg, world if world is not None else World(sc, seed=seed))


def _fly(v, wire, *, t_end_s=600.0, chunk_s=PHYSICS_DT_S):
    """Store the mission, arm, AUTO, run to the end; returns per-step samples and all messages."""
    v.mission.stores[0] = list(wire)
    v.executor.reset()
    assert v.set_mode("AUTO") and v.arm()
    t, samples, msgs = 0.0, [], []
    while t < t_end_s and not (v.landed and not v.armed and t > 5):
        t += chunk_s
        for r in v.advance(t):
            msgs.append((t, r))
        samples.append((v.t_s, *v.kin.pos, *v.kin.vel, v.executor.current))
    return np.array(samples), msgs


@pytest.fixture(scope="module", params=["ardupilot", "px4"])
def scan_flight(request):
    sc = PAPER.replace(fleet={"autopilot": request.param})
    plan = scan_missions(sc, plan_scan(sc))[0]
    wire = to_wire(plan, request.param)
    v = _vehicle(sc)
    samples, msgs = _fly(v, wire)
    return sc, wire, v, samples, msgs


def test_scan_reaches_every_item_in_order_and_lands(scan_flight):
    sc, wire, v, samples, msgs = scan_flight
    reached = [r.msg.seq for _, r in msgs if r.msg.get_type() == "MISSION_ITEM_REACHED"]
    nav = [w.seq for w in wire if w.command in (16, 20, 22)]
    first = 1 if sc.fleet.autopilot == "ardupilot" else 0
    assert nav and reached == [s for s in nav if s >= first]
    assert v.landed and not v.armed
    assert np.linalg.norm(v.position_xyz_m[:2]) < 2.0  # RTL came home
    texts = [r.msg.text for _, r in msgs if r.msg.get_type() == "STATUSTEXT"]
    assert v.flavour.mission_done_text in texts


def test_scan_flies_through_waypoints_without_stopping_and_within_the_acceleration_bound(scan_flight):
    sc, wire, v, samples, msgs = scan_flight
    t, vel = samples[:, 0], samples[:, 4:7]
    reached = {r.msg.seq: tt for tt, r in msgs if r.msg.get_type() == "MISSION_ITEM_REACHED"}
    wps = [w.seq for w in wire if w.command == 16 and w.seq > 0]
    # from cruise speed after the first waypoint (it may be right above the launch point) to the
    # second-to-last waypoint: every waypoint in between is a pass-through one
    t0 = reached[wps[0]] + sc.fleet.speed_m_s / sc.fleet.max_acceleration_m_s2 + 1.0
    t1 = reached[wps[-2]]
    speed = np.hypot(vel[:, 0], vel[:, 1])
    cruise = (t >= t0) & (t <= t1)
    assert cruise.sum() > 100
    # corners are flown round at the speed whose turn radius keeps within corner_cut_m of the
    # waypoint (11 m/s for the scan's 90 deg turns), never stopped at
    v90, _ = corner([1.0, 0.0], [0.0, 1.0], sc.fleet.speed_m_s, sc.fleet.max_acceleration_m_s2, v.cfg.corner_cut_m)
    assert speed[cruise].min() > 0.9 * v90 > 5.0
    assert np.median(speed[cruise]) == pytest.approx(sc.fleet.speed_m_s, rel=0.02)
    acc = np.linalg.norm(np.diff(vel, axis=0), axis=1) / np.diff(t)
    airborne = (samples[:-1, 3] > 0.0) & (samples[1:, 3] > 0.0)  # touchdown stops it at 0.5 m/s
    acc = acc[airborne]
    assert acc.max() <= sc.fleet.max_acceleration_m_s2 * 1.5  # horizontal and vertical bounded separately
    assert np.abs(samples[cruise, 3] - sc.fleet.altitude_m).max() < 1.0


def test_scan_track_stays_on_the_planned_lanes(scan_flight):
    from shapely.geometry import LineString, Point

    sc, wire, v, samples, msgs = scan_flight
    lanes = LineString(np.vstack([[0.0, 0.0], plan_scan(sc).vehicles[0].waypoints_xy_m, [0.0, 0.0]]))
    dev = np.array([lanes.distance(Point(p)) for p in samples[::10, 1:3]])
    assert dev.max() < v.cfg.corner_cut_m + 2.0  # rounded corners only, no wide loops


def test_battery_follows_the_energy_model(scan_flight):
    sc, wire, v, samples, msgs = scan_flight
    status = [r.msg for _, r in msgs if r.msg.get_type() == "SYS_STATUS"]
    remaining = [m.battery_remaining for m in status]
    assert remaining[0] == 100 and remaining[-1] < remaining[0]
    assert all(a >= b for a, b in zip(remaining, remaining[1:]))
    assert remaining[-1] == round(100 * (1 - v.energy_used_j / sc.fleet.energy_budget_j))
    # Flight time x power bounds: between hover power and the 25 m/s power for the airborne time
    airborne = samples[:, 3] > 0.05
    t_air = airborne.sum() * PHYSICS_DT_S
    pm = sc.power_model
    assert pm.power_w(10.2) * t_air * 0.95 < v.energy_used_j < pm.power_w(25.0) * t_air * 1.05


def test_rssi_matches_the_channel_model(scan_flight):
    sc, wire, v, samples, msgs = scan_flight
    rssi = [r.msg for _, r in msgs if r.msg.get_type() == "UAVLOC_RSSI_BATCH"]
    assert all(r.component == 191 for _, r in msgs if r.msg.get_type() == "UAVLOC_RSSI_BATCH")
    for m in rssi:
        m._header = mav.MAVLink_header(m.id, srcSystem=1, srcComponent=191)
    slots = decode_rssi_batches(rssi, sc.frame, epoch_unix_s=EPOCH)
    assert len(slots) > 500
    world = v.world
    people = world.positions(slots.t_s)  # (N, S, 2)
    idx = np.array([world.index_of(e) for e in slots.emitter_id])
    xy = people[np.arange(len(slots)), idx]
    d = np.sqrt(np.sum((xy - slots.xyz_m[:, :2]) ** 2, axis=1) + slots.xyz_m[:, 2] ** 2)
    assert d.max() <= sc.fleet.comm_range_m + 0.5
    resid = slots.rssi_dbm - world.channel.median_rssi_dbm(d)
    se = sc.channel.shadowing_sigma_db / np.sqrt(sc.channel.samples_per_slot)  # slot mean of 10 samples
    assert abs(resid.mean()) < 4 * se / np.sqrt(len(resid)) + 0.02
    assert resid.std() == pytest.approx(se, rel=0.1)
    # exactly the (slot, person) pairs within range are reported: check at the physics step times
    slot = sc.channel.slot_s
    reported = set(zip(np.round(slots.t_s / slot).astype(int).tolist(), slots.emitter_id.tolist()))
    air = samples[samples[:, 3] > 0.0]
    air = air[:: max(1, len(air) // 400)]
    ppl = world.positions(air[:, 0])  # (T, S, 2)
    d3 = np.sqrt(np.sum((ppl - air[:, None, 1:3]) ** 2, axis=2) + air[:, None, 3] ** 2)
    k, j = np.nonzero(d3 <= sc.fleet.comm_range_m)
    expected = set(zip(np.round(air[k, 0] / slot).astype(int).tolist(), world.emitter_ids[j].tolist()))
    assert len(expected) > 20
    grid = set(np.round(air[:, 0] / slot).astype(int).tolist())
    assert {p for p in reported if p[0] in grid} == expected


def test_same_seed_same_flight_and_rssi():
    sc = PAPER.replace(fleet={"autopilot": "px4"})
    wire = to_wire(scan_missions(sc, plan_scan(sc))[1], "px4")
    runs = []
    for _ in range(2):
        v = _vehicle(sc, sysid=2, seed=5)
        s, m = _fly(v, wire, t_end_s=120.0, chunk_s=0.7)
        runs.append((s, [x.msg.pack(mav.MAVLink(None, 2, 191)) for _, x in m
                         if x.msg.get_type() == "UAVLOC_RSSI_BATCH"]))
    np.testing.assert_array_equal(runs[0][0][-1], runs[1][0][-1])
    assert runs[0][1] == runs[1][1] and len(runs[0][1]) > 10


def _cmd(v, command, *p):
    p = list(p) + [0.0] * (7 - len(p))
    out = v.handle(mav.MAVLink_command_long_message(1, 1, command, 0, *p), GCS, 0.0)
    return [r.msg for r in out if r.msg.get_type() == "COMMAND_ACK"][0].result


def test_guided_takeoff_rtl_and_land_by_command():
    sc = PAPER
    v = _vehicle(sc)
    assert _cmd(v, mav.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 30) == mav.MAV_RESULT_DENIED  # disarmed
    assert _cmd(v, mav.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mav.MAV_RESULT_ACCEPTED
    assert _cmd(v, mav.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 30) == mav.MAV_RESULT_FAILED  # not GUIDED
    assert _cmd(v, mav.MAV_CMD_DO_SET_MODE, 1, 4) == mav.MAV_RESULT_ACCEPTED  # GUIDED
    assert _cmd(v, mav.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 30) == mav.MAV_RESULT_ACCEPTED
    v.advance(12.0)
    assert v.position_xyz_m[2] == pytest.approx(30.0, abs=0.6) and not v.landed
    assert _cmd(v, mav.MAV_CMD_COMPONENT_ARM_DISARM, 0) == mav.MAV_RESULT_FAILED  # in the air
    v.kin.pos[:2] = [300.0, -200.0]  # as if it had flown there
    assert _cmd(v, mav.MAV_CMD_NAV_RETURN_TO_LAUNCH) == mav.MAV_RESULT_ACCEPTED
    v.advance(120.0)
    assert v.landed and not v.armed and np.linalg.norm(v.position_xyz_m) < 1.5
    assert _cmd(v, mav.MAV_CMD_NAV_LAND) == mav.MAV_RESULT_FAILED  # already on the ground
    assert _cmd(v, 31010) == mav.MAV_RESULT_UNSUPPORTED


def test_px4_mode_encoding_and_takeoff_amsl():
    sc = PAPER.replace(fleet={"autopilot": "px4"})
    v = _vehicle(sc)
    assert _cmd(v, mav.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mav.MAV_RESULT_ACCEPTED
    assert _cmd(v, mav.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, float("nan"), float("nan"), float("nan"), 20.0) == 0
    v.advance(10.0)
    assert v.mode == "LOITER" and v.position_xyz_m[2] == pytest.approx(20.0, abs=0.6)
    hb = v.heartbeat_reply().msg
    assert hb.autopilot == mav.MAV_AUTOPILOT_PX4 and hb.custom_mode == (4 << 16) | (3 << 24)
    assert hb.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED
    assert _cmd(v, mav.MAV_CMD_DO_SET_MODE, 1, 4, 5) == mav.MAV_RESULT_ACCEPTED and v.mode == "RTL"


def test_set_current_and_mission_current():
    sc = PAPER
    v = _vehicle(sc)
    wire = to_wire(scan_missions(sc, plan_scan(sc))[0], "ardupilot")
    v.mission.stores[0] = wire
    assert _cmd(v, mav.MAV_CMD_DO_SET_MISSION_CURRENT, 3) == mav.MAV_RESULT_ACCEPTED
    assert v.current_seq == 3 and v.mode == "STABILIZE"  # does not switch into AUTO
    assert _cmd(v, mav.MAV_CMD_DO_SET_MISSION_CURRENT, len(wire)) == mav.MAV_RESULT_FAILED
    out = v.handle(mav.MAVLink_mission_set_current_message(1, 1, 2), GCS, 0.0)
    assert out[0].msg.get_type() == "MISSION_CURRENT" and out[0].msg.seq == 2
    mc = v.mission_current_reply().msg
    assert mc.total == len(wire) - 1 and mc.mission_state == mav.MISSION_STATE_NOT_STARTED


def test_command_int_and_nan_parameters():
    v = _vehicle(PAPER)
    nan = float("nan")
    out = v.handle(mav.MAVLink_command_long_message(1, 1, mav.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, nan, nan, nan,
                                                    nan, nan, nan), GCS, 0.0)
    assert out[0].msg.result == mav.MAV_RESULT_ACCEPTED and v.armed
    out = v.handle(mav.MAVLink_command_int_message(1, 1, 0, mav.MAV_CMD_DO_SET_MODE, 0, 0, 1, 4, nan, nan, 0, 0, 0),
                   GCS, 0.0)
    assert out[0].msg.command == mav.MAV_CMD_DO_SET_MODE and out[0].msg.result == 0 and v.mode == "GUIDED"
    assert out[0].to == GCS and (out[0].msg.target_system, out[0].msg.target_component) == (255, 190)
    out = v.handle(mav.MAVLink_command_long_message(1, 1, mav.MAV_CMD_REQUEST_MESSAGE, 0,
                                                    mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION, nan, nan, nan, nan, nan,
                                                    nan), GCS, 0.0)
    kinds = [r.msg.get_type() for r in out]
    assert kinds == ["COMMAND_ACK", "AUTOPILOT_VERSION"]
    assert out[1].msg.capabilities & mav.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    assert v.handle(mav.MAVLink_command_long_message(2, 1, mav.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, 0, 0, 0, 0, 0, 0),
                    GCS, 0.0) == []  # for another system


def test_guided_goto_by_reposition_and_position_target():
    sc = PAPER
    v = _vehicle(sc)
    assert _cmd(v, mav.MAV_CMD_DO_SET_MODE, 1, 4) == 0 and _cmd(v, mav.MAV_CMD_COMPONENT_ARM_DISARM, 1) == 0
    assert _cmd(v, mav.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 50) == 0
    v.advance(12.0)
    lat, lon = sc.frame.to_wgs84(300.0, 200.0)
    nan = float("nan")
    out = v.handle(mav.MAVLink_command_int_message(1, 1, 3, mav.MAV_CMD_DO_REPOSITION, 0, 0, 20.0, 0, 0, nan,
                                                   int(round(lat * 1e7)), int(round(lon * 1e7)), 60.0), GCS, 0.0)
    assert out[0].msg.result == mav.MAV_RESULT_ACCEPTED and v.speed_m_s == 20.0
    v.advance(40.0)
    np.testing.assert_allclose(v.position_xyz_m, [300.0, 200.0, 60.0], atol=0.5)
    lat, lon = sc.frame.to_wgs84(0.0, 100.0)
    v.handle(mav.MAVLink_set_position_target_global_int_message(0, 1, 1, 6, 0b110111111000, int(round(lat * 1e7)),
                                                                int(round(lon * 1e7)), 40.0, 0, 0, 0, 0, 0, 0, 0, 0),
             GCS, 0.0)
    v.advance(70.0)
    np.testing.assert_allclose(v.position_xyz_m, [0.0, 100.0, 40.0], atol=0.5)


@pytest.mark.parametrize("autopilot,speed_param,scale", [("ardupilot", "WPNAV_SPEED", 100.0),
                                                         ("px4", "MPC_XY_CRUISE", 1.0)])
def test_parameters_list_read_and_set(autopilot, speed_param, scale):
    v = _vehicle(PAPER.replace(fleet={"autopilot": autopilot}))
    out = v.handle(mav.MAVLink_param_request_list_message(1, 1), GCS, 0.0)
    assert len(out) == len(v.params) and {r.msg.param_count for r in out} == {len(v.params)}
    assert [r.msg.param_index for r in out] == list(range(len(out)))
    (r,) = v.handle(mav.MAVLink_param_request_read_message(1, 1, speed_param.encode(), -1), GCS, 0.0)
    assert r.msg.param_value == pytest.approx(PAPER.fleet.speed_m_s * scale)
    (r,) = v.handle(mav.MAVLink_param_set_message(1, 1, speed_param.encode(), 12.0 * scale, 9), GCS, 0.0)
    assert r.msg.param_value == pytest.approx(12.0 * scale) and v.speed_m_s == pytest.approx(12.0)
    assert v.handle(mav.MAVLink_param_set_message(1, 1, b"NO_SUCH", 1.0, 9), GCS, 0.0) == []


def _wps(sc, xy, autopilot, *, takeoff=True, rtl=True, alt=40.0):
    from uavloc_gcs.mission import flight_mission

    plan = flight_mission(sc.frame.to_wgs84_latlon(np.asarray(xy, float)), alt_m=alt, speed_m_s=15,
                          autopilot=autopilot, home_latlon_deg=sc.launch_latlon_deg, include_takeoff=takeoff,
                          return_home=rtl)
    return to_wire(plan)


def test_auto_without_takeoff_item_px4_climbs_ardupilot_refuses():
    for ap in ("px4", "ardupilot"):
        sc = PAPER.replace(fleet={"autopilot": ap})
        v = _vehicle(sc)
        samples, msgs = _fly(v, _wps(sc, [[100, 0], [100, 100]], ap, takeoff=False), t_end_s=120.0)
        texts = [r.msg.text for _, r in msgs if r.msg.get_type() == "STATUSTEXT"]
        if ap == "px4":
            assert samples[:, 3].max() > 39.0 and "Mission finished, loitering" in texts
        else:
            assert samples[:, 3].max() == 0.0 and "Auto: Missing Takeoff Cmd" in texts


def test_do_jump_repeats_a_leg():
    from uavloc_gcs.mission import WireItem

    sc = PAPER.replace(fleet={"autopilot": "px4"})
    items = _wps(sc, [[100, 0], [100, 100]], "px4", rtl=False)  # takeoff, speed, wp2, wp3
    jump = WireItem(len(items), 2, 177, 0, 1, 2.0, 2.0, 0, 0, 0, 0, 0.0)  # back to seq 2, twice
    v = _vehicle(sc)
    samples, msgs = _fly(v, items + [jump], t_end_s=200.0)
    reached = [r.msg.seq for _, r in msgs if r.msg.get_type() == "MISSION_ITEM_REACHED"]
    assert reached == [0, 2, 3, 2, 3, 2, 3]


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_new_mission_in_flight(autopilot):
    """ArduPilot keeps flying the current index of the new mission; PX4 restarts the new plan."""
    sc = PAPER.replace(fleet={"autopilot": autopilot})
    v = _vehicle(sc)
    first = _wps(sc, [[200, 0], [200, 200], [0, 200]], autopilot)
    v.mission.stores[0] = first
    v.executor.reset()
    assert v.set_mode("AUTO") and v.arm()
    v.advance(30.0)
    cur = v.current_seq
    assert v.mode == "AUTO" and not v.landed and cur >= 2
    second = _wps(sc, [[-200, 0], [-200, -200], [0, -200]], autopilot)
    srv = v.mission
    srv.handle(mav.MAVLink_mission_count_message(1, 1, len(second), 0), GCS, 0.0)
    for w in second:
        srv.handle(mav.MAVLink_mission_item_int_message(1, 1, w.seq, w.frame, w.command, w.current, w.autocontinue,
                                                        w.param1, w.param2, w.param3, w.param4, w.x, w.y, w.z, 0),
                   GCS, 0.0)
    assert all(a.same_as(b) for a, b in zip(v.mission_items, second))
    assert v.current_seq == (cur if autopilot == "ardupilot" else 0)
    v.advance(200.0)
    assert v.executor.complete and v.landed


def test_hovering_after_takeoff_draws_hover_power():
    v = _vehicle(PAPER)
    assert _cmd(v, mav.MAV_CMD_DO_SET_MODE, 1, 4) == 0 and _cmd(v, mav.MAV_CMD_COMPONENT_ARM_DISARM, 1) == 0
    assert _cmd(v, mav.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 20) == 0
    v.advance(100.0)  # 4 s climbing, then hovering
    assert v.energy_used_j == pytest.approx(PAPER.power_model.power_w(0.0) * 100.0, rel=0.01)


@pytest.mark.parametrize("ap", ["ardupilot", "px4"])
def test_rtl_lands_in_rtl_and_the_next_missions_rtl_item_flies_home_again(ap):
    """Both autopilots land at home inside RTL mode (measured on SITL: the mode stays RTL). A return
    that ended (or was cut short) must not leave the next mission's RTL item landing where it is."""
    sc = PAPER.replace(fleet={"autopilot": ap})
    v = _vehicle(sc)
    _fly(v, _wps(sc, [[100, 0], [100, 60]], ap, rtl=False), t_end_s=120.0)
    assert not v.landed
    assert v.set_mode("RTL")
    t = v.t_s
    while not (v.landed and not v.armed) and t < v.t_s + 300:
        t += 0.5
        v.advance(t)
    assert v.landed and v.mode == "RTL" and np.linalg.norm(v.position_xyz_m[:2]) < 2.0
    v.set_mode("GUIDED" if ap == "ardupilot" else "LOITER")
    samples, _ = _fly(v, _wps(sc, [[100, 0]], ap, rtl=True), t_end_s=v.t_s + 300.0)
    assert samples[:, 1].max() > 90.0  # flew out to the waypoint
    assert v.landed and not v.armed and np.linalg.norm(v.position_xyz_m[:2]) < 2.0


def test_ardupilot_flies_loiter_turns_as_a_circle_and_goes_on():
    """NAV_LOITER_TURNS as ArduCopter SITL flies it (docs/science/looks.md): to the circle's edge,
    the turns at about sqrt(a r) (7.9 m/s around 60 m), then the next item -- not a hover at the
    centre for ever, as the fake did before."""
    from uavloc_gcs.mission import WireItem

    sc = PAPER.replace(fleet={"autopilot": "ardupilot", "speed_m_s": 10.0})
    v = _vehicle(sc)
    lat, lon = sc.frame.to_wgs84(200.0, 0.0)
    lat2, lon2 = sc.frame.to_wgs84(0.0, 50.0)
    home = WireItem(0, 0, 16, 0, 1, 0, 0, 0, 0, 0, 0, 0.0)
    items = [home,
             WireItem(1, 3, 22, 0, 1, 0, 0, 0, math.nan, 0, 0, 40.0),  # take-off to 40 m
             WireItem(2, 3, 18, 0, 1, 2.0, 0, -60.0, 0, int(lat * 1e7), int(lon * 1e7), 40.0),  # 2 turns, CCW
             WireItem(3, 3, 16, 0, 1, 0, 0, 0, 0, int(lat2 * 1e7), int(lon2 * 1e7), 40.0),
             WireItem(4, 3, 20, 0, 1, 0, 0, 0, 0, 0, 0, 0.0)]
    samples, msgs = _fly(v, items, t_end_s=400.0)
    reached = {r.msg.seq: t for t, r in msgs if r.msg.get_type() == "MISSION_ITEM_REACHED"}
    assert {2, 3, 4} <= set(reached), reached
    on = samples[samples[:, 7] == 2]
    d = np.hypot(on[:, 1] - 200.0, on[:, 2])
    circling = on[np.abs(d - 60.0) < 1.0]
    speed = np.hypot(circling[:, 4], circling[:, 5])
    assert len(circling) and np.median(speed) == pytest.approx(7.9, abs=0.2)
    # two turns of a 60 m circle at 7.9 m/s: about 95 s on the circle
    assert (circling[-1, 0] - circling[0, 0]) == pytest.approx(2 * 2 * math.pi * 60.0 / 7.9, rel=0.05)
    # counter-clockwise (param3 < 0): the angle about the centre grows
    ang = np.unwrap(np.arctan2(circling[:, 2], circling[:, 1] - 200.0))
    assert ang[-1] - ang[0] == pytest.approx(4 * math.pi, rel=0.05)


def test_a_waypoint_followed_by_a_loiter_at_the_same_point_is_arrived_at_not_flown_past():
    """The daemon's scan mission ends with LOITER_TIME at the last waypoint. The fake took that
    waypoint as a pass-through with a zero-length next leg, at full speed, and flew 37 m past it
    (out of a geofence the plan kept 20 m inside); ArduCopter's S-curve stops at it."""
    from uavloc_gcs.mission import MissionItem, MissionPlan, change_speed, pass_through_waypoint, return_to_launch
    from uavloc_gcs.mission import takeoff

    sc = PAPER
    ll = sc.frame.to_wgs84_latlon(np.array([[0.0, 200.0], [300.0, 200.0]]))
    items = (takeoff(60.0, *sc.launch_latlon_deg), change_speed(15.0),
             pass_through_waypoint(*ll[0], 60.0), pass_through_waypoint(*ll[1], 60.0),
             MissionItem(19, params=(5.0, 0.0, 0.0, 0.0), lat_deg=float(ll[1][0]), lon_deg=float(ll[1][1]),
                         alt_m=60.0),
             return_to_launch())
    plan = MissionPlan(items, *sc.launch_latlon_deg, autopilot="ardupilot", cruise_speed_m_s=15.0, hover_speed_m_s=5.0)
    v = _vehicle(sc)
    samples, _msgs = _fly(v, to_wire(plan, "ardupilot"))
    assert samples[:, 1].max() < 300.0 + 3.0, samples[:, 1].max()  # no more than a few metres past it
    assert v.landed and np.linalg.norm(v.position_xyz_m[:2]) < 2.0


@pytest.mark.parametrize("ap", ["ardupilot", "px4"])
def test_landing_is_reported_as_each_autopilot_reports_it(ap):
    """Issue 42 item 1: after touching down the autopilot stays armed in landed state LANDING until
    its land detector is sure, says ON_GROUND still armed, then disarms by itself (measured on SITL,
    ``python -m tests.sitl.landing_measure``: ArduCopter ON_GROUND 1.7 s after touchdown and
    disarmed 0.7 s later; PX4 SIH 7 s and 2.2-2.7 s). The fake says the same in its telemetry."""
    sc = PAPER.replace(fleet={"autopilot": ap})
    v = _vehicle(sc)
    _fly(v, _wps(sc, [[40, 0]], ap, rtl=False), t_end_s=60.0)
    assert v.set_mode("RTL")
    seen = []  # (t, altitude, armed, landed state) from the vehicle's own messages
    state = {"armed": True, "landed": None, "alt": math.nan}
    t = v.t_s
    while t < 300.0 and (state["armed"] or not seen or seen[-1][0] < t - 2.0):
        t += 0.1
        for r in v.advance(t) + [v.heartbeat_reply(), Reply(v._extended_sys_state())]:
            m = r.msg
            if m.get_type() == "HEARTBEAT":
                state["armed"] = bool(m.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED)
            elif m.get_type() == "EXTENDED_SYS_STATE":
                state["landed"] = m.landed_state
            elif m.get_type() == "GLOBAL_POSITION_INT":
                state["alt"] = m.relative_alt / 1000.0
        seen.append((t, v.kin.pos[2], state["armed"], state["landed"]))
    down = next(s for s in seen if s[1] <= 0.0)
    on_ground = next(s for s in seen if s[3] == mav.MAV_LANDED_STATE_ON_GROUND)
    disarmed = next(s for s in seen if not s[2])
    low = [s for s in seen if 0.0 < s[1] < 1.5 and s[0] < down[0]]
    assert low and all(s[2] and s[3] == mav.MAV_LANDED_STATE_LANDING for s in low)  # armed, landing, low
    assert all(s[3] == mav.MAV_LANDED_STATE_LANDING and s[2] for s in seen if down[0] <= s[0] < on_ground[0])
    assert on_ground[0] - down[0] == pytest.approx(v.flavour.land_detect_s, abs=0.2)
    assert disarmed[0] - on_ground[0] == pytest.approx(v.flavour.disarm_after_landed_s, abs=0.2)
    assert v.landed and not v.armed and v.mode == "RTL"
