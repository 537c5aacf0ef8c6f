"""The vehicle side of the mission protocol, per flavour, driven message by message (no sockets)."""

from __future__ import annotations

import math

import pytest

from uavloc_gcs.dialect import mavlink as mav
from uavloc_gcs.mission import WireItem, flight_mission, to_wire
from sim_link.vehicles.flavour import ARDUPILOT, PX4
from sim_link.vehicles.mission_server import MissionServer, Peer

GCS = Peer(("127.0.0.1", 1), 255, 190)
OTHER = Peer(("127.0.0.1", 2), 254, 190)
HOME = WireItem(0, 0, 16, 0, 1, 0, 0, 0, 0, 426250000, 132830000, 0.0)


def _server(flavour):
    return MissionServer(flavour, 1, lambda: HOME)


def _plan(ap: str, n: int = 3):
    pts = [(42.626 + 0.001 * k, 13.284) for k in range(n)]
    return to_wire(flight_mission(pts, alt_m=100, speed_m_s=25, autopilot=ap, home_latlon_deg=(42.625, 13.283)))


def _item(w: WireItem, **kw):
    d = {**w.__dict__, **kw}
    return mav.MAVLink_mission_item_int_message(1, 1, d["seq"], d["frame"], d["command"], d["current"],
                                                d["autocontinue"], d["param1"], d["param2"], d["param3"],
                                                d["param4"], d["x"], d["y"], d["z"], 0)


def _types(replies):
    return [r.msg.get_type() for r in replies]


def _upload(srv, items, t=0.0, peer=GCS):
    out = srv.handle(mav.MAVLink_mission_count_message(1, 1, len(items), 0), peer, t)
    for w in items:
        out = srv.handle(_item(w), peer, t)
    return out


@pytest.mark.parametrize("flavour,request_type", [(ARDUPILOT, "MISSION_REQUEST"), (PX4, "MISSION_REQUEST_INT")])
def test_upload_request_style_and_ack(flavour, request_type):
    srv = _server(flavour)
    items = _plan(flavour.name)
    out = srv.handle(mav.MAVLink_mission_count_message(1, 1, len(items), 0), GCS, 0.0)
    assert _types(out) == [request_type] and out[0].msg.seq == 0 and out[0].to == GCS
    for w in items[:-1]:
        out = srv.handle(_item(w), GCS, 0.0)
        assert out[0].msg.seq == w.seq + 1
    out = srv.handle(_item(items[-1]), GCS, 0.0)
    assert _types(out) == ["MISSION_ACK"] and out[0].msg.type == mav.MAV_MISSION_ACCEPTED
    assert [w.command for w in srv.mission()] == [w.command for w in items]
    # the final ACK got lost: the GCS re-sends the last item and is ACKed again
    again = srv.handle(_item(items[-1]), GCS, 0.1)
    assert _types(again) == ["MISSION_ACK"] and again[0].msg.type == mav.MAV_MISSION_ACCEPTED


def test_ardupilot_nacks_out_of_sequence_and_keeps_going():
    srv = _server(ARDUPILOT)
    items = _plan("ardupilot")
    srv.handle(mav.MAVLink_mission_count_message(1, 1, len(items), 0), GCS, 0.0)
    srv.handle(_item(items[0]), GCS, 0.0)
    out = srv.handle(_item(items[0]), GCS, 0.0)  # duplicate of item 0 (our request 1 was lost)
    assert _types(out) == ["MISSION_ACK"] and out[0].msg.type == mav.MAV_MISSION_INVALID_SEQUENCE
    out = _upload_rest(srv, items, 1)
    assert out[0].msg.type == mav.MAV_MISSION_ACCEPTED


def _upload_rest(srv, items, start):
    out = []
    for w in items[start:]:
        out = srv.handle(_item(w), GCS, 0.0)
    return out


def test_px4_ignores_out_of_sequence_and_re_requests_on_its_timer():
    srv = _server(PX4)
    items = _plan("px4")
    srv.handle(mav.MAVLink_mission_count_message(1, 1, len(items), 0), GCS, 0.0)
    srv.handle(_item(items[0]), GCS, 0.0)
    assert srv.handle(_item(items[2]), GCS, 0.01) == []
    assert srv.tick(0.1) == []
    (r,) = srv.tick(0.26)  # 250 ms retry
    assert r.msg.get_type() == "MISSION_REQUEST_INT" and r.msg.seq == 1
    assert srv.tick(5.3) and srv.upload is None  # 5 s without items: gives up (STATUSTEXT)


def test_ardupilot_retry_interval_and_timeout_cancel():
    srv = _server(ARDUPILOT)
    srv.handle(mav.MAVLink_mission_count_message(1, 1, 3, 0), GCS, 0.0)
    assert srv.tick(0.5) == []
    assert _types(srv.tick(1.01)) == ["MISSION_REQUEST"]
    out = srv.tick(8.5)
    assert _types(out) == ["MISSION_ACK", "STATUSTEXT"]
    assert out[0].msg.type == mav.MAV_MISSION_OPERATION_CANCELLED
    assert out[1].msg.text == "Mission upload timeout"


def test_failed_upload_is_atomic_on_px4_but_not_on_ardupilot():
    for flavour, keeps_old in ((PX4, True), (ARDUPILOT, False)):
        srv = _server(flavour)
        old = _plan(flavour.name, 5)
        _upload(srv, old)
        new = _plan(flavour.name, 2)
        new = [WireItem(**{**w.__dict__, "z": 50.0}) for w in new]
        srv.handle(mav.MAVLink_mission_count_message(1, 1, len(new), 0), GCS, 0.0)
        srv.handle(_item(new[0]), GCS, 0.0)
        bad = WireItem(**{**new[1].__dict__, "command": 31999})  # unknown command
        out = srv.handle(_item(bad), GCS, 0.0)
        assert out[-1].msg.type == mav.MAV_MISSION_UNSUPPORTED and srv.upload is None
        stored = srv.mission()
        if keeps_old:
            assert len(stored) == len(old) and all(a.same_as(b) for a, b in zip(stored, old))
        else:  # truncated to the new count, first item replaced: a mix of old and new
            assert len(stored) == len(new) and stored[0].same_as(new[0]) and stored[1].same_as(old[1])


def test_px4_frame_rules():
    srv = _server(PX4)
    speed = _plan("px4")[1]
    assert speed.command == 178 and speed.frame == mav.MAV_FRAME_MISSION
    wp = _plan("px4")[2]
    cases = [
        ([WireItem(**{**speed.__dict__, "seq": 0, "frame": 3})], mav.MAV_MISSION_UNSUPPORTED),
        ([WireItem(**{**wp.__dict__, "seq": 0, "frame": 10})], mav.MAV_MISSION_UNSUPPORTED_FRAME),
        ([WireItem(**{**wp.__dict__, "seq": 0, "frame": 2})], mav.MAV_MISSION_UNSUPPORTED),
        ([WireItem(20, 3, 20, 0, 1, 0, 0, 0, 0, 0, 0, 0.0)], mav.MAV_MISSION_UNSUPPORTED),  # RTL frame 3
        # NAV_LOITER_TURNS: refused by PX4 SITL (docs/science/looks.md), so by the fake too
        ([WireItem(**{**wp.__dict__, "seq": 0, "command": 18, "param1": 2.0, "param3": 60.0})],
         mav.MAV_MISSION_UNSUPPORTED),
    ]
    for items, code in cases:
        items = [WireItem(**{**w.__dict__, "seq": 0}) for w in items]
        out = _upload(srv, items)
        assert out[-1].msg.type == code


def test_ardupilot_nan_and_range_rules():
    srv = _server(ARDUPILOT)
    home, takeoff, speed, wp = _plan("ardupilot")[:4]
    assert math.isnan(wp.param4) and math.isnan(takeoff.param4)  # NaN yaw is allowed there
    cases = [
        (WireItem(**{**speed.__dict__, "param4": math.nan}), mav.MAV_MISSION_INVALID_PARAM4),
        (WireItem(**{**wp.__dict__, "param1": math.nan}), mav.MAV_MISSION_INVALID_PARAM1),
        (WireItem(**{**wp.__dict__, "param2": math.inf}), mav.MAV_MISSION_INVALID_PARAM2),
        (WireItem(**{**wp.__dict__, "x": 910_000_000}), mav.MAV_MISSION_INVALID_PARAM5_X),
        (WireItem(**{**wp.__dict__, "y": -1_810_000_000}), mav.MAV_MISSION_INVALID_PARAM6_Y),
        (WireItem(**{**wp.__dict__, "z": math.nan}), mav.MAV_MISSION_INVALID_PARAM7),
        (WireItem(**{**wp.__dict__, "frame": 1}), mav.MAV_MISSION_UNSUPPORTED_FRAME),
    ]
    for bad, code in cases:
        out = _upload(srv, [home, WireItem(**{**bad.__dict__, "seq": 1})])
        assert out[-1].msg.type == code, (bad, code)
    ok = [WireItem(**{**w.__dict__, "seq": k}) for k, w in enumerate([home, takeoff, wp])]
    assert _upload(srv, ok)[-1].msg.type == mav.MAV_MISSION_ACCEPTED


@pytest.mark.parametrize("flavour", [ARDUPILOT, PX4])
def test_download_int_and_legacy(flavour):
    srv = _server(flavour)
    items = _plan(flavour.name)
    _upload(srv, items)
    (count,) = srv.handle(mav.MAVLink_mission_request_list_message(1, 1, 0), GCS, 0.0)
    assert count.msg.count == len(items)
    got = []
    for s in range(len(items)):
        (r,) = srv.handle(mav.MAVLink_mission_request_int_message(1, 1, s, 0), GCS, 0.0)
        got.append(r.msg)
    if flavour.home_is_item0:
        assert (got[0].x, got[0].y) == (HOME.x, HOME.y)
        got, items = got[1:], items[1:]
    for m, w in zip(got, items):
        assert m.get_type() == "MISSION_ITEM_INT" and m.command == w.command and (m.x, m.y) == (w.x, w.y)
    legacy = srv.handle(mav.MAVLink_mission_request_message(1, 1, len(items) - 1, 0), GCS, 0.0)
    assert legacy[-1].msg.get_type() == "MISSION_ITEM"
    assert ("STATUSTEXT" in _types(legacy)) == (flavour.name == "ardupilot")
    oob = srv.handle(mav.MAVLink_mission_request_int_message(1, 1, 99, 0), GCS, 0.0)
    assert oob[0].msg.get_type() == "MISSION_ACK" and oob[0].msg.type != mav.MAV_MISSION_ACCEPTED


def test_concurrent_uploads_and_downloads_are_refused():
    ap = _server(ARDUPILOT)
    ap.handle(mav.MAVLink_mission_count_message(1, 1, 3, 0), GCS, 0.0)
    (r,) = ap.handle(mav.MAVLink_mission_count_message(1, 1, 3, 0), OTHER, 0.0)
    assert r.msg.type == mav.MAV_MISSION_DENIED and r.to == OTHER
    (r,) = ap.handle(mav.MAVLink_mission_request_list_message(1, 1, 0), OTHER, 0.0)
    assert r.msg.type == mav.MAV_MISSION_DENIED
    px4 = _server(PX4)
    px4.handle(mav.MAVLink_mission_count_message(1, 1, 3, 0), GCS, 0.0)
    out = px4.handle(mav.MAVLink_mission_count_message(1, 1, 4, 0), OTHER, 0.0)
    assert out[0].msg.type == mav.MAV_MISSION_ERROR
    assert px4.handle(mav.MAVLink_mission_count_message(1, 1, 5000, 0), OTHER, 0.0)[0].msg.type == \
        mav.MAV_MISSION_ERROR
    assert _server(PX4).handle(mav.MAVLink_mission_count_message(1, 1, 5000, 0), GCS, 0.0)[0].msg.type == \
        mav.MAV_MISSION_NO_SPACE


def test_clear_and_count_zero():
    for flavour in (ARDUPILOT, PX4):
        srv = _server(flavour)
        _upload(srv, _plan(flavour.name))
        (r,) = srv.handle(mav.MAVLink_mission_clear_all_message(1, 1, 0), GCS, 0.0)
        assert r.msg.type == mav.MAV_MISSION_ACCEPTED and srv.mission() == []
        _upload(srv, _plan(flavour.name))
        (r,) = srv.handle(mav.MAVLink_mission_count_message(1, 1, 0, 0), GCS, 0.0)
        assert r.msg.type == mav.MAV_MISSION_ACCEPTED and srv.mission() == []


def test_messages_for_another_system_are_ignored():
    srv = _server(PX4)
    assert srv.handle(mav.MAVLink_mission_count_message(2, 1, 3, 0), GCS, 0.0) == []


def test_strict_px4_download_must_be_in_order_lenient_serves_any():
    from dataclasses import replace

    for flavour, strict in ((replace(PX4, strict_download_order=True), True), (PX4, False), (ARDUPILOT, False)):
        srv = _server(flavour)
        _upload(srv, _plan(flavour.name, 4))
        srv.handle(mav.MAVLink_mission_request_list_message(1, 1, 0), GCS, 0.0)
        (r,) = srv.handle(mav.MAVLink_mission_request_int_message(1, 1, 0, 0), GCS, 0.0)
        (r,) = srv.handle(mav.MAVLink_mission_request_int_message(1, 1, 0, 0), GCS, 0.0)  # a repeat is fine
        assert r.msg.get_type() == "MISSION_ITEM_INT"
        (r,) = srv.handle(mav.MAVLink_mission_request_int_message(1, 1, 3, 0), GCS, 0.0)  # skipping ahead
        if strict:
            assert r.msg.get_type() == "MISSION_ACK" and r.msg.type == mav.MAV_MISSION_ERROR
        else:
            assert r.msg.get_type() == "MISSION_ITEM_INT" and r.msg.seq == 3
