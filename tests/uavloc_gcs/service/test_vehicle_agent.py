"""VehicleAgent: which mission state it believes, and RSSI from a connection beside the autopilot."""

from uavloc_gcs.dialect import mavlink as mav
from uavloc_gcs.geo import LocalFrame
from uavloc_gcs.service.vehicle import VehicleAgent


class _Link:
    """Only what VehicleAgent needs of a link: subscriptions (callbacks called by the test)."""

    def __init__(self):
        self.callbacks = []

    def subscribe(self, types, *, source_system, callback):
        self.callbacks.append((types, source_system, callback))
        return self

    def close(self):
        pass

    def feed(self, msg):
        for types, _, cb in self.callbacks:
            if types is None or msg.get_type() == types:
                cb(msg)


def _agent(link, clock):
    return VehicleAgent(1, link, LocalFrame(42.625, 13.283), autopilot="px4", epoch_unix_s=lambda: 0.0,
                        wall=lambda: clock[0])


def _current(seq, state):
    return mav.MAVLink_mission_current_message(seq, 20, state, 0)


def test_a_stale_mission_complete_is_ignored_until_our_mission_has_started():
    """Reproduces PX4's stale state: a vehicle that finished a mission before keeps reporting
    COMPLETE after our upload, which ended the search the moment the scan started."""
    link, clock = _Link(), [100.0]
    a = _agent(link, clock)
    link.feed(_current(12, mav.MISSION_STATE_COMPLETE))
    assert a.tel.mission_ours  # nothing uploaded by us yet: nothing to judge
    a.tel.mission_ours = False  # what upload() does once the vehicle acknowledged our mission
    a._acked_wall_s = 100.0
    for k in range(5):
        clock[0] = 100.5 + k
        link.feed(_current(12, mav.MISSION_STATE_COMPLETE))
        assert not a.tel.mission_ours
    link.feed(_current(0, mav.MISSION_STATE_ACTIVE))  # our mission started
    assert a.tel.mission_ours and a.tel.mission_seq == 0
    link.feed(_current(9, mav.MISSION_STATE_COMPLETE))  # now a COMPLETE is ours
    assert a.tel.mission_ours and a.tel.mission_state == mav.MISSION_STATE_COMPLETE


def test_a_vehicle_without_mission_states_is_believed_a_second_after_the_ack():
    link, clock = _Link(), [100.0]
    a = _agent(link, clock)
    a.tel.mission_ours, a._acked_wall_s = False, 100.0
    link.feed(_current(3, mav.MISSION_STATE_UNKNOWN))
    assert not a.tel.mission_ours
    clock[0] = 101.2
    link.feed(_current(3, mav.MISSION_STATE_UNKNOWN))
    assert a.tel.mission_ours


def test_the_mission_clock_follows_the_vehicles_boot_clock_from_one_anchor():
    """PX4 SIH at a 5x speed-up: time_unix_usec advances at the host's rate (10.2 s) while its boot
    clock advances 49 s (measured); the mission clock must run with the flight, not the host."""
    link, clock = _Link(), [100.0]
    a = _agent(link, clock)
    link.feed(mav.MAVLink_system_time_message(1_800_000_000_000_000, 20_000))
    assert a.tel.unix_s == 1_800_000_000.0
    clock[0] = 110.2
    link.feed(mav.MAVLink_system_time_message(1_800_000_010_200_000, 69_000))
    assert a.tel.unix_s == 1_800_000_049.0 and a.tel.unix_wall_s == 110.2
    link.feed(mav.MAVLink_global_position_int_message(69_500, 0, 0, 0, 0, 0, 0, 0, 0))
    assert a.tel.unix_s == 1_800_000_049.5  # positions carry the boot clock too
