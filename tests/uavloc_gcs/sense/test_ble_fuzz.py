"""Fuzzed and truncated Bluetooth LE captures: counts, never a traceback (as test_fuzz.py for Wi-Fi)."""

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from uavloc_gcs.sense import parse_capture_bytes
from uavloc_gcs.sense.ble import BLE_LINKTYPES

from .ble_captures import capture

KINDS = ("phdr", "nordic", "hci", "hci_ext", "btsnoop")
_BASES = {k: capture(k, 30, n_adv=7, seed=11)[0] for k in KINDS}
_HEAD = {"btsnoop": 16}  # pcap: 24


def _check(buf: bytes):
    frames, skips = parse_capture_bytes(buf)
    # every record read gives frames or one counted reason (an HCI event may carry several reports)
    used_or_counted = sum(skips.reasons.values())
    assert len(frames) + used_or_counted >= skips.read.records
    assert used_or_counted <= skips.read.records
    assert np.all((frames.rssi_dbm >= -120) & (frames.rssi_dbm <= 10))
    assert np.all(frames.address >= 0) and np.all(frames.address < 2**48)
    assert np.all((frames.channel >= 0) & (frames.channel <= 39))
    return frames, skips


def test_unmutated_bases_parse_whole():
    for kind, buf in _BASES.items():
        frames, skips = _check(buf)
        assert len(frames) == 30 and skips.malformed == 0, kind


mutation = st.lists(st.tuples(st.integers(0, 10**7), st.integers(0, 255)), min_size=1, max_size=40)


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(kind=st.sampled_from(KINDS), flips=mutation, cut=st.integers(0, 10**7))
def test_flipped_and_truncated_bytes_never_raise(kind, flips, cut):
    buf = bytearray(_BASES[kind])
    head = _HEAD.get(kind, 24)  # keep the magic and the link type: the rest is fair game
    for pos, val in flips:
        buf[head + pos % (len(buf) - head)] = val
    _check(bytes(buf[:head + cut % (len(buf) - head + 1)]))


@settings(max_examples=300, deadline=None)
@given(body=st.binary(max_size=300), linktype=st.sampled_from(sorted(BLE_LINKTYPES)))
def test_random_records_never_raise(body, linktype):
    from uavloc_gcs.sense.synth import pcap_bytes

    _check(pcap_bytes([(1.0, body), (2.0, body[::-1])], linktype=linktype))


@settings(max_examples=150, deadline=None)
@given(tail=st.binary(max_size=400))
def test_random_bytes_after_a_btsnoop_header_never_raise(tail):
    _check(_BASES["btsnoop"][:16] + tail)


def test_every_record_snapped_anywhere_never_raises():
    """Each record of each base cut at every length, marked as snapped (captured < original)."""
    from uavloc_gcs.sense.capture import ReadStats, read_records
    from uavloc_gcs.sense.frames import SkipCounts, parse_records

    for kind in ("phdr", "nordic", "hci", "hci_ext"):
        for lt, t, data, _ in list(read_records(_BASES[kind], ReadStats()))[:7]:
            skips = SkipCounts()
            frames = parse_records([(lt, t, data[:k], True) for k in range(len(data) + 1)], skips)
            assert len(frames) + sum(skips.reasons.values()) >= len(data) + 1
