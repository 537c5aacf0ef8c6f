"""The vehicle's state machine (service/vehiclelife.py) on facts alone: each step reads the facts
it is given, and the moves are the table's."""

import math

from uavloc_gcs.service.vehiclelife import NEXT, STATES, Facts, VehicleLife, allowed


def _facts(**kw) -> Facts:
    base = dict(armed=False, on_ground=True, mode="STABILIZE", in_mission_mode=False, mission_seq=None,
                mission_state=None, mission_ours=True, rel_alt_m=0.0, ground_speed_m_s=0.0, silent_s=0.0)
    base.update(kw)
    base.setdefault("landed", not base["armed"] and base["on_ground"])
    return Facts(**base)


def _scanning() -> VehicleLife:
    v = VehicleLife(1, "udpout:x:1")
    v.phase = "connected"
    v.phase = "uploading scan"
    v.phase = "starting"
    v.purpose, v.hold_seq, v.end_seq = "scan", 10, 11
    return v


def _home_by(_v) -> float:
    return 100.0


def test_every_move_leads_to_a_state():
    assert all(new in STATES for moves in NEXT.values() for new in moves)
    assert allowed("landed", "starting") and not allowed("scanning", "starting")


def test_a_refused_start_never_finishes_its_scan():
    """'Auto: Missing Takeoff Cmd': AUTO refused, the vehicle on the ground with a stale item at the
    scan's end from the last search; never seen airborne, so never 'finished its scan'."""
    v = _scanning()
    for _ in range(3):
        events = v.observe(_facts(armed=True, mode="AUTO", in_mission_mode=True, mission_seq=10), 0.0, 5.0, _home_by)
        assert not any(k == "scan" for k, _ in events)
    assert not v.scan_done and v.phase == "starting"


def test_a_scan_flown_to_its_hold_is_done():
    v = _scanning()
    v.observe(_facts(armed=True, on_ground=False, mode="AUTO", in_mission_mode=True, mission_seq=4, rel_alt_m=60.0),
              0.0, 5.0, _home_by)
    assert v.phase == "scanning" and v.flew
    events = v.observe(_facts(armed=True, on_ground=False, mode="AUTO", in_mission_mode=True, mission_seq=10,
                              rel_alt_m=60.0), 0.0, 5.0, _home_by)
    assert ("scan", "vehicle 1 finished its scan") in events and v.scan_done and not v.landed_mid_scan


def test_landing_by_itself_mid_scan_is_said_and_kept():
    v = _scanning()
    v.observe(_facts(armed=True, on_ground=False, mode="AUTO", in_mission_mode=True, mission_seq=6, rel_alt_m=60.0),
              0.0, 5.0, _home_by)
    events = v.observe(_facts(armed=False, on_ground=True, mode="RTL", mission_seq=6), 0.0, 5.0, _home_by)
    assert v.landed_mid_scan and v.scan_reached_seq == 6
    assert any("landed by itself during its scan, at item 6 of 10" in text for _k, text in events), events
    assert v.phase == "landed" and v.home and v.odd_moves == []


def test_silence_marks_lost_and_freezes_the_phase():
    v = _scanning()
    events = v.observe(_facts(silent_s=6.0), 0.0, 5.0, _home_by)
    assert v.lost and events[0][0] == "lost" and v.phase == "starting"
    events = v.observe(_facts(silent_s=0.1), 0.0, 5.0, _home_by)
    assert not v.lost and events[0][0] == "found"
    assert math.isinf(VehicleLife(2, "c").home_by_s)


def test_a_sortie_ends_at_its_landing_and_a_vehicle_silent_for_its_swap_is_not_lost():
    """Issue 38: a sortie with more to come ends in RTL; its landing is its end (not a scan cut
    short), and a vehicle waiting for its pack, powered off by the swap, is not marked lost."""
    v = _scanning()
    v.sorties = [["sortie 2"]]
    air = dict(armed=True, on_ground=False, mode="AUTO", in_mission_mode=True, rel_alt_m=60.0)
    v.observe(_facts(mission_seq=4, **air), 0.0, 5.0, _home_by)
    v.observe(_facts(mission_seq=11, mission_state=5, **air), 0.0, 5.0, _home_by)  # its RTL: not "scan done"
    assert v.phase == "scanning" and not v.scan_done
    events = v.observe(_facts(mission_seq=11, mode="AUTO.RTL"), 0.0, 5.0, _home_by)
    assert ("landed", "vehicle 1 landed after sortie 1 of its scan") in events
    assert v.phase == "landed" and v.home and not v.scan_done and not v.landed_mid_scan
    v.phase = "waiting for pack"
    assert v.observe(_facts(silent_s=60.0), 0.0, 5.0, _home_by) == [] and not v.lost
    assert v.odd_moves == []
    v.phase = "landed"
    assert v.observe(_facts(silent_s=60.0), 0.0, 5.0, _home_by)[0][0] == "lost"  # landed, not waiting: lost


def _returning() -> VehicleLife:
    v = _scanning()
    v.observe(_facts(armed=True, on_ground=False, mode="AUTO", in_mission_mode=True, mission_seq=4, rel_alt_m=40.0),
              0.0, 5.0, _home_by)
    v.returning(100.0)
    return v


def test_armed_and_landing_low_and_slow_is_not_landed():
    """Issue 42 item 1 (ArduCopter SITL): the statement "All vehicles are home" came while a vehicle
    was armed in LANDING 1.2-1.4 m up, sinking at 0.5 m/s. Only the vehicle's own "disarmed" (and
    ON_GROUND where it says it) makes it landed."""
    v = _returning()
    for alt in (1.4, 1.2, 0.6, 0.0):  # low, slow, armed: the old rule said "on the ground" here
        events = v.observe(_facts(armed=True, on_ground=True, landed=False, mode="RTL", rel_alt_m=alt), 0.0, 5.0,
                           _home_by)
        assert events == [] and not v.home and v.phase == "returning", (alt, events)
    events = v.observe(_facts(armed=False, on_ground=True, landed=True, mode="RTL", rel_alt_m=0.0), 0.0, 5.0, _home_by)
    assert [k for k, _ in events] == ["landed"] and v.home and v.phase == "landed"
    assert "disarmed" in events[0][1]


def test_px4_on_the_ground_armed_does_not_flip_landed_and_airborne():
    """Issue 42 item 1 (PX4): "landed" -> "airborne again in AUTO.RTL" -> "landed" within two seconds.
    Measured on PX4 SIH (tests/sitl/landing_measure.py): for 10 s after touching down, armed, its
    height wanders between -1.2 and +1.2 m at a few dm/s. One "landed", once it is disarmed."""
    v = _returning()
    said = []
    for k, alt in enumerate([1.47, 0.57, -1.07, 1.18, -0.67, 0.58, 1.6, -0.86, 0.77, 0.03]):
        f = _facts(armed=True, on_ground=abs(alt) < 1.5, landed=False, mode="AUTO.RTL", rel_alt_m=alt,
                   ground_speed_m_s=0.3 if k % 2 else 0.6)
        said += v.observe(f, 0.0, 5.0, _home_by)
    said += v.observe(_facts(armed=False, landed=True, mode="AUTO.RTL", rel_alt_m=0.0), 0.0, 5.0, _home_by)
    assert [k for k, _ in said] == ["landed"], said
    assert v.home and v.odd_moves == []
