"""MAVLink 2 signature checking that verifies the signature before it touches the replay state.

pymavlink's generated ``MAVLink.check_signature`` records a packet's timestamp for its stream
*before* comparing the signature. A sender without the key can therefore send one packet with
any signature and a timestamp far in the future for (link id, system, component) of a real
vehicle, and every genuine packet of that vehicle afterwards is rejected as a replay: a one-packet
denial of service. The MAVLink signing rules update a stream's timestamp only for packets that
carry a valid signature; :func:`verify_signature_first` installs a check that does that.
"""

from __future__ import annotations

import hashlib
import struct
import types

NEW_STREAM_MAX_AGE = 6_000_000  # 10 us units: a new stream may be at most one minute behind us
_TIMESTAMP = struct.Struct("<IH")


def _check_signature(self, msgbuf: bytearray, srcSystem: int, srcComponent: int) -> bool:  # noqa: N803
    signing = self.signing
    digest = hashlib.sha256(signing.secret_key + bytes(msgbuf[:-6])).digest()[:6]
    if digest != bytes(msgbuf[-6:]):
        return False
    tlow, thigh = _TIMESTAMP.unpack(bytes(msgbuf[-12:-6]))
    timestamp = tlow + (thigh << 32)
    stream = (msgbuf[-13], srcSystem, srcComponent)
    last = signing.stream_timestamps.get(stream)
    if last is not None:
        if timestamp <= last:
            return False  # replayed or reordered
    elif timestamp + NEW_STREAM_MAX_AGE < signing.timestamp:
        return False  # a new stream from more than a minute ago
    signing.stream_timestamps[stream] = timestamp
    signing.timestamp = max(signing.timestamp, timestamp)
    return True


def verify_signature_first(codec):
    """Make ``codec`` (a generated ``MAVLink`` object) check signatures before replay state."""
    codec.check_signature = types.MethodType(_check_signature, codec)
    return codec
