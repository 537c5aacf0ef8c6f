"""A DO_JUMP written in a .plan, read by mission_io, encoded for each autopilot and flown by the
fake vehicle: the jump lands on the waypoint the file names on both ArduPilot and PX4.

PX4 takes DO_JUMP param1 as the 0-based index of its mission (no home item); ArduPilot as the seq
with home at 0. QGroundControl subtracts one for PX4 when it drops home; so does
``uavloc_gcs.mission.to_wire``. Without that the jump would land one item late.
"""

import json

import numpy as np
import pytest

from mission_io import plan as plan_file
from uavloc_gcs import mission as M

from .test_vehicle_flight import PAPER, _fly, _vehicle


def _plan_text(sc) -> str:
    """A QGC-style .plan: takeoff, waypoints A and B, DO_JUMP back to A once, RTL (doJumpIds 10..50)."""
    a, b = sc.frame.to_wgs84_latlon(np.array([[0.0, 120.0], [120.0, 120.0]]))
    plan = M.MissionPlan((M.takeoff(30.0), M.pass_through_waypoint(*a, 30.0), M.pass_through_waypoint(*b, 30.0),
                          M.MissionItem(M.DO_JUMP, M.FRAME_MISSION, (2.0, 1.0, 0.0, 0.0)), M.return_to_launch()),
                         *sc.launch_latlon_deg, 400.0, autopilot=sc.fleet.autopilot)
    doc = json.loads(plan_file.dumps(plan))
    for k, item in enumerate(doc["mission"]["items"]):
        item["doJumpId"] = 10 * (k + 1)
    doc["mission"]["items"][3]["params"][0] = 20  # the doJumpId of waypoint A
    return json.dumps(doc)


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_a_plan_file_jump_lands_on_the_named_waypoint(autopilot):
    sc = PAPER.replace(fleet={"autopilot": autopilot})
    plan = plan_file.loads(_plan_text(sc), path="jump.plan")
    wire = M.to_wire(plan, autopilot)
    first = 1 if autopilot == "ardupilot" else 0
    seq_a, seq_b = first + 1, first + 2
    assert (wire[seq_a].command, wire[first + 3].command) == (M.NAV_WAYPOINT, M.DO_JUMP)
    _, msgs = _fly(_vehicle(sc), wire, t_end_s=300.0)
    reached = [r.msg.seq for _, r in msgs if r.msg.get_type() == "MISSION_ITEM_REACHED"]
    waypoints = [s for s in reached if s in (seq_a, seq_b)]
    assert waypoints == [seq_a, seq_b, seq_a, seq_b], reached  # A, B, then the jump back to A (once)


def test_px4_restarts_jump_counts_with_every_upload():
    """PX4 (``parse_mavlink_mission_item``) stores each uploaded DO_JUMP with its count at 0, so the
    same mission uploaded again jumps again."""
    from uavloc_gcs.dialect import mavlink as mav

    from .test_vehicle_flight import GCS

    sc = PAPER.replace(fleet={"autopilot": "px4"})
    wire = M.to_wire(plan_file.loads(_plan_text(sc)), "px4")
    v = _vehicle(sc)
    _fly(v, wire, t_end_s=300.0)
    assert v.executor.jumps_done  # the jump was used up
    srv = v.mission
    srv.handle(mav.MAVLink_mission_count_message(1, 1, len(wire), 0), GCS, v.t_s)
    for w in wire:
        srv.handle(mav.MAVLink_mission_item_int_message(1, 1, w.seq, w.frame, w.command, w.current, w.autocontinue,
                                                        w.param1, w.param2, w.param3, w.param4, w.x, w.y, w.z, 0),
                   GCS, v.t_s)
    assert len(v.mission_items) == len(wire) and not v.executor.jumps_done
