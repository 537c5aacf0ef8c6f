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
            if types is None or msg.get_type() in ((types,) if isinstance(types, str) else types):
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


def test_a_vehicle_the_autopilot_says_landed_and_disarmed_is_on_the_ground_at_any_altitude():
    """Measured on PX4 SITL: landed ("Disarmed by landing"), EXTENDED_SYS_STATE on ground, but a
    relative altitude of 2.2 m from a drifted height estimate; the altitude rule alone kept it
    airborne and the search ended "returning home, not landed yet"."""
    link, clock = _Link(), [100.0]
    a = _agent(link, clock)
    disarmed = mav.MAVLink_heartbeat_message(2, 12, 29, 67371008, 3, 3)  # the last heartbeat measured
    link.feed(disarmed)
    link.feed(mav.MAVLink_global_position_int_message(374304, 426250008, 132829885, 899947, 2201, 2, -2, 3, 35594))
    assert not a.on_ground()  # 2.2 m, and the autopilot has not said where it is
    link.feed(mav.MAVLink_extended_sys_state_message(0, mav.MAV_LANDED_STATE_IN_AIR))
    assert not a.on_ground()
    link.feed(mav.MAVLink_extended_sys_state_message(0, mav.MAV_LANDED_STATE_ON_GROUND))
    assert a.on_ground()
    armed = mav.MAVLink_heartbeat_message(2, 12, 29 | 128, 67371008, 4, 3)
    link.feed(armed)
    link.feed(mav.MAVLink_global_position_int_message(374404, 426250008, 132829885, 899947, 2201, 800, 0, 3, 0))
    assert not a.on_ground()  # armed and moving: the altitude rule decides, as before


def _ap_heartbeat(armed: bool, custom_mode: int = 6):  # ArduCopter, RTL
    return mav.MAVLink_heartbeat_message(2, 3, 89 | (128 if armed else 0), custom_mode, 4 if armed else 3, 3)


def test_landed_is_only_what_the_vehicle_says_disarmed_and_on_the_ground():
    """Issue 42 item 1, as measured on ArduCopter SITL (tests/sitl/landing_measure.py): armed in RTL,
    landed state LANDING, 1.48 m up, sinking at 0.5 m/s, not moving over ground -- the height-and-
    speed rule said "on the ground" 5.4 s before the vehicle touched down and disarmed. Landed is
    the vehicle's own word only: disarmed, and ON_GROUND where it sends a landed state."""
    link, clock = _Link(), [100.0]
    a = _agent(link, clock)
    assert not a.landed()  # nothing heard: nothing said
    link.feed(_ap_heartbeat(armed=True))
    link.feed(mav.MAVLink_global_position_int_message(110700, 426250000, 132830000, 901480, 1480, 0, 0, 49, 0))
    link.feed(mav.MAVLink_extended_sys_state_message(0, mav.MAV_LANDED_STATE_LANDING))
    assert a.on_ground()  # what a start decides by: low and slow may be the ground
    assert not a.landed()  # ... but it is armed and landing
    link.feed(mav.MAVLink_extended_sys_state_message(0, mav.MAV_LANDED_STATE_ON_GROUND))
    assert not a.landed()  # down, still armed (0.7 s on ArduCopter, 2-3 s on PX4)
    link.feed(_ap_heartbeat(armed=False))
    assert a.landed()
    link.feed(mav.MAVLink_extended_sys_state_message(0, mav.MAV_LANDED_STATE_IN_AIR))
    assert not a.landed()  # disarmed but not on the ground by its own word: not landed


def test_without_a_landed_state_disarmed_is_landed_at_any_height():
    """An autopilot that sends no EXTENDED_SYS_STATE: its HEARTBEAT's disarmed is the word."""
    link, clock = _Link(), [100.0]
    a = _agent(link, clock)
    link.feed(_ap_heartbeat(armed=True))
    link.feed(mav.MAVLink_global_position_int_message(1000, 426250000, 132830000, 900300, 300, 0, 0, 10, 0))
    assert not a.landed()
    link.feed(_ap_heartbeat(armed=False))
    assert a.landed()


def test_rssi_of_both_message_versions_arrives_with_its_sensor_columns_on_either_path():
    """UAVLOC_RSSI_BATCH2 (address, fingerprint, channel) and the old UAVLOC_RSSI_BATCH, through
    the autopilot's link and on a connection beside it."""
    import numpy as np

    from uavloc_gcs.dialect.rssi import BATCH, BATCH2, encode_rssi_batches
    from uavloc_gcs.observations import SlotBatch

    frame = LocalFrame(42.625, 13.283)
    link, beside, got = _Link(), _Link(), []
    a = VehicleAgent(1, link, frame, autopilot="px4", epoch_unix_s=lambda: 1.8e9, on_slots=got.append,
                     wall=lambda: 0.0)
    a.attach_rssi(beside)
    address = np.array([0xDA0102030405, 0xFFFFFFFFFFFF])
    sensor = SlotBatch.from_columns([1.0, 1.025], [1, 1], [[0, 0, 100], [0.5, 0, 100]], address, [-70.0, -80.0],
                                    [3, 1], address=address, fingerprint=[0xDEADBEEF, 5], channel=[6, 11])
    tx = mav.MAVLink(None, srcSystem=1, srcComponent=191)
    rx = mav.MAVLink(None)
    for path, kind in ((link, BATCH2), (beside, BATCH2), (link, BATCH)):
        slots = sensor if kind == BATCH2 else SlotBatch.from_columns([2.0], [1], [[0, 0, 100]], [7], [-75.0], [10])
        for m in encode_rssi_batches(slots, frame, epoch_unix_s=1.8e9, message=kind):
            (msg,) = rx.parse_buffer(m.pack(tx))
            path.feed(msg)
    assert a.rssi_messages == 3 and len(got) == 3
    for b in got[:2]:
        assert b.address.tolist() == address.tolist() and b.emitter_id.tolist() == address.tolist()
        assert b.fingerprint.tolist() == [0xDEADBEEF, 5] and b.channel.tolist() == [6, 11]
        assert b.n_samples.tolist() == [3, 1]
    assert got[2].address.tolist() == [7] and got[2].fingerprint.tolist() == [0] and got[2].channel.tolist() == [0]


def test_a_reboot_never_takes_the_mission_clock_back():
    """A battery swap reboots the autopilot: its boot clock starts again. Positions after it must
    not be dated by the old anchor (the fake PX4's mission clock went from 192 s back to 26 s after
    a swap); the next SYSTEM_TIME anchors the clock again."""
    link, clock = _Link(), [100.0]
    a = _agent(link, clock)
    link.feed(mav.MAVLink_system_time_message(1_800_000_000_000_000, 5_000))
    link.feed(mav.MAVLink_global_position_int_message(195_000, 0, 0, 0, 0, 0, 0, 0, 0))
    assert a.tel.unix_s == 1_800_000_190.0
    clock[0] = 130.0  # the swap, then the rebooted autopilot's first position
    link.feed(mav.MAVLink_global_position_int_message(2_000, 0, 0, 0, 0, 0, 0, 0, 0))
    assert a.tel.unix_s == 1_800_000_190.0  # not 1_799_999_997: on from the last reading
    link.feed(mav.MAVLink_global_position_int_message(4_500, 0, 0, 0, 0, 0, 0, 0, 0))
    assert a.tel.unix_s == 1_800_000_192.5  # with the new boot clock
    link.feed(mav.MAVLink_system_time_message(1_800_000_230_000_000, 8_000))
    assert a.tel.unix_s == 1_800_000_230.0
    link.feed(mav.MAVLink_global_position_int_message(9_000, 0, 0, 0, 0, 0, 0, 0, 0))
    assert a.tel.unix_s == 1_800_000_231.0
    link.feed(mav.MAVLink_global_position_int_message(8_800, 0, 0, 0, 0, 0, 0, 0, 0))  # reordered, not a reboot
    assert a.tel.unix_s == 1_800_000_230.8
