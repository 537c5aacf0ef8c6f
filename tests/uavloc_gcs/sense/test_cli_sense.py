"""``uavloc sense`` end to end: capture -> frames.csv / slots.csv -> ``uavloc localize``; bad input."""

import csv
import math
import subprocess
import sys

import numpy as np
import pytest

from uavloc_gcs.cli import main
from uavloc_gcs.scenario import load_scenario

pytest.importorskip("scapy.all", reason="scapy (pip install scapy) builds the test captures")
from scapy.all import wrpcap, wrpcapng  # noqa: E402

from .flight_world import build  # noqa: E402

SMALL = "uavloc_gcs/examples/small.toml"


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    sc = load_scenario(SMALL)
    d = tmp_path_factory.mktemp("flight")
    w = build(sc, [(180.0, 120.0), (380.0, 220.0)], [True, False], seed=3)
    (d / "flight.tlog").write_bytes(w.tlog)
    wrpcapng(str(d / "heard.pcapng"), w.packets)
    return sc, d, w


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(line for line in f if not line.startswith("#")))


def test_capture_to_slots_to_localize(world, tmp_path, capsys):
    sc, d, w = world
    assert main(["sense", str(d / "heard.pcapng"), "--out", str(tmp_path / "s"), "--tlog", str(d / "flight.tlog")]) == 0
    frames = _rows(tmp_path / "s" / "frames.csv")
    assert len(frames) == len(w.packets)
    assert set(frames[0]) >= {"time_unix_s", "source_mac", "channel", "rssi_dbm", "emitter_id"}
    # the stable phone is one emitter id; the randomizing one a new id per burst (one address each)
    stable = {r["emitter_id"] for r in frames if r["source_mac"] == "00:1a:11:00:00:01"}
    assert len(stable) == 1
    by_id = {}
    for r in frames:
        by_id.setdefault(r["emitter_id"], set()).add(r["source_mac"])
    assert all(len(v) == 1 for v in by_id.values())
    slots = _rows(tmp_path / "s" / "slots.csv")
    assert slots and {r["vehicle_id"] for r in slots} == {"1"}
    assert sum(int(r["n_samples"]) for r in slots) == len(frames)  # every frame heard in flight is placed
    assert main(["localize", str(tmp_path / "s" / "slots.csv"), "--scenario", SMALL, "--static",
                 "--out", str(tmp_path / "e")]) == 0
    est = _rows(tmp_path / "e" / "estimates.csv")
    assert est
    # each true phone has an estimate near it (the randomizing phone's bursts are linked into a person)
    for xy in w.phones_xy_m:
        lat, lon = sc.frame.to_wgs84(*xy)
        errs = []
        for r in est:
            if r["lat_deg"]:
                e, n = sc.frame.to_local(float(r["lat_deg"]), float(r["lon_deg"]))
                errs.append(math.hypot(e - xy[0], n - xy[1]))
        assert min(errs) < 60.0, (xy, sorted(errs)[:3])


def test_pcap_and_pcapng_give_the_same_frames(world, tmp_path):
    _, d, w = world
    wrpcap(str(tmp_path / "heard.pcap"), w.packets)
    assert main(["sense", str(tmp_path / "heard.pcap"), "--out", str(tmp_path / "a")]) == 0
    assert main(["sense", str(d / "heard.pcapng"), "--out", str(tmp_path / "b")]) == 0
    a, b = _rows(tmp_path / "a" / "frames.csv"), _rows(tmp_path / "b" / "frames.csv")
    assert len(a) == len(b) == len(w.packets)
    # scapy writes a pcap's microseconds truncated and a pcapng's rounded: times within 1 us
    assert all(abs(float(x.pop("time_unix_s")) - float(y.pop("time_unix_s"))) <= 1.5e-6 for x, y in zip(a, b))
    assert a == b


def test_learn_team_then_exclude(world, tmp_path, capsys):
    _, d, w = world
    team = tmp_path / "team.txt"
    assert main(["sense", str(d / "heard.pcapng"), "--learn-team", str(team)]) == 0
    text = team.read_text()
    assert "mac 00:1a:11:00:00:01" in text  # the stable phone, heard many times
    assert main(["sense", str(d / "heard.pcapng"), "--exclude", str(team), "--out", str(tmp_path / "o")]) == 0
    macs = {r["source_mac"] for r in _rows(tmp_path / "o" / "frames.csv")}
    assert "00:1a:11:00:00:01" not in macs
    (tmp_path / "oui.txt").write_text("oui 00:1a:11\n")
    assert main(["sense", str(d / "heard.pcapng"), "--exclude", str(tmp_path / "oui.txt"),
                 "--out", str(tmp_path / "p")]) == 0
    assert all(not r["source_mac"].startswith("00:1a:11") for r in _rows(tmp_path / "p" / "frames.csv"))


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "uavloc_gcs", "sense", *args], capture_output=True, text=True,
                          timeout=120)


def test_not_a_capture_exits_2_in_one_sentence(tmp_path):
    p = tmp_path / "flight.tlog"
    p.write_bytes(b"\x00\x01\x02\x03 not a capture")
    r = _cli(str(p), "--out", str(tmp_path / "o"))
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.strip().count("\n") == 0 and "not a pcap, pcapng or btsnoop capture" in r.stderr
    assert not (tmp_path / "o").exists()  # nothing half-written


def test_corrupted_capture_counts_skips(world, tmp_path):
    _, d, _ = world
    buf = bytearray((d / "heard.pcapng").read_bytes())
    rng = np.random.default_rng(0)
    for pos in rng.integers(100, len(buf), 300):
        buf[pos] = int(rng.integers(256))
    (tmp_path / "bad.pcapng").write_bytes(bytes(buf[: len(buf) * 2 // 3]))
    r = _cli(str(tmp_path / "bad.pcapng"), "--out", str(tmp_path / "o"))
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    assert "skipped:" in r.stdout and (tmp_path / "o" / "frames.csv").exists()


def test_bad_flags_are_one_sentence(tmp_path, world):
    _, d, _ = world
    for args, key in [([], "capture"), ([str(d / "heard.pcapng")], "--out"),
                      ([str(d / "heard.pcapng"), "--tlog", str(d / "flight.tlog")], "--tlog"),
                      ([str(d / "heard.pcapng"), "--out", str(tmp_path / "o"), "--slot-ms", "0"], "--slot-ms")]:
        r = _cli(*args)
        assert r.returncode == 2 and key in r.stderr and "Traceback" not in r.stderr, (args, r.stderr)


def test_live_without_device_or_monitor_mode_is_one_sentence(tmp_path):
    pytest.importorskip("pcapy", reason="pcapy-ng (pip install 'uavloc[sense]') is the live binding")
    r = _cli("--interface", "nosuchwlan9", "--out", str(tmp_path / "o"))
    assert r.returncode == 2 and "cannot capture on nosuchwlan9" in r.stderr and "Traceback" not in r.stderr


def test_an_interface_not_in_monitor_mode_is_refused(tmp_path):
    import os

    pytest.importorskip("pcapy", reason="pcapy-ng (pip install 'uavloc[sense]') is the live binding")
    if os.geteuid() != 0:
        pytest.skip("opening the loopback interface for capture needs root (CAP_NET_RAW)")
    r = _cli("--interface", "lo", "--out", str(tmp_path / "o"), "--duration-s", "1")
    assert r.returncode == 2 and "lo is not in monitor mode" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "o").exists()
