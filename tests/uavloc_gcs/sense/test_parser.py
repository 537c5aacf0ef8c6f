"""The capture parser against scapy's dissector, on captures scapy builds and on the synthetic ones."""

import struct

import numpy as np
import pytest

from uavloc_gcs.errors import FileFormatError
from uavloc_gcs.sense import parse_capture, parse_capture_bytes
from uavloc_gcs.sense.aggregate import emitter_ids, slot_entries
from uavloc_gcs.sense.dot11 import fingerprint_elements
from uavloc_gcs.sense.radiotap import freq_to_channel
from uavloc_gcs.sense.synth import MODELS, pcap_bytes, probe_request, synthetic_capture

scapy_all = pytest.importorskip("scapy.all", reason="scapy (pip install scapy) builds the reference captures")
from scapy.all import Dot11, Dot11Beacon, Dot11Elt, Dot11ProbeReq, RadioTap, wrpcap, wrpcapng  # noqa: E402
from scapy.utils import RawPcapReader  # noqa: E402


def _probe(mac, rssi, freq=2437, ch=6, seq=1, ssid=b"", ht=True, flags=0):
    p = (RadioTap(present="Flags+Channel+dBm_AntSignal", Flags=flags, ChannelFrequency=freq, ChannelFlags=0xa0,
                  dBm_AntSignal=rssi)
         / Dot11(type=0, subtype=4, addr1="ff:ff:ff:ff:ff:ff", addr2=mac, addr3="ff:ff:ff:ff:ff:ff", SC=seq << 4)
         / Dot11ProbeReq() / Dot11Elt(ID=0, info=ssid) / Dot11Elt(ID=1, info=b"\x02\x04\x0b\x16")
         / Dot11Elt(ID=3, info=bytes([ch])))
    if ht:
        p = p / Dot11Elt(ID=45, info=b"\x2d\x11" + b"\x00" * 24)
    return p


def _beacon(mac):
    return (RadioTap(present="dBm_AntSignal", dBm_AntSignal=-40)
            / Dot11(type=0, subtype=8, addr1="ff:ff:ff:ff:ff:ff", addr2=mac, addr3=mac) / Dot11Beacon()
            / Dot11Elt(ID=0, info=b"net"))


@pytest.fixture
def mixed(tmp_path):
    pkts = [_probe("02:00:00:00:00:%02x" % i, -50 - i, seq=i) for i in range(6)]
    pkts.insert(2, _beacon("00:11:22:33:44:55"))
    pkts.append(_probe("02:00:00:00:00:99", -70, freq=5180, ch=36))
    for k, p in enumerate(pkts):
        p.time = 1_700_000_000 + 0.01 * k
    path = tmp_path / "mixed.pcap"
    wrpcap(str(path), pkts)
    return path, pkts


def test_fields_match_scapy_on_a_scapy_capture(mixed):
    path, pkts = mixed
    frames, skips = parse_capture(path)
    want = [p for p in pkts if p.haslayer(Dot11ProbeReq)]
    assert len(frames) == len(want) == 7
    assert skips.reasons["not_probe"] == 1 and skips.malformed == 0
    assert [f"{a:012x}" for a in frames.address] == [p[Dot11].addr2.replace(":", "") for p in want]
    assert frames.rssi_dbm.tolist() == [p.dBm_AntSignal for p in want]
    assert frames.channel.tolist() == [freq_to_channel(p.ChannelFrequency) for p in want]
    assert frames.seq.tolist() == [p[Dot11].SC >> 4 for p in want]
    assert np.allclose(frames.t_s, [float(p.time) for p in want], atol=1e-6)


def test_pcapng_gives_the_same_frames_as_pcap(mixed, tmp_path):
    path, pkts = mixed
    ng = tmp_path / "mixed.pcapng"
    wrpcapng(str(ng), pkts)
    a, _ = parse_capture(path)
    b, skips = parse_capture(ng)
    assert skips.read.bad_records == 0
    assert a.address.tolist() == b.address.tolist() and a.rssi_dbm.tolist() == b.rssi_dbm.tolist()
    assert np.allclose(a.t_s, b.t_s, atol=1e-6)


def test_big_endian_nanosecond_pcap():
    buf, truth = synthetic_capture(50, rng=np.random.default_rng(3))
    recs, pos = [], 24
    while pos < len(buf):
        sec, usec, incl, orig = struct.unpack_from("<IIII", buf, pos)
        recs.append(struct.pack(">IIII", sec, usec * 1000, incl, orig) + buf[pos + 16:pos + 16 + incl])
        pos += 16 + incl
    be = struct.pack(">IHHiIII", 0xA1B23C4D, 2, 4, 0, 0, 65535, 127) + b"".join(recs)
    frames, skips = parse_capture_bytes(be)
    assert len(frames) == 50 and skips.malformed == 0
    assert frames.address.tolist() == truth.address.tolist()
    assert np.allclose(frames.t_s, truth.t_s, atol=2e-6)


def test_synthetic_capture_matches_scapy_and_the_truth():
    buf, truth = synthetic_capture(300, rng=np.random.default_rng(0))
    frames, skips = parse_capture_bytes(buf)
    assert skips.malformed == 0 and len(frames) == 300
    assert frames.address.tolist() == truth.address.tolist()
    assert frames.rssi_dbm.tolist() == truth.rssi_dbm.tolist()
    assert frames.channel.tolist() == truth.channel.tolist()
    import io

    scapy_rssi, scapy_seq = [], []
    for raw, _ in RawPcapReader(io.BytesIO(buf)):
        p = RadioTap(raw)
        scapy_rssi.append(p.dBm_AntSignal)
        scapy_seq.append(p[Dot11].SC >> 4)
    assert frames.rssi_dbm.tolist() == scapy_rssi and frames.seq.tolist() == scapy_seq
    assert all(len(a) == 3 for a in frames.antennas_dbm)  # combined + two chains


def test_ppi_header():
    frame = probe_request(0x02AABBCCDDEE, 5, 11, MODELS["ios17"])
    common = struct.pack("<QHHHHBBbb", 0, 0x0001, 2, 2462, 0x00a0, 0, 0, -63, -95)  # FCS present
    ppi = struct.pack("<BBHI", 0, 0, 8 + 4 + len(common), 105) + struct.pack("<HH", 2, len(common)) + common
    frames, skips = parse_capture_bytes(pcap_bytes([(1.7e9, ppi + frame)], linktype=192))
    assert len(frames) == 1 and frames.rssi_dbm[0] == -63 and frames.channel[0] == 11
    assert frames.address[0] == 0x02AABBCCDDEE


def test_bad_fcs_and_other_link_types_are_counted(mixed):
    _, pkts = mixed
    bad = _probe("02:00:00:00:01:01", -60, flags=0x50)  # FCS at end + bad FCS
    recs = [(1.7e9, bytes(bad)), (1.7e9 + 1, bytes(pkts[0]))]
    frames, skips = parse_capture_bytes(pcap_bytes(recs))
    assert skips.reasons["bad_fcs"] == 1
    frames, skips = parse_capture_bytes(pcap_bytes(recs, linktype=1))  # Ethernet
    assert len(frames) == 0 and skips.reasons["not_80211"] == 2


def test_bad_lengths_are_counted_not_raised():
    good = bytes(_probe("02:00:00:00:00:01", -60))
    long_radiotap = good[:2] + struct.pack("<H", 4000) + good[4:]
    bad_element = good[:-27] + b"\x2d\xff" + good[-25:]  # HT element claims 255 bytes
    short = good[:20]
    frames, skips = parse_capture_bytes(pcap_bytes([(1.0, long_radiotap), (2.0, bad_element), (3.0, short),
                                                    (4.0, good)]))
    assert len(frames) == 1
    assert skips.reasons["bad_radiotap"] == 1 and skips.reasons["bad_element"] == 1
    assert skips.reasons["short_80211"] == 1 and skips.malformed == 3


def test_truncated_file_counts_the_cut_record():
    buf, _ = synthetic_capture(10, rng=np.random.default_rng(1))
    frames, skips = parse_capture_bytes(buf[:-30])
    assert len(frames) == 9 and skips.read.bad_records == 1


def test_not_a_capture_is_refused(tmp_path):
    p = tmp_path / "notes.txt"
    p.write_text("hello world\n")
    with pytest.raises(FileFormatError, match="not a pcap, pcapng or btsnoop capture"):
        parse_capture(p)


def test_fingerprint_ignores_ssid_channel_and_rates_but_not_the_model():
    base = MODELS["android14"]
    fp = {}
    for name, model in MODELS.items():
        f1 = probe_request(0x021111111111, 1, 1, model)
        fp[name] = fingerprint_elements(f1[24:-4])[0]
    assert len(set(fp.values())) == len(MODELS)  # four models, four fingerprints
    same = [fingerprint_elements(probe_request(a, s, ch, base, ssid)[24:-4])[0]
            for a, s, ch, ssid in [(0x02AAAAAAAAAA, 9, 6, b""), (0x02BBBBBBBBBB, 77, 11, b"home-wifi"),
                                   (0x02CCCCCCCCCC, 400, 36, b"cafe")]]
    assert set(same) == {fp["android14"]}


def test_emitter_ids_never_join_different_content():
    buf, truth = synthetic_capture(400, n_phones=6, rng=np.random.default_rng(5))
    frames, _ = parse_capture_bytes(buf)
    ids = emitter_ids(frames)
    for i in np.unique(ids):
        sel = ids == i
        assert len(np.unique(frames.fingerprint[sel])) == 1 and len(np.unique(frames.address[sel])) == 1
        assert len(np.unique(truth.phone[sel])) == 1  # one id, one device
    # same address with another content: a new id
    a = probe_request(0x02DDDDDDDDDD, 1, 6, MODELS["ios17"])
    b = probe_request(0x02DDDDDDDDDD, 2, 6, MODELS["windows"])
    from uavloc_gcs.sense.synth import radiotap

    rt = radiotap(0, 2437, -50, (-50, -51))
    f, _ = parse_capture_bytes(pcap_bytes([(1.0, rt + a), (1.1, rt + b), (1.2, rt + a)]))
    assert emitter_ids(f).tolist() == [1, 2, 1]


def test_slot_entries_mean_count_and_first_channel():
    rt6 = __import__("uavloc_gcs.sense.synth", fromlist=["radiotap"]).radiotap
    m = MODELS["ios17"]
    recs = [(100.001, rt6(0, 2437, -50, (-50, -50)) + probe_request(0x020000000001, 1, 6, m)),
            (100.010, rt6(0, 2462, -60, (-60, -60)) + probe_request(0x020000000001, 2, 11, m)),
            (100.012, rt6(0, 2437, -70, (-70, -70)) + probe_request(0x020000000002, 1, 6, m)),
            (100.030, rt6(0, 2437, -40, (-40, -40)) + probe_request(0x020000000001, 3, 6, m))]
    f, _ = parse_capture_bytes(pcap_bytes(recs))
    e = slot_entries(f, 0.025)
    assert len(e) == 3
    assert e.address.tolist() == [0x020000000001, 0x020000000002, 0x020000000001]
    assert e.rssi_dbm.tolist() == [-55.0, -70.0, -40.0] and e.n_frames.tolist() == [2, 1, 1]
    assert e.channel.tolist() == [6, 6, 6]
    assert np.allclose(e.t_s, [100.0, 100.0, 100.025])
