"""``uavloc sense`` on Bluetooth LE captures, and the radio on its way to the ground: frames.csv,
slots.csv, UAVLOC_RSSI_BATCH2 (extension field ``radio``), slot CSV files and the store."""

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from uavloc_gcs.cli import main

from .ble_captures import btsnoop, capture

REAL = Path(__file__).parent / "real" / "le_secure_connections.pcapng"


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(line for line in f if not line.startswith("#")))


@pytest.mark.parametrize("kind", ["phdr", "btsnoop"])
def test_sense_on_a_ble_capture_writes_frames_csv_with_the_radio(kind, tmp_path, capsys):
    buf, truth = capture(kind, 40, seed=2)
    path = tmp_path / f"heard.{'log' if kind == 'btsnoop' else 'pcap'}"
    path.write_bytes(buf)
    assert main(["sense", str(path), "--out", str(tmp_path / "o")]) == 0
    rows = _rows(tmp_path / "o" / "frames.csv")
    assert len(rows) == 40 and {r["radio"] for r in rows} == {"ble"}
    order = np.argsort(truth.t_s, kind="stable")
    assert [int(r["rssi_dbm"]) for r in rows] == truth.rssi_dbm[order].tolist()
    apple = {r["apple_type"] for r in rows}
    assert {"findmy", "nearby_info", "proximity_pairing", "handoff", "nearby_action", ""} == apple
    assert {r["ble_pdu"] for r in rows} == {"ADV_IND", "ADV_NONCONN_IND", "ADV_SCAN_IND", "SCAN_RSP"}
    fm = [r for r in rows if r["apple_type"] == "findmy" and r["fingerprint"] != "00000000"]
    assert fm and all(r["ble_random"] == "1" for r in fm)
    assert "0 probe requests and 40 BLE advertisements used" in capsys.readouterr().out


def test_sense_on_the_real_ubertooth_capture(tmp_path, capsys):
    assert main(["sense", str(REAL), "--out", str(tmp_path / "o")]) == 0
    rows = _rows(tmp_path / "o" / "frames.csv")
    assert len(rows) == 42 and {(r["radio"], r["channel"], r["source_mac"]) for r in rows} == {
        ("ble", "37", "7d:43:82:42:23:16")}
    assert "not_advertising 261" in capsys.readouterr().out


def test_wifi_frames_keep_their_radio_column(tmp_path):
    from uavloc_gcs.sense.synth import synthetic_capture

    buf, _ = synthetic_capture(20, rng=np.random.default_rng(1))
    (tmp_path / "w.pcap").write_bytes(buf)
    assert main(["sense", str(tmp_path / "w.pcap"), "--out", str(tmp_path / "o")]) == 0
    rows = _rows(tmp_path / "o" / "frames.csv")
    assert {r["radio"] for r in rows} == {"wifi"} and {r["apple_type"] for r in rows} == {""}


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "uavloc_gcs", "sense", *args], capture_output=True, text=True,
                          timeout=120)


def test_garbage_and_unsupported_btsnoop_exit_2_in_one_sentence(tmp_path):
    for name, data, words in (("junk.log", b"bt-not-a-capture", "not a pcap, pcapng or btsnoop capture"),
                              ("bcsp.log", b"btsnoop\0" + bytes([0, 0, 0, 1, 0, 0, 3, 0xEB]), "datalink 1003"),
                              ("short.log", b"btsnoop\0\0\0", "btsnoop header is 10 bytes")):
        (tmp_path / name).write_bytes(data)
        r = _cli(str(tmp_path / name), "--out", str(tmp_path / "o"))
        assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
        assert r.stderr.strip().count("\n") == 0 and words in r.stderr and name in r.stderr


def test_btsnoop_with_broken_records_is_counted(tmp_path):
    buf, _ = capture("btsnoop", 10, seed=4)
    (tmp_path / "cut.log").write_bytes(buf[:-7])
    r = _cli(str(tmp_path / "cut.log"), "--out", str(tmp_path / "o"))
    assert r.returncode == 0 and "unreadable records 1" in r.stdout, r.stdout + r.stderr


# -- the radio on its way to the ground ------------------------------------------------------------

def _slots(radio):
    from uavloc_gcs.observations import SlotBatch

    n = len(radio)
    t = 10.0 + 0.015 * np.arange(n)  # 12 entries within one 200 ms message
    xyz = np.column_stack([5.0 * t, np.zeros(n), np.full(n, 60.0)])
    address = 0xC10000000000 + np.arange(n)
    return SlotBatch.from_columns(t, np.full(n, 2), xyz, address, np.full(n, -70.0), np.ones(n, dtype=int),
                                  address=address, fingerprint=np.arange(n), channel=np.full(n, 37), radio=radio)


def _wire(msgs):
    from uavloc_gcs.dialect import mavlink

    tx, rx = mavlink.MAVLink(None, srcSystem=2, srcComponent=191), mavlink.MAVLink(None)
    out, size = [], []
    for m in msgs:
        b = m.pack(tx)
        size.append(len(b))
        out.extend(rx.parse_buffer(b) or [])
    return out, size


def test_radio_travels_in_uavloc_rssi_batch2_and_old_messages_read_as_wifi():
    from uavloc_gcs.dialect.rssi import BATCH2, decode_rssi_batches, encode_rssi_batches
    from uavloc_gcs.geo import LocalFrame

    frame = LocalFrame(47.0, 8.0)
    mixed = _slots([1, 0, 1, 1, 0, 1, 0, 0, 1, 1, 0, 1])
    back = decode_rssi_batches(_wire(encode_rssi_batches(mixed, frame, message=BATCH2))[0], frame)
    assert back.radio.tolist() == mixed.radio.tolist() and back.channel.tolist() == [37] * 12
    # a Wi-Fi-only message: the radio array is zero and trimmed, the bytes are what they were
    wifi = _slots([0] * 12)
    msgs, size = _wire(encode_rssi_batches(wifi, frame, message=BATCH2))
    assert decode_rssi_batches(msgs, frame).radio.tolist() == [0] * 12
    assert size[0] <= 12 + 209  # header 10 + CRC 2: no radio byte is sent (MAVLink 2 trims the zeros)
    _, size_ble = _wire(encode_rssi_batches(mixed, frame, message=BATCH2))
    assert size_ble[0] == 12 + 221 and size_ble[0] <= 12 + 255


def test_slot_csv_keeps_the_radio_and_old_files_read_as_wifi():
    from uavloc_gcs.estimation.slots_csv import dumps_slots_csv, loads_slots_csv
    from uavloc_gcs.geo import LocalFrame

    frame = LocalFrame(47.0, 8.0)
    s = _slots([1, 0, 1])
    text = dumps_slots_csv(s, frame)
    assert text.splitlines()[0].endswith(",address,fingerprint,channel,radio") and ",ble" in text
    assert loads_slots_csv(text, frame).radio.tolist() == [1, 0, 1]
    old = "\n".join(line.rsplit(",", 1)[0] for line in text.splitlines())
    assert loads_slots_csv(old, frame).radio.tolist() == [0, 0, 0]
    assert "radio" not in dumps_slots_csv(_slots([0, 0]), frame).splitlines()[0]


def test_store_keeps_the_radio(tmp_path):
    from uavloc_gcs.service.store import Store, StoreReader

    with Store(tmp_path / "m.sqlite") as st:
        st.add_slots(_slots([1, 0, 1]))
    with StoreReader(tmp_path / "m.sqlite") as st:
        assert st.slots().radio.tolist() == [1, 0, 1]


def test_team_exclusion_on_ble_frames():
    """An OUI never matches a BLE random address; BLE frames without a Find My key (fingerprint 0)
    are never listed by fingerprint."""
    from uavloc_gcs.sense import parse_capture_bytes
    from uavloc_gcs.sense.exclusion import learn_team, loads_exclusion

    buf, truth = capture("phdr", 60, seed=9)
    frames, _ = parse_capture_bytes(buf)
    text = learn_team(frames, fingerprints=True)
    assert "fp 0x00000000" not in text
    public = frames.address[frames.random == 0]
    oui = f"{int(public[0]) >> 24:06x}"
    random_oui = f"{int(frames.address[frames.random == 1][0]) >> 24:06x}"
    assert len(loads_exclusion(text)) > 0  # what was learned reads back (0 is refused as a fingerprint)
    lists = loads_exclusion(f"oui {oui[:2]}:{oui[2:4]}:{oui[4:]}\noui {random_oui[:2]}:{random_oui[2:4]}:"
                            f"{random_oui[4:]}\n")
    team = lists.mask(frames)
    assert set(frames.address[team].tolist()) == {int(public[0])}
