"""802.11 management frames: the header fields and information elements a sensor needs.

A probe request (type 0, subtype 4) is what a phone sends unasked when it looks for networks: a
24-byte management header (frame control, duration, receiver, transmitter = the phone's address,
BSSID, sequence control), then information elements ``id u8, length u8, body``. Every element
length is checked against the bytes left; a frame whose elements overrun it is malformed (unless
the capture itself cut the frame short, where the complete elements are used).

Content fingerprint (what ``fingerprint`` means in UAVLOC_RSSI_BATCH2): the first 4 bytes,
big-endian, of SHA-256 over the probe request's elements in the order sent, each as ``id, length,
body``, leaving out the elements that change from frame to frame or band to band for one phone:

- SSID (0): the wildcard SSID or the name of a network the phone asks for; directed probes cycle
  through the phone's remembered networks, so their content and order vary per frame;
- DS Parameter Set (3): the channel the frame was sent on;
- Supported Rates (1) and Extended Supported Rates (50): differ between the 2.4 and 5 GHz bands for
  one phone (no 802.11b rates at 5 GHz);
- the body of vendor-specific elements (221) beyond their OUI and type: some carry counters or
  per-boot values (a Raspberry Pi in the public UJI/Brno captures sends vendor 00:50:f2 type 8 with
  a byte that changes from burst to burst, splitting one device into 8 fingerprints in a day), and
  WPS's UUID-E identifies the single device, not its model. Each kept as ``221, length, OUI, type``;
- the body of the FILS Request Parameters extension element (255 with extension id 2): its maximum
  channel time follows the scan being run (the same capture has phones switching between two values
  under one address). Kept as ``255, length, 2``.

What stays (HT/VHT/HE capabilities, extended capabilities, interworking, vendor elements and
above all their ORDER) is what Vanhoef et al. (AsiaCCS 2016) and Martin et al. (PETS 2017) showed
to be stable per device model and OS and distinctive between them, even when the address is
randomized; Pintor et al. (Computer Networks 2022) list the same fields as stable in their
labelled probe-request data set. 0 means unknown on the wire, so a hash of 0 becomes 1.
"""

from __future__ import annotations

import hashlib

from .radiotap import Malformed

MGMT = 0
PROBE_REQUEST = 4
HEADER_LEN = 24
VARYING_ELEMENTS = frozenset({0, 1, 3, 50})  # SSID, rates, DS parameter set, extended rates
FILS_REQUEST_PARAMETERS = 2  # extension element id

_FP_CACHE: dict[bytes, tuple[int, int]] = {}
_FP_CACHE_MAX = 65_536


def probe_fields(frame: bytes, snapped: bool) -> tuple[int, int, int, int] | None:
    """(source address, sequence number, fingerprint, DS channel) of a probe request, None for any
    other frame. Raises Malformed when the header or an element length does not fit."""
    if not frame:
        raise Malformed("short_80211")
    fc = frame[0]
    if (fc >> 2) & 3 != MGMT or fc >> 4 != PROBE_REQUEST or fc & 3:
        return None  # control frames (ACK, CTS: 10-16 bytes) are short by design, not malformed
    if len(frame) < HEADER_LEN:
        raise Malformed("short_80211")
    start = HEADER_LEN + (4 if frame[1] & 0x80 else 0)  # +HT Control when the Order bit is set
    address = int.from_bytes(frame[10:16], "big")
    seq = (frame[22] | frame[23] << 8) >> 4
    fp, ds = fingerprint_elements(frame[start:], snapped)
    return address, seq, fp, ds


def fingerprint_elements(ies: bytes, snapped: bool = False) -> tuple[int, int]:
    """(fingerprint, DS channel or 0) of a run of information elements. Raises Malformed."""
    hit = _FP_CACHE.get(ies)
    if hit is not None:
        return hit
    n = len(ies)
    pos = 0
    keep = []
    ds = 0
    while pos < n:
        if pos + 2 > n:
            if snapped:
                break
            raise Malformed("bad_element")
        eid = ies[pos]
        end = pos + 2 + ies[pos + 1]
        if end > n:
            if snapped:
                break
            raise Malformed("bad_element")
        if eid == 3 and end - pos == 3:
            ds = ies[pos + 2]
        elif eid == 221:
            keep.append(ies[pos:min(end, pos + 6)])  # id, length, OUI (3), vendor type (1)
        elif eid == 255 and end - pos >= 3 and ies[pos + 2] == FILS_REQUEST_PARAMETERS:
            keep.append(ies[pos:pos + 3])
        elif eid not in VARYING_ELEMENTS:
            keep.append(ies[pos:end])
        pos = end
    fp = int.from_bytes(hashlib.sha256(b"".join(keep)).digest()[:4], "big") or 1
    if len(_FP_CACHE) < _FP_CACHE_MAX:
        _FP_CACHE[ies] = (fp, ds)
    return fp, ds
