"""Synthetic Bluetooth LE captures built with scapy (not with uavloc's code), with their truth.

No public capture with Apple Find My frames under a licence that allows shipping it was found, so
the Apple cases are built here: each advertiser is a 48-bit address with a set of AD structures
(scapy's ``EIR_Hdr`` / ``EIR_Manufacturer_Specific_Data``), sent as a link-layer advertising PDU
(scapy's ``BTLE`` / ``BTLE_ADV``) behind the 256 pseudo-header (``BTLE_RF``) or the nRF Sniffer
event header (``NRF2_Packet_Event``), or as an HCI LE (Extended) Advertising Report (scapy's
``HCI_*`` layers) behind the 201 direction header or in a btsnoop file.

Two pieces are not scapy's: the nRF Sniffer's 7-byte UART header (scapy 2.8's ``NRFS2_Packet``
fails to build: its ``post_build`` reads a field it does not have) and the btsnoop container
(scapy has no btsnoop writer); both are a few struct fields, and the tests check these captures
against tshark's dissection where tshark is installed.

Find My (seemoo-lab/openhaystack, ``set_addr_from_key`` / ``fill_adv_template_from_key``): the
address is key[0:6] with the top two bits of key[0] set, the Apple message ``0x12, 0x19, status,
key[6:28], key[0] >> 6, hint``.
"""

from __future__ import annotations

import hashlib
import io
import struct
from dataclasses import dataclass

import numpy as np

APPLE = 0x004C


@dataclass(frozen=True)
class Adv:
    address: int
    random: bool
    pdu: int  # 0 ADV_IND, 2 ADV_NONCONN_IND, 4 SCAN_RSP, 6 ADV_SCAN_IND
    apple: int  # -1 none
    ad: bytes  # AD structures as scapy builds them
    fingerprint: int  # expected: sha256(key)[:4] for Find My, else 0
    key: bytes | None


def mac(address: int) -> str:
    return ":".join(f"{b:02x}" for b in address.to_bytes(6, "big"))


def _ad(apple_type: int | None, body: bytes) -> list:
    from scapy.layers.bluetooth import EIR_Flags, EIR_Hdr, EIR_Manufacturer_Specific_Data
    from scapy.packet import Raw

    out = [EIR_Hdr() / EIR_Flags(flags=["general_disc_mode", "br_edr_not_supported"])]
    if apple_type is not None:
        out.append(EIR_Hdr() / EIR_Manufacturer_Specific_Data(company_identifier=APPLE)
                   / Raw(bytes([apple_type, len(body)]) + body))
    return out


def advertisers(n: int, rng: np.random.Generator) -> list[Adv]:
    """n advertisers: Find My (separated, full key), Find My short form, nearby info, proximity
    pairing, handoff, nearby action, and a non-Apple one with a public address, in turn."""
    out = []
    for i in range(n):
        kind = i % 7
        key = None
        if kind == 0:  # Find My, full: the key's first 6 bytes are the address
            key = rng.integers(0, 256, 28, dtype=np.uint8).tobytes()
            address = int.from_bytes(bytes([key[0] | 0xC0]) + key[1:6], "big")
            apple, body = 0x12, bytes([rng.integers(0, 256)]) + key[6:28] + bytes([key[0] >> 6, 0])
        else:
            address = int(rng.integers(0, 2**48)) | (0xC0 << 40 if kind != 6 else 0)
            apple, body = {1: (0x12, bytes([0x00, 0x02])), 2: (0x10, bytes([0x07, 0x1C, 0x11, 0x22, 0x33])),
                           3: (0x07, bytes(25)), 4: (0x0C, bytes(14)), 5: (0x0F, bytes([0x00, 0x09, 1, 2, 3])),
                           6: (None, b"")}[kind]
        ad = b"".join(bytes(p) for p in _ad(apple, body))
        fp = int.from_bytes(hashlib.sha256(key).digest()[:4], "big") or 1 if key is not None else 0
        pdu = (2, 0, 6, 4)[i % 4]
        out.append(Adv(address, kind != 6, pdu, -1 if apple is None else apple, ad, fp, key))
    return out


def _ll(adv: Adv):
    from scapy.layers.bluetooth import EIR_Hdr
    from scapy.layers.bluetooth4LE import (BTLE, BTLE_ADV, BTLE_ADV_IND, BTLE_ADV_NONCONN_IND, BTLE_ADV_SCAN_IND,
                                           BTLE_SCAN_RSP)

    cls = {0: BTLE_ADV_IND, 2: BTLE_ADV_NONCONN_IND, 4: BTLE_SCAN_RSP, 6: BTLE_ADV_SCAN_IND}[adv.pdu]
    return BTLE() / BTLE_ADV(TxAdd=int(adv.random)) / cls(AdvA=mac(adv.address),
                                                          data=[EIR_Hdr(e) for e in _split(adv.ad)])


def _split(ad: bytes) -> list[bytes]:
    out, pos = [], 0
    while pos < len(ad):
        out.append(ad[pos:pos + 1 + ad[pos]])
        pos += 1 + ad[pos]
    return out


@dataclass
class Truth:
    t_s: np.ndarray
    adv: list  # Adv per frame
    rssi_dbm: np.ndarray
    channel: np.ndarray


def capture(kind: str, n_frames: int, *, n_adv: int = 14, seed: int = 0) -> tuple[bytes, Truth]:
    """A capture of ``kind`` ('phdr' 256, 'nordic' 272, 'hci' 201 legacy reports, 'hci_ext' 201
    extended reports, 'btsnoop' H4 btsnoop) with n_frames frames, and the truth per frame."""
    from scapy.contrib.nrf_sniffer import NRF2_Packet_Event
    from scapy.layers.bluetooth import (HCI_Event_Hdr, HCI_Event_LE_Meta, HCI_Hdr, HCI_LE_Meta_Advertising_Report,
                                        HCI_LE_Meta_Advertising_Reports, HCI_LE_Meta_Extended_Advertising_Report,
                                        HCI_LE_Meta_Extended_Advertising_Reports, HCI_PHDR_Hdr)
    from scapy.layers.bluetooth4LE import BTLE_RF
    from scapy.packet import Raw
    from scapy.utils import PcapWriter

    rng = np.random.default_rng(seed)
    advs = advertisers(n_adv, rng)
    t0 = 1_700_000_000.0
    t = t0 + np.cumsum(rng.uniform(0.001, 0.05, n_frames))
    t = np.round(t * 1e6) / 1e6
    which = rng.integers(0, len(advs), n_frames)
    rssi = rng.integers(-100, -30, n_frames)
    channel = rng.choice([37, 38, 39], n_frames)
    rf = {37: 0, 38: 12, 39: 39}
    pkts = []
    for k in range(n_frames):
        a = advs[which[k]]
        if kind == "phdr":
            p = BTLE_RF(rf_channel=rf[int(channel[k])], signal=int(rssi[k]), dewhitened=1, sig_power_valid=1,
                        crc_checked=1, crc_valid=1) / _ll(a)
        elif kind == "nordic":  # scapy's rssi field holds the byte: the sniffer sends -RSSI
            ev = bytes(NRF2_Packet_Event(rf_channel=int(channel[k]), rssi=-int(rssi[k]), crc_ok=1, phy=0) / _ll(a))
            p = struct.pack("<BHBHB", 0, len(ev), 3, k & 0xFFFF, 0x02) + ev
        else:
            from scapy.layers.bluetooth import EIR_Hdr

            hci_type = {0: 0, 2: 3, 4: 4, 6: 2}[a.pdu]
            data = [EIR_Hdr(e) for e in _split(a.ad)]
            if kind == "hci_ext":
                ext_type = {0: 0x13, 2: 0x10, 4: 0x1B, 6: 0x12}[a.pdu]
                rep = HCI_LE_Meta_Extended_Advertising_Reports(reports=[HCI_LE_Meta_Extended_Advertising_Report(
                    connectable=ext_type & 1, scannable=ext_type >> 1 & 1, scan_response=ext_type >> 3 & 1, legacy=1,
                    addr_type=int(a.random), addr=mac(a.address), primary_phy=1, rssi=int(rssi[k]), data=data)])
            else:
                rep = HCI_LE_Meta_Advertising_Reports(reports=[HCI_LE_Meta_Advertising_Report(
                    type=hci_type, addr_type=int(a.random), addr=mac(a.address), data=data, rssi=int(rssi[k]))])
            p = HCI_Hdr() / HCI_Event_Hdr() / HCI_Event_LE_Meta() / rep
            if kind != "btsnoop":
                p = HCI_PHDR_Hdr(direction=1) / p
        pkts.append(bytes(p))
    if kind in ("hci", "hci_ext", "btsnoop"):
        channel = np.zeros(n_frames, dtype=int)  # HCI reports carry no channel
    truth = Truth(t, [advs[i] for i in which], rssi, channel)
    if kind == "btsnoop":
        return btsnoop(pkts, t), truth
    buf = io.BytesIO()
    w = PcapWriter(buf, linktype={"phdr": 256, "nordic": 272}.get(kind, 201), sync=True)
    w.write_header(None)
    for p, tk in zip(pkts, t):
        w.write_packet(Raw(p), sec=int(tk), usec=int(round((tk % 1) * 1e6)))
    w.flush()
    return buf.getvalue(), truth


def btsnoop(packets: list[bytes], t_s, *, datalink: int = 1002) -> bytes:
    """A btsnoop file (version 1; 1002 H4 packets as given, 1001 H1 with the H4 type byte left off
    and put in the flags) of received packets (commands: sent)."""
    out = [b"btsnoop\0", struct.pack(">II", 1, datalink)]
    for p, t in zip(packets, t_s):
        us = int(round(t * 1e6)) + 0x00DCDDB30F2F8000
        body, flags = p, 1
        if datalink == 1001:
            flags = (0 if p[0] == 1 else 1) | (2 if p[0] in (1, 4) else 0)  # a command is sent, not received
            body = p[1:]
        out.append(struct.pack(">IIIIq", len(body), len(body), flags, 0, us) + body)
    return b"".join(out)
