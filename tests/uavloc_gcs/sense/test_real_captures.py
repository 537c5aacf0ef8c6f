"""Public real captures: two shipped ones, replayed on every run, and more when present.

``real/`` holds two small radiotap captures from tcpdump's test suite (BSD licence, see
``real/README.md``) with tcpdump's own dissection beside them: each is compared with it, with
scapy's, and run end to end.

Set ``UAVLOC_REAL_CAPTURES`` to a folder of ``.pcap``/``.pcapng`` files with radiotap probe
requests, e.g. files of the Brno sc6-61 probe-request data set (github.com/tomas-fryza/probe-request-project,
``DATA/sc6-61/_PCAP/...``, with their ``_CSV/..._ver-99.csv`` beside them). Each capture is parsed
and compared frame by frame with scapy's dissector (and with the data set's own CSV where it is
beside it), then run end to end: ``uavloc sense --tlog`` on a synthetic flight over its first
minute, and ``uavloc localize`` on the slots.
"""

import csv
import os
import re
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pytest

from uavloc_gcs.cli import main
from uavloc_gcs.scenario import load_scenario
from uavloc_gcs.sense import parse_capture
from uavloc_gcs.sense.radiotap import freq_to_channel

SHIPPED = Path(__file__).parent / "real"
ROOT = os.environ.get("UAVLOC_REAL_CAPTURES")
CAPTURES = sorted(SHIPPED.glob("*.pcap")) + (
    sorted(p for ext in ("*.pcap", "*.pcapng") for p in Path(ROOT).glob(ext)) if ROOT else [])

# tcpdump's line for a frame: "  n  2013-04-17 12:59:13.707778 ... 2412 MHz 11b -22dBm signal ... Probe Request"
TCPDUMP_LINE = re.compile(r"^\s*\d+\s+(\S+ \S+) .*? (\d+) MHz .*? (-?\d+)dBm signal ")


def tcpdump_lines(path: Path) -> list[str]:
    return (path.with_suffix(".out")).read_text().splitlines()


@pytest.mark.parametrize("path", sorted(SHIPPED.glob("*.pcap")), ids=lambda p: p.name)
def test_shipped_real_capture_matches_tcpdumps_dissection(path):
    """Every probe request tcpdump prints is read with its time, signal and channel; every other
    frame is counted as skipped, for the reason tcpdump's line gives."""
    frames, skips = parse_capture(path)
    lines = tcpdump_lines(path)
    probes = [line for line in lines if "Probe Request" in line]
    assert len(frames) == len(probes) > 0
    for line, t, rssi, ch in zip(probes, frames.t_s, frames.rssi_dbm, frames.channel):
        when, mhz, dbm = TCPDUMP_LINE.match(line).groups()[:3]
        want_t = datetime.strptime(when, "%Y-%m-%d %H:%M:%S.%f").replace(tzinfo=timezone.utc).timestamp()
        assert abs(t - want_t) < 1e-6 and rssi == int(dbm) and ch == freq_to_channel(int(mhz))
    # ACKs are 14-byte control frames: other frames, not malformed ones (an earlier parser counted
    # them as short 802.11 headers)
    assert skips.reasons == {"not_probe": len(lines) - len(probes)} and skips.malformed == 0


def test_radiotap_namespaces_of_real_captures():
    """exthdr's second present word continues the radiotap namespace (bits 32-63, none defined): the
    header has one signal field, -22 dBm (an earlier parser read that word as a new namespace, took
    a 0 dBm second antenna and a flags byte that marked probe responses' FCS bad). meshid's header
    has two more radiotap namespaces, one per antenna: its last four bytes are da 00 d4 01, antenna
    0 at -38 dBm and antenna 1 at -44 dBm, after the combined -38 dBm."""
    frames, _ = parse_capture(SHIPPED / "ieee802.11_exthdr.pcap")
    assert frames.antennas_dbm[0] == (-22,)
    frames, _ = parse_capture(SHIPPED / "ieee802.11_meshid.pcap")
    assert frames.antennas_dbm == ((-38, -38, -44),)


@pytest.mark.parametrize("path", CAPTURES, ids=lambda p: p.name)
def test_real_capture_matches_scapy_and_the_data_sets_csv(path):
    from scapy.layers.dot11 import Dot11, Dot11ProbeReq, RadioTap
    from scapy.utils import RawPcapReader

    frames, skips = parse_capture(path)
    assert len(frames) > 0 and skips.malformed == 0
    want = []
    for raw, _ in RawPcapReader(str(path)):
        p = RadioTap(raw)
        if p.haslayer(Dot11ProbeReq) and p.dBm_AntSignal is not None:
            want.append((int(p[Dot11].addr2.replace(":", ""), 16), p.dBm_AntSignal, p[Dot11].SC >> 4))
    got = list(zip(frames.address.tolist(), frames.rssi_dbm.tolist(), frames.seq.tolist()))
    assert got == want
    name = path.name.replace("_anonymized.pcap", "_ver-99.csv")
    if name != path.name and (path.parent / name).exists():
        rows = list(csv.DictReader(open(path.parent / name, newline=""), delimiter=";"))
        assert [int(r["src"].replace(":", ""), 16) for r in rows] == frames.address.tolist()
        assert [int(r["rssi"]) for r in rows] == frames.rssi_dbm.tolist()
        assert [freq_to_channel(int(r["ch_freq"])) for r in rows] == frames.channel.tolist()
    # one fingerprint per address: what varies within a device is left out of the hash
    pairs = np.unique(np.stack([frames.address, frames.fingerprint], axis=1), axis=0)
    assert len(pairs) == len(np.unique(frames.address))


@pytest.mark.parametrize("path", CAPTURES[:2], ids=lambda p: p.name)
def test_real_capture_end_to_end(path, tmp_path):
    from .flight_world import T0_UNIX_S, flight_tlog

    sc = load_scenario("uavloc_gcs/examples/small.toml")
    (tmp_path / "f.tlog").write_bytes(flight_tlog(sc))
    frames, _ = parse_capture(path)
    offset = T0_UNIX_S - float(frames.t_s.min())
    assert main(["sense", str(path), "--out", str(tmp_path / "s"), "--tlog", str(tmp_path / "f.tlog"),
                 "--clock-offset-s", f"{offset:.6f}"]) == 0
    assert (tmp_path / "s" / "slots.csv").read_text().count("\n") > 2
    assert main(["localize", str(tmp_path / "s" / "slots.csv"), "--scenario", "uavloc_gcs/examples/small.toml",
                 "--static", "--out", str(tmp_path / "e")]) == 0
    assert (tmp_path / "e" / "estimates.csv").exists()
