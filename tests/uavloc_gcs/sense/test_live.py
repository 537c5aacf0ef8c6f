"""The live path without hardware: a stand-in libpcap binding (the pcapy API) that delivers a
synthetic capture's records, and a stand-in ``iw`` that records the channel hops."""

import os
import stat
import sys
import time
import types

import numpy as np
import pytest

from uavloc_gcs.cli import main
from uavloc_gcs.errors import ConfigError
from uavloc_gcs.sense import parse_capture_bytes
from uavloc_gcs.sense.capture import ReadStats, read_records
from uavloc_gcs.sense.live import ChannelHopper, parse_channels
from uavloc_gcs.sense.synth import synthetic_capture


class _Header:
    def __init__(self, t, n):
        self.t, self.n = t, n

    def getts(self):
        return int(self.t), int(round((self.t - int(self.t)) * 1e6))

    def getcaplen(self):
        return self.n

    def getlen(self):
        return self.n


class _Pcap:
    """What pcapy.open_live returns: datalink(), setfilter(), dispatch(n, callback)."""

    def __init__(self, records, linktype=127):
        self.records, self.linktype, self.filters = list(records), linktype, []

    def datalink(self):
        return self.linktype

    def setfilter(self, text):
        self.filters.append(text)

    def dispatch(self, n, callback):
        if not self.records:
            time.sleep(0.02)  # libpcap's read timeout
            return 0
        batch, self.records = self.records[:n], self.records[n:]
        for _, t, data, _ in batch:
            callback(_Header(time.time(), len(data)), data)
        return len(batch)


def _fake_pcapy(monkeypatch, handles):
    mod = types.ModuleType("pcapy")

    class PcapError(Exception):
        pass

    def open_live(name, snaplen, promisc, timeout_ms):
        if name not in handles:
            raise PcapError(f"{name}: No such device exists")
        return handles[name]

    mod.PcapError, mod.open_live = PcapError, open_live
    monkeypatch.setitem(sys.modules, "pcapy", mod)


def test_live_interfaces_to_frames_csv(monkeypatch, tmp_path, capsys):
    buf, truth = synthetic_capture(120, n_phones=5, rng=np.random.default_rng(9))
    recs = list(read_records(buf, ReadStats()))
    a, b = _Pcap(recs[:60]), _Pcap(recs[60:])
    _fake_pcapy(monkeypatch, {"wlan1": a, "wlan2": b})
    assert main(["sense", "-i", "wlan1", "-i", "wlan2", "--out", str(tmp_path / "o"), "--duration-s", "1.5"]) == 0
    assert a.filters == b.filters == ["type mgt subtype probe-req"]
    rows = (tmp_path / "o" / "frames.csv").read_text().splitlines()[1:]
    assert len(rows) == 120  # both interfaces' frames, stamped on arrival
    macs = {r.split(",")[1] for r in rows}
    want, _ = parse_capture_bytes(buf)
    assert macs == {":".join(f"{a:012x}"[i:i + 2] for i in range(0, 12, 2)) for a in want.address.tolist()}


def test_live_refusals_are_one_sentence(monkeypatch, tmp_path, capsys):
    def refused(iface, sentence):
        rc = main(["sense", "-i", iface, "--out", str(tmp_path / "o"), "--duration-s", "0.1"])
        err = capsys.readouterr().err
        assert rc == 2 and sentence in err and err.count("\n") == 1, err

    _fake_pcapy(monkeypatch, {"eth0": _Pcap([], linktype=1)})
    refused("wlan9", "cannot capture on wlan9: no such interface")
    refused("eth0", "eth0 is not in monitor mode")
    monkeypatch.setitem(sys.modules, "pcapy", None)  # the binding is not installed
    refused("wlan1", "pip install 'uavloc[sense]'")
    assert not (tmp_path / "o").exists()


def test_channel_plan():
    assert parse_channels("1,6,11", 0.25) == [(1, 0.25), (6, 0.25), (11, 0.25)]
    assert parse_channels("1:400,36:100", 0.25) == [(1, 0.4), (36, 0.1)]
    for bad in ("", "1,x", "0", "1:0", "300", "6:99999"):
        with pytest.raises(ConfigError, match="--channels"):
            parse_channels(bad, 0.25)


def test_hopper_runs_iw_on_its_one_interface(monkeypatch, tmp_path):
    log = tmp_path / "iw.log"
    iw = tmp_path / "iw"
    iw.write_text(f"#!/bin/sh\necho \"$@\" >> {log}\n")
    iw.chmod(iw.stat().st_mode | stat.S_IEXEC)
    monkeypatch.setenv("PATH", f"{tmp_path}{os.pathsep}{os.environ['PATH']}")
    hop = ChannelHopper("wlan1", [(1, 0.05), (6, 0.1), (11, 0.05)])
    time.sleep(0.8)
    hop.close()
    calls = log.read_text().splitlines()
    assert calls[:4] == ["dev wlan1 set channel 1", "dev wlan1 set channel 6", "dev wlan1 set channel 11",
                         "dev wlan1 set channel 1"]
    assert all(c.startswith("dev wlan1 set channel ") for c in calls)
