"""Bluetooth LE captures built with scapy (ble_captures.py): every link type, frame by frame against
the truth they were built from, scapy's own dissection and tshark's (when installed); Apple
Continuity types and the Find My key; HCI corner cases."""

import hashlib
import io
import shutil
import subprocess

import numpy as np
import pytest

from uavloc_gcs.sense import parse_capture_bytes
from uavloc_gcs.sense.ble_ad import FINDMY, advertising_data, findmy_key

from .ble_captures import btsnoop, capture, mac

KINDS = ("phdr", "nordic", "hci", "hci_ext", "btsnoop")


@pytest.fixture(scope="module")
def captures():
    return {k: capture(k, 120, seed=3) for k in KINDS}


@pytest.mark.parametrize("kind", KINDS)
def test_every_frame_matches_the_truth_it_was_built_from(kind, captures):
    buf, truth = captures[kind]
    f, skips = parse_capture_bytes(buf)
    assert len(f) == 120 and skips.summary() == "none"
    np.testing.assert_allclose(f.t_s, truth.t_s, atol=1e-6)
    assert f.address.tolist() == [a.address for a in truth.adv]
    assert f.rssi_dbm.tolist() == truth.rssi_dbm.tolist()
    assert f.channel.tolist() == truth.channel.tolist()
    assert f.pdu.tolist() == [a.pdu for a in truth.adv]
    assert f.random.tolist() == [int(a.random) for a in truth.adv]
    assert f.apple.tolist() == [a.apple for a in truth.adv]
    assert f.fingerprint.tolist() == [a.fingerprint for a in truth.adv]
    assert set(f.radio.tolist()) == {1}
    assert {0x12, 0x10, 0x07, 0x0C, 0x0F, -1} == set(f.apple.tolist())


def _scapy_fields(kind: str, buf: bytes):
    """(address, rssi, channel, apple type) per frame as scapy dissects the capture."""
    from scapy.layers.bluetooth import EIR_Manufacturer_Specific_Data, HCI_Hdr, HCI_PHDR_Hdr
    from scapy.layers.bluetooth4LE import BTLE, BTLE_RF
    from scapy.utils import RawPcapReader

    assert kind in ("phdr", "hci", "hci_ext")
    out = []
    for raw, _ in RawPcapReader(io.BytesIO(buf)):
        p = BTLE_RF(raw) if kind == "phdr" else HCI_PHDR_Hdr(raw)
        if kind == "phdr":
            adv = p[BTLE].payload.payload
            addr, rssi = adv.AdvA, p.signal
            ch = {0: 37, 12: 38, 39: 39}[p.rf_channel]
        else:
            rep = p[HCI_Hdr].reports[0]
            addr, rssi, ch = rep.addr, rep.rssi, 0
        msd = p.getlayer(EIR_Manufacturer_Specific_Data)
        apple = bytes(msd.payload)[0] if msd is not None and msd.company_identifier == 0x004C else -1
        out.append((int(addr.replace(":", ""), 16), rssi, ch, apple))
    return out


@pytest.mark.parametrize("kind", ("phdr", "hci", "hci_ext"))
def test_every_frame_matches_scapys_dissection(kind, captures):
    buf, _ = captures[kind]
    f, _ = parse_capture_bytes(buf)
    assert list(zip(f.address.tolist(), f.rssi_dbm.tolist(), f.channel.tolist(), f.apple.tolist())) == \
        _scapy_fields(kind, buf)


TSHARK_FIELDS = ("btle.advertising_address", "bthci_evt.bd_addr", "btle_rf.signal_dbm", "nordic_ble.rssi",
                 "bthci_evt.rssi", "btle_rf.channel", "nordic_ble.channel", "btcommon.eir_ad.entry.company_id",
                 "btcommon.eir_ad.entry.data")


@pytest.mark.skipif(shutil.which("tshark") is None, reason="tshark not installed")
@pytest.mark.parametrize("kind", KINDS)
def test_every_frame_matches_tsharks_dissection(kind, captures, tmp_path):
    """tshark (Wireshark's packet-btle_rf.c, packet-nordic_ble.c, packet-bthci_evt.c) reads the
    same address, RSSI, channel and Apple message type as uavloc."""
    buf, _ = captures[kind]
    path = tmp_path / f"{kind}.cap"
    path.write_bytes(buf)
    cmd = ["tshark", "-r", str(path), "-T", "fields", "-E", "separator=|", "-E", "aggregator=;"]
    out = subprocess.run(cmd + [a for f in TSHARK_FIELDS for a in ("-e", f)], capture_output=True, text=True,
                         check=True, timeout=120).stdout.splitlines()
    f, _ = parse_capture_bytes(buf)
    assert len(out) == len(f)
    for k, line in enumerate(out):
        ll_addr, hci_addr, rf_sig, nrf_rssi, hci_rssi, rf_ch, nrf_ch, company, data = line.split("|")
        assert f.address[k] == int((ll_addr or hci_addr).replace(":", ""), 16)
        assert f.rssi_dbm[k] == int(rf_sig or nrf_rssi or hci_rssi)
        if rf_ch:
            assert f.channel[k] == {0: 37, 12: 38, 39: 39}[int(rf_ch)]
        elif nrf_ch:
            assert f.channel[k] == int(nrf_ch)
        entries = dict(zip(company.split(";"), data.split(";")[-len(company.split(";")):])) if company else {}
        apple = entries.get("0x004c")
        assert f.apple[k] == (int(apple[:2], 16) if apple else -1)


def test_findmy_key_is_rebuilt_from_address_and_payload():
    """The 28-byte key: the address with its top two bits from the payload's key-bits byte, then
    the 22 payload bytes (openhaystack's set_addr_from_key / fill_adv_template_from_key reversed)."""
    key = bytes(range(0x81, 0x81 + 28))  # top bits 0b10
    address = int.from_bytes(bytes([key[0] | 0xC0]) + key[1:6], "big")
    body = bytes([0x04]) + key[6:] + bytes([key[0] >> 6, 0x00])
    assert findmy_key(address, body) == key
    assert findmy_key(address, bytes([0x00, 0x02])) is None  # the short form carries no key
    ad = bytes([30, 0xFF, 0x4C, 0x00, 0x12, 25]) + body
    apple, fp = advertising_data(address, ad)
    assert apple == FINDMY and fp == int.from_bytes(hashlib.sha256(key).digest()[:4], "big")


def test_apple_message_list_prefers_findmy_and_names_others():
    from uavloc_gcs.sense.ble_ad import apple_type_name

    nearby_then_handoff = bytes([0x10, 2, 1, 2, 0x0C, 1, 0])
    ad = bytes([3 + len(nearby_then_handoff), 0xFF, 0x4C, 0x00]) + nearby_then_handoff
    assert advertising_data(1, ad) == (0x10, 0)
    assert [apple_type_name(t) for t in (0x12, 0x07, 0x10, 0x0C, 0x0F, 0x55, -1)] == [
        "findmy", "proximity_pairing", "nearby_info", "handoff", "nearby_action", "apple_0x55", ""]


def _hci_event(reports: bytes, n: int, sub: int = 0x02) -> bytes:
    body = bytes([sub, n]) + reports
    return bytes([0x04, 0x3E, len(body)]) + body


def test_hci_reports_without_rssi_or_address_and_several_per_event():
    """Verified against scapy: a legacy event with three reports (one with RSSI 127, 'not
    available'), and an extended report from an anonymous advertiser (address type 0xFF)."""
    from scapy.layers.bluetooth import HCI_Hdr, HCI_LE_Meta_Advertising_Report

    reps = [HCI_LE_Meta_Advertising_Report(type=0, addr_type=1, addr=mac(0xC1 << 40 | k), data=[], rssi=r)
            for k, r in ((1, -40), (2, 127), (3, -90))]
    ev = _hci_event(b"".join(bytes(r) for r in reps), 3)
    assert [r.rssi for r in HCI_Hdr(ev).reports] == [-40, 127, -90]
    f, skips = parse_capture_bytes(btsnoop([ev], [1.0]))
    assert f.address.tolist() == [0xC1 << 40 | 1, 0xC1 << 40 | 3] and f.rssi_dbm.tolist() == [-40, -90]
    anon = bytes([0x10, 0x00, 0xFF]) + bytes(6) + bytes([1, 0, 0xFF, 0x7F, 0xC4, 0, 0, 0]) + bytes(6) + b"\0"
    f, skips = parse_capture_bytes(btsnoop([_hci_event(anon, 1, 0x0D)], [1.0]))
    assert len(f) == 0 and skips.reasons == {"no_signal": 1}


def test_btsnoop_h1_puts_the_type_byte_back_and_skips_commands():
    buf, truth = capture("btsnoop", 10, seed=5)
    from uavloc_gcs.sense.capture import read_records, ReadStats

    pkts = [r[2] for r in read_records(buf, ReadStats())]
    command = bytes([0x01, 0x0C, 0x20, 0x02, 0x01, 0x00])  # HCI_LE_Set_Scan_Enable
    h1 = btsnoop([command] + pkts, np.concatenate([[truth.t_s[0] - 1], truth.t_s]), datalink=1001)
    f, skips = parse_capture_bytes(h1)
    assert f.address.tolist() == [a.address for a in truth.adv] and skips.reasons == {"not_advertising": 1}
    np.testing.assert_allclose(f.t_s, truth.t_s, atol=1e-6)


def test_extended_pdu_with_adva_on_a_secondary_channel():
    """AUX_ADV_IND (PDU type 7) with AdvA and ADI in its extended header (tshark 4.0.17 reads this
    frame as AUX_COMMON from 11:22:33:44:55:66, random, -61 dBm, RF channel 5 = data channel 4); an
    ADV_EXT_IND without AdvA (a pointer to the auxiliary packet) is counted as no_address."""
    from uavloc_gcs.sense.ble import adverts

    addr = bytes.fromhex("665544332211")  # on air: little-endian, i.e. 11:22:33:44:55:66
    ad = bytes([2, 0x01, 0x06])
    ext = bytes([0x01 | 0x08]) + addr + bytes([0x34, 0x12])  # flags AdvA|ADI, AdvA, ADI
    payload = bytes([len(ext)]) + ext + ad
    pdu = bytes.fromhex("d6be898e") + bytes([0x47, len(payload)]) + payload + b"\0\0\0"
    phdr = bytes([5, (-61) & 0xFF, 0x80, 0, 0, 0, 0, 0, 0x03, 0x00])  # RF 5 = channel index 4
    assert adverts(256, phdr + pdu, False) == [(0x112233445566, True, -61, 4, 7, -1, 0)]
    pointer = bytes([0x08 | 0x10]) + bytes([0x34, 0x12]) + bytes(3)  # flags ADI|AuxPtr, ADI, AuxPtr
    pointer = bytes([len(pointer)]) + pointer
    pdu = bytes.fromhex("d6be898e") + bytes([0x07, len(pointer)]) + pointer + b"\0\0\0"
    assert adverts(256, phdr + pdu, False) == "no_address"
