"""SlotBatch -> UAVLOC_RSSI_BATCH2 / UAVLOC_RSSI_BATCH -> bytes -> SlotBatch round trips."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from uavloc_gcs.dialect import mavlink
from uavloc_gcs.dialect.rssi import (
    BATCH, BATCH2, MAX_ENTRIES, RssiBatcher, decode_rssi_batch, decode_rssi_batches, encode_rssi_batches,
    is_rssi_message, join_address, split_address, wire_fingerprint,
)
from uavloc_gcs.geo import LocalFrame
from uavloc_gcs.observations import SlotBatch

FRAME = LocalFrame(42.625, 13.283)
EPOCH = 1_790_000_000.0


def _track(n_slots: int, emitters: int, *, v=(25.0, 0.0, 0.0), t0=12.0, rng=None) -> SlotBatch:
    rng = rng or np.random.default_rng(0)
    t = t0 + 0.025 * np.arange(n_slots)
    xyz = np.array([100.0, -50.0, 100.0]) + t[:, None] * np.array(v)
    rows_t = np.repeat(t, emitters)
    rows_xyz = np.repeat(xyz, emitters, axis=0)
    ids = np.tile(rng.integers(1, 2**32, size=emitters), n_slots)
    rssi = rng.uniform(-95, -60, size=len(rows_t))
    return SlotBatch.from_columns(rows_t, np.full(len(rows_t), 3), rows_xyz, ids, rssi,
                                  rng.integers(1, 11, size=len(rows_t)))


def _with(s: SlotBatch, *, address=None, fingerprint=None, channel=None) -> SlotBatch:
    address = s.address if address is None else address
    return SlotBatch.from_columns(s.t_s, s.vehicle, s.xyz_m, address, s.rssi_dbm, s.n_samples, address=address,
                                  fingerprint=s.fingerprint if fingerprint is None else fingerprint,
                                  channel=s.channel if channel is None else channel)


def _sensor(slots: SlotBatch, rng) -> SlotBatch:
    """The slots as a Wi-Fi sensor reports them: 48-bit addresses (the high and locally
    administered bits set among them), 32-bit fingerprints, channels."""
    n = len(slots)
    address = rng.integers(0, 2**48, size=n, dtype=np.int64)
    address[: min(n, 3)] = [0xFFFFFFFFFFFF, 0x020000000001, 0xDA0000000000][: min(n, 3)]
    fingerprint = rng.integers(0, 2**32, size=n, dtype=np.int64)
    fingerprint[: min(n, 2)] = [2**32 - 1, 0][: min(n, 2)]
    return _with(slots, address=address, fingerprint=fingerprint, channel=rng.choice([0, 1, 6, 11, 165], size=n))


def _wire(msgs, src_system=3):
    tx = mavlink.MAVLink(None, srcSystem=src_system, srcComponent=191)
    rx = mavlink.MAVLink(None)
    out = []
    for m in msgs:
        out.extend(rx.parse_buffer(m.pack(tx)) or [])
    return out


def _assert_same(a: SlotBatch, b: SlotBatch, *, pos_tol_m=0.03):
    a, b = a.sorted_by_time(), b.sorted_by_time()
    assert len(a) == len(b)
    np.testing.assert_allclose(b.t_s, a.t_s, atol=1e-6)
    np.testing.assert_allclose(b.xyz_m, a.xyz_m, atol=pos_tol_m)
    np.testing.assert_array_equal(b.emitter_id, a.emitter_id)
    np.testing.assert_allclose(b.rssi_dbm, a.rssi_dbm, atol=0.005 + 1e-9)
    np.testing.assert_array_equal(b.n_samples, a.n_samples)
    np.testing.assert_array_equal(b.vehicle, a.vehicle)
    np.testing.assert_array_equal(b.address, a.address)
    np.testing.assert_array_equal(b.fingerprint, a.fingerprint)
    np.testing.assert_array_equal(b.channel, a.channel)


def test_round_trip_through_bytes_straight_flight():
    slots = _track(40, 3)
    msgs = encode_rssi_batches(slots, FRAME, epoch_unix_s=EPOCH)
    assert all(1 <= m.count <= MAX_ENTRIES for m in msgs)
    assert len(msgs) == int(np.ceil(len(slots) / MAX_ENTRIES))  # 3 per slot: full messages
    back = decode_rssi_batches(_wire(msgs), FRAME, epoch_unix_s=EPOCH)
    _assert_same(slots, back)


def test_sensor_columns_round_trip_through_bytes_in_the_new_message():
    slots = _sensor(_track(40, 3), np.random.default_rng(4))
    msgs = encode_rssi_batches(slots, FRAME, epoch_unix_s=EPOCH)  # auto: the new message is needed
    assert {m.get_type() for m in msgs} == {BATCH2} and msgs[0].get_msgId() == 54101
    back = decode_rssi_batches(_wire(msgs), FRAME, epoch_unix_s=EPOCH)
    _assert_same(slots, back)  # address, fingerprint, channel, frame count included
    np.testing.assert_array_equal(back.sorted_by_time().emitter_id, slots.sorted_by_time().address)
    assert back.address.max() == 0xFFFFFFFFFFFF and back.fingerprint.max() == 2**32 - 1


def test_address_halves_and_fingerprint_width():
    hi, lo = split_address([0x123456789ABC, 0xFFFFFFFFFFFF, 0])
    assert hi.tolist() == [0x1234, 0xFFFF, 0] and lo.tolist() == [0x56789ABC, 0xFFFFFFFF, 0]
    assert join_address(hi, lo).tolist() == [0x123456789ABC, 0xFFFFFFFFFFFF, 0]
    # a wider hash (e.g. 62 bits) travels as its low 32 bits
    assert wire_fingerprint([0x3ABCDEF012345678, 7, 0, 2**40]).tolist() == [0x12345678, 7, 0, 1]
    s = _with(_track(1, 1), fingerprint=[0x3ABCDEF012345678])
    back = decode_rssi_batches(_wire(encode_rssi_batches(s, FRAME)), FRAME)
    assert back.fingerprint.tolist() == [0x12345678]


def test_paper_slots_travel_in_the_old_message_unless_the_new_one_is_asked_for():
    slots = _track(20, 2)  # address = emitter id (uint32), no fingerprint, no channel
    old = encode_rssi_batches(slots, FRAME, epoch_unix_s=EPOCH)
    new = encode_rssi_batches(slots, FRAME, epoch_unix_s=EPOCH, message=BATCH2)
    assert {m.get_type() for m in old} == {BATCH} and {m.get_type() for m in new} == {BATCH2}
    assert all(is_rssi_message(m) for m in _wire(old) + _wire(new))
    for msgs in (old, new):
        _assert_same(slots, decode_rssi_batches(_wire(msgs), FRAME, epoch_unix_s=EPOCH))
    # full messages: without sensor columns the new one's trailing zero extensions are trimmed on the
    # wire, so it costs what the old one costs; with them, 209 bytes of payload
    tx = mavlink.MAVLink(None, srcSystem=3, srcComponent=191)
    assert len(new[0].pack(tx)) == len(old[0].pack(tx)) == 125 + 12
    full = encode_rssi_batches(_sensor(slots, np.random.default_rng(1)), FRAME, message=BATCH2)
    assert all(f.fingerprint[-1] and f.count == 12 for f in full[:1])
    assert len(full[0].pack(tx)) == 209 + 12


def test_old_message_from_an_old_companion_decodes_with_address_equal_to_emitter_id():
    tx = mavlink.MAVLink(None, srcSystem=2, srcComponent=191)
    raw = tx.uavloc_rssi_batch_encode(int(EPOCH * 1e6) + 5_000_000, 426250000, 132830000, 100_000, 2500, 0, 0,
                                      25000, 2, [0, 25] + [0] * 10, [4_000_000_000, 17] + [0] * 10,
                                      [-7512, -8000] + [0] * 10, [10, 3] + [0] * 10).pack(tx)
    (msg,) = mavlink.MAVLink(None).parse_buffer(raw)
    b = decode_rssi_batch(msg, FRAME, epoch_unix_s=EPOCH)
    assert b.emitter_id.tolist() == [4_000_000_000, 17] and b.address.tolist() == [4_000_000_000, 17]
    assert b.fingerprint.tolist() == [0, 0] and b.channel.tolist() == [0, 0]
    assert b.rssi_dbm.tolist() == [-75.12, -80.0] and b.n_samples.tolist() == [10, 3]
    np.testing.assert_allclose(b.t_s, [5.0, 5.025])
    assert b.vehicle.tolist() == [2, 2]
    with pytest.raises(ValueError, match="not an RSSI message"):
        decode_rssi_batch(mavlink.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3), FRAME)


def test_window_limits_the_span_of_a_message():
    slots = _track(30, 1)  # one emitter: 12 entries would span 275 ms > 200 ms
    msgs = encode_rssi_batches(slots, FRAME, epoch_unix_s=EPOCH, window_s=0.2)
    assert all(max(m.dt_ms[: m.count]) <= 200 for m in msgs)
    assert [m.count for m in msgs][:3] == [9, 9, 9]


def test_several_vehicles_are_refused_and_out_of_range_values_named():
    s = _track(2, 1)
    two = SlotBatch.from_columns(s.t_s, [1, 2], s.xyz_m, s.emitter_id, s.rssi_dbm, s.n_samples)
    with pytest.raises(ValueError, match="several vehicles"):
        encode_rssi_batches(two, FRAME)
    big = SlotBatch.from_columns(s.t_s, s.vehicle, s.xyz_m, [2**33, 1], s.rssi_dbm, s.n_samples)
    with pytest.raises(ValueError, match="emitter_id"):
        encode_rssi_batches(big, FRAME, message=BATCH)
    (m,) = encode_rssi_batches(big, FRAME)  # auto: the old message cannot carry it, the new one can
    assert m.get_type() == BATCH2
    with pytest.raises(ValueError, match="address must fit 48 bits"):
        encode_rssi_batches(_with(s, address=[2**48, 1]), FRAME)
    with pytest.raises(ValueError, match="channel"):
        encode_rssi_batches(_with(s, channel=[256, 1]), FRAME)
    with pytest.raises(ValueError, match="message must be one of"):
        encode_rssi_batches(s, FRAME, message="UAVLOC_RSSI")


def test_count_is_honoured_and_clipped():
    msgs = encode_rssi_batches(_track(2, 1), FRAME)
    (m,) = msgs
    assert m.count == 2
    assert len(decode_rssi_batch(m, FRAME, vehicle=9)) == 2
    m.count = 200  # a broken sender: at most 12 entries are read
    assert len(decode_rssi_batch(m, FRAME, vehicle=9)) == MAX_ENTRIES


def test_turning_vehicle_positions_within_a_few_cm():
    # 25 m/s on a circle with 5 m/s^2 centripetal acceleration (radius 125 m)
    t = 0.025 * np.arange(80)
    ang = 25.0 / 125.0 * t
    xyz = np.column_stack([125 * np.sin(ang), 125 * (1 - np.cos(ang)), np.full_like(t, 100.0)])
    slots = SlotBatch.from_columns(t, np.ones(len(t)), xyz, np.full(len(t), 7), np.full(len(t), -80.0),
                                   np.full(len(t), 10))
    back = decode_rssi_batches(_wire(encode_rssi_batches(slots, FRAME), src_system=1), FRAME)
    _assert_same(slots, back, pos_tol_m=0.05)


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(1, 60), emitters=st.integers(1, 4),
    vx=st.floats(-30, 30), vy=st.floats(-30, 30), vz=st.floats(-3, 3),
    t0=st.floats(0, 20000), seed=st.integers(0, 2**31),
)
def test_round_trip_property(n, emitters, vx, vy, vz, t0, seed):
    t0 = round(t0 * 40) / 40  # slot starts on the 25 ms grid, as the simulator and companions use
    slots = _track(n, emitters, v=(vx, vy, vz), t0=t0, rng=np.random.default_rng(seed))
    if seed % 2:
        slots = _sensor(slots, np.random.default_rng(seed))
    back = decode_rssi_batches(_wire(encode_rssi_batches(slots, FRAME, epoch_unix_s=EPOCH)), FRAME,
                               epoch_unix_s=EPOCH)
    _assert_same(slots, back)


def test_batcher_streams_the_same_entries_as_one_shot_encoding():
    slots = _track(100, 2)
    batcher = RssiBatcher(FRAME, epoch_unix_s=EPOCH)
    msgs = []
    for i in range(0, len(slots), 6):  # slots arrive a few at a time
        chunk = slots.take(np.arange(i, min(i + 6, len(slots))))
        msgs += batcher.add(chunk)
        msgs += batcher.flush(now_s=float(chunk.t_s[-1]))
    msgs += batcher.flush(force=True)
    assert all(m.count <= MAX_ENTRIES for m in msgs)
    _assert_same(slots, decode_rssi_batches(_wire(msgs), FRAME, epoch_unix_s=EPOCH))
    # Batching keeps messages nearly full: 2 emitters x 40 slots/s, 12 per message
    assert np.mean([m.count for m in msgs]) > 10


def test_batcher_sends_the_new_message_when_asked():
    slots = _track(30, 2)
    batcher = RssiBatcher(FRAME, epoch_unix_s=EPOCH, message=BATCH2)
    msgs = batcher.add(slots) + batcher.flush(force=True)
    assert {m.get_type() for m in msgs} == {BATCH2}
    _assert_same(slots, decode_rssi_batches(_wire(msgs), FRAME, epoch_unix_s=EPOCH))
    with pytest.raises(ValueError, match="message must be one of"):
        RssiBatcher(FRAME, message="v3")


def test_a_quiet_receiver_says_so_once_a_second_and_never_ahead_of_what_it_holds():
    """Keepalives (count 0): the ground tells "heard nothing" from "not heard from yet" (issue 42)."""
    from uavloc_gcs.dialect.rssi import KEEPALIVE_S, message_time_s

    slots = _track(8, 1, t0=0.05)  # 8 slots from 0.05 s
    batcher = RssiBatcher(FRAME, epoch_unix_s=EPOCH)
    out = batcher.add(slots)
    first = batcher.flush(now_s=0.1)  # an entry is pending (window open): the keepalive stops at it
    assert len(first) == 1 and first[0].count == 0
    assert message_time_s(first[0], epoch_unix_s=EPOCH) == pytest.approx(float(slots.t_s[0]))
    out += batcher.flush(now_s=0.5)  # the window has closed: the batch goes, no keepalive with it
    assert out and all(m.count > 0 for m in out)
    quiet = []
    for t in np.arange(0.6, 5.0, 0.05):  # nothing heard for 4.4 s
        quiet += batcher.flush(now_s=float(t))
    assert all(m.count == 0 for m in quiet)
    times = [message_time_s(m, epoch_unix_s=EPOCH) for m in quiet]
    assert len(quiet) == 4 and np.all(np.diff(times) >= KEEPALIVE_S - 0.05 - 1e-9)
    assert len(decode_rssi_batches(_wire(quiet), FRAME, epoch_unix_s=EPOCH)) == 0
    silent = RssiBatcher(FRAME, epoch_unix_s=EPOCH, keepalive_s=None)  # a receiver that predates them
    assert silent.flush(now_s=10.0) == []
