"""Fuzzed captures: any bytes behind a capture's magic give counts, never a traceback."""

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from uavloc_gcs.sense import parse_capture_bytes
from uavloc_gcs.sense.capture import LINKTYPE_PPI
from uavloc_gcs.sense.synth import synthetic_capture

_BASE, _ = synthetic_capture(40, n_phones=5, rng=np.random.default_rng(11))


def _pcapng(pcap: bytes) -> bytes:
    """The same records as a little-endian pcapng (SHB, IDB, EPBs)."""
    import struct

    shb = struct.pack("<IIIHHq", 0x0A0D0D0A, 28, 0x1A2B3C4D, 1, 0, -1) + struct.pack("<I", 28)
    idb = struct.pack("<IIHHI", 1, 20, 127, 0, 65535) + struct.pack("<I", 20)
    out, pos = [shb, idb], 24
    while pos < len(pcap):
        sec, usec, incl, orig = struct.unpack_from("<IIII", pcap, pos)
        data = pcap[pos + 16:pos + 16 + incl]
        pad = b"\0" * (-incl % 4)
        ts = sec * 1_000_000 + usec
        blen = 32 + incl + len(pad)
        out.append(struct.pack("<IIIIIII", 6, blen, 0, ts >> 32, ts & 0xFFFFFFFF, incl, orig) + data + pad
                   + struct.pack("<I", blen))
        pos += 16 + incl
    return b"".join(out)


_BASE_NG = _pcapng(_BASE)


def _check(buf: bytes):
    frames, skips = parse_capture_bytes(buf)
    # every record read is either a frame used or one counted reason
    assert len(frames) + sum(skips.reasons.values()) == skips.read.records
    assert np.all((frames.rssi_dbm >= -120) & (frames.rssi_dbm <= 10))
    assert np.all(frames.address >= 0) and np.all(frames.address < 2**48)
    return frames, skips


def test_unmutated_bases_parse_whole():
    for buf in (_BASE, _BASE_NG):
        frames, skips = _check(buf)
        assert len(frames) == 40 and skips.malformed == 0


mutation = st.lists(st.tuples(st.integers(0, 10**7), st.integers(0, 255)), min_size=1, max_size=40)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(base=st.sampled_from(["pcap", "pcapng"]), flips=mutation, cut=st.integers(0, 10**7))
def test_flipped_and_truncated_bytes_never_raise(base, flips, cut):
    buf = bytearray(_BASE if base == "pcap" else _BASE_NG)
    head = 24 if base == "pcap" else 12  # keep the magic and byte order: the rest is fair game
    for pos, val in flips:
        buf[head + pos % (len(buf) - head)] = val
    _check(bytes(buf[:head + cut % (len(buf) - head + 1)]))


@settings(max_examples=200, deadline=None)
@given(body=st.binary(max_size=600), linktype=st.sampled_from([127, LINKTYPE_PPI, 105, 1, 0xFFFF]))
def test_random_records_never_raise(body, linktype):
    from uavloc_gcs.sense.synth import pcap_bytes

    _check(pcap_bytes([(1.0, body), (2.0, body[::-1])], linktype=linktype))


@settings(max_examples=150, deadline=None)
@given(tail=st.binary(max_size=400))
def test_random_bytes_after_a_header_never_raise(tail):
    _check(_BASE[:24] + tail)
    _check(_BASE_NG[:48] + tail)
