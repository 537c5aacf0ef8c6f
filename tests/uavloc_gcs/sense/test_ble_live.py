"""``uavloc sense --ble-adapter``: a stand-in bleak that reports advertisements as BlueZ would, and
the refusals when bleak or the adapter is missing (one sentence, exit 2)."""

import csv
import subprocess
import sys
import types

import pytest

from uavloc_gcs.cli import main
from uavloc_gcs.sense.ble_live import scan_record

KEY = bytes(range(0x41, 0x41 + 28))
FINDMY_ADDRESS = ":".join(f"{b:02X}" for b in bytes([KEY[0] | 0xC0]) + KEY[1:6])
FINDMY_DATA = bytes([0x12, 0x19, 0x00]) + KEY[6:] + bytes([KEY[0] >> 6, 0x00])


class _Device:
    def __init__(self, address, kind):
        self.address, self.details = address, {"path": "/org/bluez/hci0/dev_x", "props": {"AddressType": kind}}


class _Adv:
    def __init__(self, rssi, manufacturer_data):
        self.rssi, self.manufacturer_data = rssi, manufacturer_data


def _fake_bleak(calls):
    class BleakScanner:
        def __init__(self, callback, scanning_mode="active", *, bluez=None, **kw):
            calls.append((scanning_mode, bluez))
            self.callback = callback

        async def start(self):
            for k in range(5):
                self.callback(_Device(FINDMY_ADDRESS, "random"), _Adv(-60 - k, {0x004C: FINDMY_DATA}))
            self.callback(_Device("00:1A:7D:DA:71:13", "public"), _Adv(-80, {}))
            self.callback(_Device("00:1A:7D:DA:71:13", "public"), _Adv(None, {}))  # no RSSI: not a measurement

        async def stop(self):
            calls.append("stop")

    return types.SimpleNamespace(BleakScanner=BleakScanner)


def test_scan_reports_become_ble_frames_with_findmy(tmp_path, monkeypatch, capsys):
    calls = []
    monkeypatch.setitem(sys.modules, "bleak", _fake_bleak(calls))
    assert main(["sense", "--ble-adapter", "hci0", "--duration-s", "0.3", "--out", str(tmp_path / "o")]) == 0
    assert calls[0] == ("active", {"adapter": "hci0", "filters": {"DuplicateData": True}}) and calls[-1] == "stop"
    with open(tmp_path / "o" / "frames.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["rssi_dbm"] for r in rows] == ["-60", "-61", "-62", "-63", "-64", "-80"]
    assert {r["radio"] for r in rows} == {"ble"} and [r["apple_type"] for r in rows] == ["findmy"] * 5 + [""]
    assert [r["ble_random"] for r in rows] == ["1"] * 5 + ["0"] and rows[0]["source_mac"] == FINDMY_ADDRESS.lower()
    assert rows[0]["fingerprint"] != "00000000" and rows[-1]["channel"] == "0" and rows[0]["ble_pdu"] == ""


def test_scan_record_layout():
    rec = scan_record("C1:42:43:44:45:46", True, -70, {0x004C: b"\x10\x02\x01\x02", 0x0006: b""})
    assert rec == bytes.fromhex("c14243444546") + bytes([1, 256 - 70]) + bytes([7, 0xFF, 0x4C, 0x00]) + \
        b"\x10\x02\x01\x02" + bytes([3, 0xFF, 0x06, 0x00])


def _cli(*args, env=None):
    return subprocess.run([sys.executable, "-m", "uavloc_gcs", "sense", *args], capture_output=True, text=True,
                          timeout=120, env=env)


def test_without_bleak_one_sentence_and_exit_2(tmp_path):
    import os

    fake = tmp_path / "lib" / "bleak"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text("raise ImportError('bleak is not installed here')\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path / "lib"), os.environ.get("PYTHONPATH", "")]))
    r = _cli("--ble-adapter", "hci0", "--out", str(tmp_path / "o"), env=env)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert r.stderr.strip().count("\n") == 0 and "needs the Bluetooth LE library bleak" in r.stderr


def test_without_an_adapter_one_sentence_and_exit_2(tmp_path):
    """An adapter that does not exist (this machine has none at all, and maybe no D-Bus system bus):
    bleak's error becomes one sentence naming the adapter."""
    pytest.importorskip("bleak")
    r = _cli("--ble-adapter", "hci97", "--duration-s", "1", "--out", str(tmp_path / "o"))
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert r.stderr.strip().count("\n") == 0 and "cannot scan for Bluetooth LE on hci97" in r.stderr


def test_capture_and_live_together_are_refused(tmp_path):
    r = _cli(str(tmp_path / "x.pcap"), "--ble-adapter", "hci0", "--out", str(tmp_path / "o"))
    assert r.returncode == 2 and "not both" in r.stderr
