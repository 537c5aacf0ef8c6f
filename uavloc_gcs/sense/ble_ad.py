"""Bluetooth LE advertising data: AD structures, Apple's Continuity messages, the Find My key.

AD structures (Bluetooth Core Specification Supplement, Part A, 1; Core v5.x Vol 3 Part C 11):
``length u8`` (of what follows: type and data), ``type u8``, data. A length of 0 ends the
significant part (what is left is padding). Every length is checked against the bytes left; one
that overruns is malformed (``ble_bad_ad``), unless the capture cut the frame short.

Manufacturer Specific Data (type 0xFF) starts with the 16-bit company identifier, little-endian;
Apple's is 0x004C. Apple packs one or more Continuity messages into it, each ``type u8, length u8,
body`` (furiousMAC/continuity, ``dissector/`` and ``messages/*.md``; Martin et al., "Handoff All
Your Privacy", PETS 2019). The types named here are theirs.

Find My offline finding (type 0x12; Heinrich et al., "Who Can Find My Devices?", PETS 2021;
furiousMAC/continuity ``messages/findmy.md``; seemoo-lab/openhaystack firmware,
``set_addr_from_key`` / ``fill_adv_template_from_key``): a lost or offline device advertises the
28-byte x coordinate of its current public key. Bytes 0-5 of the key are the advertiser address
(most significant octet first) with the top two bits of key byte 0 forced to 0b11 (a random static
address); the body is ``status u8, key[6:28] (22 bytes), key[0] >> 6 (u8), hint u8`` (25 bytes).
The short form (body of 2 bytes: status and the key bits, sent while the owner's devices are near)
carries no key. The key rotates, by public reverse-engineering notes about every 15 minutes
(furiousMAC/continuity findmy.md, the status byte's "current key rotation period (15 minutes)"),
and the address with it.

Content fingerprint of a BLE frame (``fingerprint`` in frames.csv and UAVLOC_RSSI_BATCH2): the
first 4 bytes, big-endian, of SHA-256 over the reconstructed 28-byte Find My key, or 0 (unknown)
when the frame carries none. It names one key, i.e. one device for one rotation period: what the
identity stage can use to tell two Find My devices apart under one address, and to find one key
heard by several vehicles. Other advertisements have no stable content that is known to be both
per-device and stable, so they get 0.
"""

from __future__ import annotations

import hashlib

from .radiotap import Malformed

AD_MANUFACTURER = 0xFF
APPLE_COMPANY_ID = 0x004C
FINDMY = 0x12
FINDMY_BODY_LEN = 25  # status, 22 key bytes, key bits, hint
FINDMY_KEY_LEN = 28

# Continuity message types (furiousMAC/continuity messages/*.md); 0x02 is iBeacon
APPLE_TYPES: dict[int, str] = {
    0x02: "ibeacon", 0x03: "airprint", 0x05: "airdrop", 0x06: "homekit", 0x07: "proximity_pairing",
    0x08: "hey_siri", 0x09: "airplay_target", 0x0A: "airplay_source", 0x0B: "magic_switch", 0x0C: "handoff",
    0x0D: "tethering_target", 0x0E: "tethering_source", 0x0F: "nearby_action", 0x10: "nearby_info",
    0x12: "findmy",
}

_CACHE: dict[tuple[int, bytes], tuple[int, int]] = {}
_CACHE_MAX = 65_536


def advertising_data(address: int, data: bytes, snapped: bool = False) -> tuple[int, int]:
    """(Apple Continuity type or -1, fingerprint or 0) of an advertiser's AD structures. Raises
    Malformed("ble_bad_ad") when a structure overruns the data (not when the capture cut it)."""
    key = (address, data)
    hit = _CACHE.get(key)
    if hit is not None:
        return hit
    apple = -1
    fp = 0
    n = len(data)
    pos = 0
    while pos < n:
        ln = data[pos]
        if ln == 0:
            break  # the rest is padding (Core Vol 3 Part C 11)
        end = pos + 1 + ln
        if end > n:
            if snapped:
                break
            raise Malformed("ble_bad_ad")
        if data[pos + 1] == AD_MANUFACTURER and ln >= 3 and data[pos + 2] | data[pos + 3] << 8 == APPLE_COMPANY_ID:
            a, f = _apple(address, data, pos + 4, end)
            if apple != FINDMY:
                apple = a if a >= 0 else apple
            fp = fp or f
        pos = end
    out = (apple, fp)
    if len(_CACHE) < _CACHE_MAX:
        _CACHE[key] = out
    return out


def _apple(address: int, data: bytes, pos: int, end: int) -> tuple[int, int]:
    """(type, fingerprint) of Apple's Continuity messages in data[pos:end]: Find My wins, else the
    first message's type. A message that overruns its structure is malformed."""
    first = -1
    while pos + 2 <= end:
        kind, ln = data[pos], data[pos + 1]
        body_end = pos + 2 + ln
        if body_end > end:
            raise Malformed("ble_bad_apple")
        if kind == FINDMY:
            key = findmy_key(address, data[pos + 2:body_end])
            return FINDMY, (_fingerprint(key) if key is not None else 0)
        if first < 0:
            first = kind
        pos = body_end
    return first, 0


def findmy_key(address: int, body: bytes) -> bytes | None:
    """The 28-byte public key of a Find My message body (type 0x12) heard from ``address`` (48-bit,
    most significant octet first), None for the short form."""
    if len(body) < FINDMY_BODY_LEN - 1:  # the hint byte is not part of the key
        return None
    top = ((address >> 40) & 0x3F) | ((body[23] & 0x03) << 6)
    return bytes([top]) + (address & 0xFFFFFFFFFF).to_bytes(5, "big") + bytes(body[1:23])


def _fingerprint(key: bytes) -> int:
    return int.from_bytes(hashlib.sha256(key).digest()[:4], "big") or 1


def apple_type_name(kind: int) -> str:
    """'findmy', 'nearby_info', ... ; '' for none, 'apple_0x..' for a type not named here."""
    if kind < 0:
        return ""
    return APPLE_TYPES.get(kind, f"apple_0x{kind:02x}")
