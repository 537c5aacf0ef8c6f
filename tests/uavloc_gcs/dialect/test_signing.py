"""A packet without the key must not change the replay state of a genuine stream.

pymavlink's generated check records the stream timestamp before it compares the signature, so
one forged packet with a future timestamp locks the real vehicle out; ours checks first.
"""

import time

import pytest

from uavloc_gcs.dialect import mavlink as M
from uavloc_gcs.dialect.signing import verify_signature_first

KEY = bytes(range(32))
OTHER = bytes(32 * [7])


def _codec(key, ts):
    c = M.MAVLink(None, 1, 1)
    c.signing.secret_key = key
    c.signing.sign_outgoing = True
    c.signing.timestamp = ts
    return c


def _hb(c):
    return c.heartbeat_encode(M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_PX4, 0, 0, 0).pack(c)


def _receiver(hardened: bool):
    rx = M.MAVLink(None, 255, 190)
    rx.robust_parsing = True
    rx.signing.secret_key = KEY
    rx.signing.timestamp = int((time.time() - 1420070400) * 1e5)
    return verify_signature_first(rx) if hardened else rx


def _accepted(rx, packets):
    return [m for p in packets for m in (rx.parse_buffer(p) or []) if not isinstance(m, M.MAVLink_bad_data)]


@pytest.mark.parametrize("hardened, genuine_after_forgery", [(True, 2), (False, 0)])
def test_forged_future_timestamp_cannot_lock_out_a_vehicle(hardened, genuine_after_forgery):
    now = int((time.time() - 1420070400) * 1e5)
    vehicle, forger = _codec(KEY, now), _codec(OTHER, now + 10**9)  # forger claims a later time
    rx = _receiver(hardened)
    assert len(_accepted(rx, [_hb(vehicle)])) == 1
    assert _accepted(rx, [_hb(forger)]) == []
    # the unpatched pymavlink check shows the weakness this module exists for
    assert len(_accepted(rx, [_hb(vehicle), _hb(vehicle)])) == genuine_after_forgery


def test_replays_and_stale_new_streams_are_still_refused():
    now = int((time.time() - 1420070400) * 1e5)
    rx = _receiver(True)
    vehicle = _codec(KEY, now)
    packet = _hb(vehicle)
    assert len(_accepted(rx, [packet, packet])) == 1  # the replay is dropped
    old = _codec(KEY, now - 2 * 6_000_000)
    old.srcComponent = 2  # a new stream from two minutes ago
    assert _accepted(rx, [_hb(old)]) == []
