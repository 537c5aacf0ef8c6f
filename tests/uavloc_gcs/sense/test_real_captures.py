"""Public real captures, replayed when present (they are not shipped: see docs/readme/sense.md).

Set ``UAVLOC_REAL_CAPTURES`` to a folder of ``.pcap``/``.pcapng`` files with radiotap probe
requests, e.g. files of the Brno sc6-61 probe-request data set (github.com/tomas-fryza/probe-request-project,
``DATA/sc6-61/_PCAP/...``, with their ``_CSV/..._ver-99.csv`` beside them). Each capture is parsed
and compared frame by frame with scapy's dissector (and with the data set's own CSV where it is
beside it), then run end to end: ``uavloc sense --tlog`` on a synthetic flight over its first
minute, and ``uavloc localize`` on the slots.
"""

import csv
import os
from pathlib import Path

import numpy as np
import pytest

from uavloc_gcs.cli import main
from uavloc_gcs.scenario import load_scenario
from uavloc_gcs.sense import parse_capture
from uavloc_gcs.sense.radiotap import freq_to_channel

ROOT = os.environ.get("UAVLOC_REAL_CAPTURES")
CAPTURES = sorted(p for ext in ("*.pcap", "*.pcapng") for p in Path(ROOT).glob(ext)) if ROOT else []
pytestmark = pytest.mark.skipif(not CAPTURES, reason="no real captures: set UAVLOC_REAL_CAPTURES to a folder of "
                                                     ".pcap/.pcapng files (docs/readme/sense.md names public ones)")


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
    if (path.parent / name).exists():
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
