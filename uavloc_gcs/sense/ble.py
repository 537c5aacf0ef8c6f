"""Bluetooth LE advertising from capture records: sniffer link layers and HCI advertising reports.

:func:`adverts` turns one record into the advertisements it carries, each
``(address, random, rssi_dbm, channel, pdu, apple_type, fingerprint)``: the advertiser address
(AdvA) as a 48-bit integer, most significant octet first as it is written (on air it is
little-endian); whether it is a random address (TxAdd, or the HCI address type); the RSSI [dBm];
the advertising channel index (37, 38, 39; 0-36 for secondary channels; 0 when the source does not
say); the link-layer PDU type (:data:`PDU_NAMES`); and what :mod:`.ble_ad` reads from the AD
structures. A record that is not an advertisement gives a reason string (counted, benign), a broken
one raises :class:`~.radiotap.Malformed` (counted by reason). Never anything else: every length is
checked against what is left before it is used. An HCI event may carry several reports; reports
without an address or RSSI are left out, and the record is counted (``no_signal``) only when none
is left.

Link types (tcpdump.org/linktypes.html; Wireshark's dissectors named):

- 251 LINKTYPE_BLUETOOTH_LE_LL: access address (4, LE), PDU header (2), payload, CRC (3). No
  signal level: counted as ``no_signal``.
- 256 LINKTYPE_BLUETOOTH_LE_LL_WITH_PHDR (Ubertooth, libbtbb; Wireshark packet-btle_rf.c): a
  10-byte little-endian pseudo-header ``rf_channel u8, signal_power s8 [dBm], noise_power s8,
  access_address_offenses u8, reference_access_address u32, flags u16`` then the 251 packet.
  Flags: 0x0001 dewhitened, 0x0002 signal power valid, 0x0400 CRC checked, 0x0800 CRC valid.
  ``rf_channel`` is the RF channel (2402 + 2k MHz), mapped to the channel index (RF 0 = 37,
  RF 12 = 38, RF 39 = 39; Core v5.x Vol 6 Part A 2).
- 272 LINKTYPE_NORDIC_BLE (nRF Sniffer for Bluetooth LE; Wireshark packet-nordic_ble.c): board id
  u8; protocol version 1: header length u8, payload length u8, version u8; version 2 and later
  (nRF Sniffer 3.x/4.x): payload length u16 LE, version u8; then packet counter u16, packet id u8,
  and at offset 7 the event packet: header length u8 (10), flags u8 (bit 0 CRC ok, bits 4-6 PHY:
  0 1M, 1 2M, 2 Coded), channel index u8, RSSI u8 as its negation (-RSSI), event counter u16, time
  u32, then the link-layer packet from the access address (on the Coded PHY a coding indicator
  byte follows the access address). Frames starting 0xBEEF (the 2015 0.9.7 format) are counted,
  not read (``nordic_legacy``).
- 201 LINKTYPE_BLUETOOTH_HCI_H4_WITH_PHDR: direction u32 BE, then an H4 packet; 187
  LINKTYPE_BLUETOOTH_HCI_H4 (btsnoop files, see :mod:`.capture`) the H4 packet alone. H4 type 0x04
  is an HCI event (Core v5.x Vol 4 Part A 2): ``code u8, length u8, parameters``. LE Meta (0x3E)
  subevent 0x02, LE Advertising Report (Vol 4 Part E 7.7.65.2): ``num_reports u8`` then per report
  ``event_type u8, address_type u8, address[6] LE, data_length u8, data, rssi s8`` (127: not
  available), read report after report as Wireshark's packet-bthci_evt.c and BlueZ do. Subevent
  0x0D, LE Extended Advertising Report (7.7.65.13): per report ``event_type u16, address_type u8,
  address[6], primary_phy u8, secondary_phy u8, sid u8, tx_power s8, rssi s8, periodic_interval
  u16, direct_address_type u8, direct_address[6], data_length u8, data``. HCI reports carry no
  channel (0).
- 147 LINKTYPE_USER0, uavloc's record of a live scan result (:mod:`.ble_live`): ``address[6] BE,
  random u8, rssi s8, AD structures`` (what BlueZ hands on, without a PDU: pdu -1).
"""

from __future__ import annotations

from .ble_ad import advertising_data
from .radiotap import Malformed

LINKTYPE_BLUETOOTH_HCI_H4 = 187
LINKTYPE_BLUETOOTH_HCI_H4_WITH_PHDR = 201
LINKTYPE_BLUETOOTH_LE_LL = 251
LINKTYPE_BLUETOOTH_LE_LL_WITH_PHDR = 256
LINKTYPE_NORDIC_BLE = 272
LINKTYPE_UAVLOC_BLE_SCAN = 147  # LINKTYPE_USER0: private to uavloc's live scanner
BLE_LINKTYPES = frozenset({LINKTYPE_BLUETOOTH_HCI_H4, LINKTYPE_BLUETOOTH_HCI_H4_WITH_PHDR, LINKTYPE_BLUETOOTH_LE_LL,
                           LINKTYPE_BLUETOOTH_LE_LL_WITH_PHDR, LINKTYPE_NORDIC_BLE, LINKTYPE_UAVLOC_BLE_SCAN})

ADVERTISING_ACCESS_ADDRESS = 0x8E89BED6  # Core v5.x Vol 6 Part B 2.1.2
ADV_IND, ADV_DIRECT_IND, ADV_NONCONN_IND, SCAN_REQ, SCAN_RSP, CONNECT_IND, ADV_SCAN_IND, ADV_EXT = range(8)
PDU_NAMES = {ADV_IND: "ADV_IND", ADV_DIRECT_IND: "ADV_DIRECT_IND", ADV_NONCONN_IND: "ADV_NONCONN_IND",
             SCAN_RSP: "SCAN_RSP", ADV_SCAN_IND: "ADV_SCAN_IND", ADV_EXT: "ADV_EXT"}
# HCI legacy report event types (Vol 4 Part E 7.7.65.2) -> link-layer PDU types
_HCI_LEGACY_PDU = {0: ADV_IND, 1: ADV_DIRECT_IND, 2: ADV_SCAN_IND, 3: ADV_NONCONN_IND, 4: SCAN_RSP}
# extended report event types with the legacy bit (7.7.65.13, table of legacy values)
_HCI_EXT_LEGACY_PDU = {0x13: ADV_IND, 0x15: ADV_DIRECT_IND, 0x12: ADV_SCAN_IND, 0x10: ADV_NONCONN_IND,
                       0x1B: SCAN_RSP, 0x1A: SCAN_RSP}
HCI_RSSI_UNAVAILABLE = 127
PHDR_DEWHITENED, PHDR_SIGNAL_VALID, PHDR_CRC_CHECKED, PHDR_CRC_VALID = 0x0001, 0x0002, 0x0400, 0x0800
NORDIC_CODED_PHY = 2

Advert = tuple[int, bool, int, int, int, int, int]


def rf_to_channel_index(rf: int) -> int:
    """Channel index (0-39) of an RF channel (0-39, 2402 + 2 rf MHz)."""
    if rf == 0:
        return 37
    if rf == 12:
        return 38
    if rf == 39:
        return 39
    return rf - 1 if rf < 12 else rf - 2


def adverts(linktype: int, data: bytes, snapped: bool) -> list[Advert] | str:
    """The advertisements of one record, or a benign reason; raises Malformed (see module doc)."""
    if linktype == LINKTYPE_BLUETOOTH_LE_LL_WITH_PHDR:
        return _phdr(data, snapped)
    if linktype == LINKTYPE_NORDIC_BLE:
        return _nordic(data, snapped)
    if linktype == LINKTYPE_BLUETOOTH_HCI_H4_WITH_PHDR:
        if len(data) < 4:
            raise Malformed("short_hci")
        return _h4(data, 4, snapped)
    if linktype == LINKTYPE_BLUETOOTH_HCI_H4:
        return _h4(data, 0, snapped)
    if linktype == LINKTYPE_BLUETOOTH_LE_LL:
        return "no_signal"  # the link layer alone carries no signal level
    if linktype == LINKTYPE_UAVLOC_BLE_SCAN:
        return _scan(data)
    return "not_ble"


def _phdr(data: bytes, snapped: bool) -> list[Advert] | str:
    if len(data) < 10:
        raise Malformed("short_ble_phdr")
    flags = data[8] | data[9] << 8
    if flags & PHDR_CRC_CHECKED and not flags & PHDR_CRC_VALID:
        raise Malformed("bad_crc")
    if not flags & PHDR_DEWHITENED:
        raise Malformed("ble_whitened")
    got = _ll(data, 10, snapped, rf_to_channel_index(data[0]) if data[0] < 40 else 0, False)
    if isinstance(got, str):
        return got
    if not flags & PHDR_SIGNAL_VALID:
        return "no_signal"
    rssi = data[1] - 256 if data[1] > 127 else data[1]
    return [(got[0], got[1], rssi, got[2], got[3], got[4], got[5])]


def _nordic(data: bytes, snapped: bool) -> list[Advert] | str:
    n = len(data)
    if n >= 2 and data[0] == 0xBE and data[1] == 0xEF:
        raise Malformed("nordic_legacy")
    if n < 17:
        raise Malformed("short_nordic")
    version = data[3]
    total = 1 + data[1] + data[2] if version == 1 else 7 + (data[1] | data[2] << 8)
    if version == 0 or version > 3:
        raise Malformed("nordic_version")
    if total != n and not (snapped and total > n):
        raise Malformed("nordic_bad_length")
    event_len = data[7]
    if event_len < 10:
        raise Malformed("nordic_bad_length")
    flags = data[8]
    if not flags & 1:
        raise Malformed("bad_crc")
    channel = data[9]
    got = _ll(data, 7 + event_len, snapped, channel if channel < 40 else 0, (flags >> 4) & 7 == NORDIC_CODED_PHY)
    if isinstance(got, str):
        return got
    return [(got[0], got[1], -data[10], got[2], got[3], got[4], got[5])]


def _ll(data: bytes, pos: int, snapped: bool, channel: int, coded: bool):
    """(address, random, channel, pdu, apple, fingerprint) of the advertising-channel PDU at
    ``pos`` (access address first), or a benign reason. Raises Malformed."""
    n = len(data)
    if pos + 6 + coded > n:
        raise Malformed("short_ble")
    if int.from_bytes(data[pos:pos + 4], "little") != ADVERTISING_ACCESS_ADDRESS:
        return "not_advertising"  # a data-channel PDU of a connection
    pos += 4 + coded  # on the Coded PHY the coding indicator follows the access address
    head, length = data[pos], data[pos + 1]
    pdu, random = head & 0x0F, bool(head & 0x40)
    start, end = pos + 2, pos + 2 + length  # the CRC (3 bytes) may follow; it is not read
    if end > n:
        if not snapped:
            raise Malformed("ble_bad_length")
        end = n
    if pdu in (ADV_IND, ADV_NONCONN_IND, ADV_SCAN_IND, SCAN_RSP, ADV_DIRECT_IND):
        if end - start < 6:
            raise Malformed("ble_bad_length")
        address = int.from_bytes(data[start:start + 6], "little")
        ad = data[start + 6:end] if pdu != ADV_DIRECT_IND else b""  # ADV_DIRECT_IND: TargetA, no data
    elif pdu == ADV_EXT:
        got = _extended(data, start, end)
        if got is None:
            return "no_address"  # ADV_EXT_IND on a primary channel: a pointer to the AUX_ADV_IND
        address, ad = got
    else:
        return "not_advertising"  # SCAN_REQ, CONNECT_IND: a scanner's or initiator's PDU
    apple, fp = advertising_data(address, ad, snapped)
    return address, random, channel, pdu, apple, fp


# sizes of the extended header's optional fields, in flag-bit order (Core v5.x Vol 6 Part B 2.3.4):
# AdvA, TargetA, CTEInfo, ADI, AuxPtr, SyncInfo, TxPower
_EXT_FIELDS = (6, 6, 1, 2, 3, 18, 1)


def _extended(data: bytes, start: int, end: int) -> tuple[int, bytes] | None:
    """(AdvA, AdvData) of a Common Extended Advertising Payload, None when it has no AdvA."""
    if end - start < 1:
        raise Malformed("ble_bad_length")
    hlen = data[start] & 0x3F
    body = start + 1
    if hlen == 0 or body + hlen > end:
        if body + hlen > end:
            raise Malformed("ble_bad_ext_header")
        return None
    flags = data[body]
    if not flags & 1:
        return None
    if hlen < 7:
        raise Malformed("ble_bad_ext_header")
    address = int.from_bytes(data[body + 1:body + 7], "little")
    need = 1 + sum(size for bit, size in enumerate(_EXT_FIELDS) if flags >> bit & 1)
    if need > hlen:
        raise Malformed("ble_bad_ext_header")
    return address, data[body + hlen:end]


def _h4(data: bytes, pos: int, snapped: bool) -> list[Advert] | str:
    n = len(data)
    if pos + 3 > n:
        if pos < n and data[pos] != 0x04:
            return "not_advertising"
        raise Malformed("short_hci")
    if data[pos] != 0x04:
        return "not_advertising"  # commands, ACL and ISO data
    code, plen = data[pos + 1], data[pos + 2]
    end = pos + 3 + plen
    if end > n:
        if not snapped:
            raise Malformed("hci_bad_length")
        end = n
    if code != 0x3E or end - pos < 5:
        return "not_advertising"
    sub = data[pos + 3]
    if sub == 0x02:
        return _reports(data, pos + 4, end, snapped, extended=False)
    if sub == 0x0D:
        return _reports(data, pos + 4, end, snapped, extended=True)
    return "not_advertising"


def _reports(data: bytes, pos: int, end: int, snapped: bool, extended: bool) -> list[Advert] | str:
    count = data[pos]
    pos += 1
    out: list[Advert] = []
    fixed = 24 if extended else 9  # bytes of a report besides its data (the RSSI included)
    for _ in range(count):
        if pos + fixed > end:
            if snapped and out:
                break
            raise Malformed("hci_bad_report")
        if extended:
            etype = data[pos] | data[pos + 1] << 8
            atype = data[pos + 2]
            address = int.from_bytes(data[pos + 3:pos + 9], "little")
            dlen = data[pos + 23]
            dstart = pos + 24
            next_pos = dstart + dlen
        else:
            etype, atype = data[pos], data[pos + 1]
            address = int.from_bytes(data[pos + 2:pos + 8], "little")
            dlen = data[pos + 8]
            dstart = pos + 9
            next_pos = dstart + dlen + 1  # the RSSI follows the data
        if next_pos > end:
            raise Malformed("hci_bad_report")
        if extended:
            rssi = data[pos + 13]
            pdu = _HCI_EXT_LEGACY_PDU.get(etype & 0x1F, ADV_IND) if etype & 0x10 else ADV_EXT
        else:
            rssi = data[next_pos - 1]
            pdu = _HCI_LEGACY_PDU.get(etype, -1)
        pos = next_pos
        if atype == 0xFF or rssi == HCI_RSSI_UNAVAILABLE:
            continue  # anonymous advertising (no address), or no RSSI: the record counts once if none is left
        apple, fp = advertising_data(address, data[dstart:dstart + dlen], snapped)
        out.append((address, bool(atype & 1), rssi - 256 if rssi > 127 else rssi, 0, pdu, apple, fp))
    return out if out else "no_signal"


def _scan(data: bytes) -> list[Advert]:
    if len(data) < 8:
        raise Malformed("short_ble_scan")
    address = int.from_bytes(data[:6], "big")
    apple, fp = advertising_data(address, data[8:])
    rssi = data[7] - 256 if data[7] > 127 else data[7]
    return [(address, bool(data[6]), rssi, 0, -1, apple, fp)]
