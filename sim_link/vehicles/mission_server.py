"""The vehicle side of the MAVLink mission protocol, ArduPilot-like or PX4-like.

A pure state machine: :meth:`MissionServer.handle` takes one decoded message (with who sent it
and the wall-clock time) and returns the replies; :meth:`MissionServer.tick` returns the re-sent
requests and timeouts that are due. Sockets, codecs and clocks belong to the caller.

Behaviour per flavour (``reference/mavlink.md`` §1.2-§1.11):

* upload: MISSION_COUNT -> requests (MISSION_REQUEST on ArduPilot, MISSION_REQUEST_INT on PX4),
  re-sent every 1 s / 250 ms until the item arrives; given up after 8 s (ArduPilot answers
  MAV_MISSION_OPERATION_CANCELLED and says "Mission upload timeout") / 5 s (PX4, silently).
  Out-of-sequence items: ArduPilot NACKs with MAV_MISSION_INVALID_SEQUENCE and keeps going; PX4
  ignores them. ArduPilot truncates the stored mission to ``count`` at the start and writes each
  item in place (a failed upload leaves a mix of old and new); PX4 keeps the old plan until the new
  one is complete. A duplicate of the last item after completion is re-ACKed.
* validation: unknown commands -> MAV_MISSION_UNSUPPORTED; PX4 accepts global frames 0/3/5/6
  for positional items and MAV_FRAME_MISSION only for the others (else UNSUPPORTED / UNSUPPORTED_FRAME);
  ArduPilot rejects NaN except in param4 of WAYPOINT/LAND/TAKEOFF (INVALID_PARAMn), infinities,
  lat/lon out of range (INVALID_PARAM5_X / 6_Y) and bad altitudes (INVALID_PARAM7).
* download: MISSION_REQUEST_LIST -> MISSION_COUNT; MISSION_REQUEST_INT -> MISSION_ITEM_INT;
  the legacy MISSION_REQUEST is answered with a float MISSION_ITEM (ArduPilot also warns).
  ArduPilot's item 0 is always the current home; its downloads use the non-INT frame numbers.
  With ``Flavour.strict_download_order`` (real PX4; off by default) only the next item or a repeat
  of the previous one is served and any other request aborts the download (MAV_MISSION_ERROR).
* clear: MISSION_CLEAR_ALL -> MISSION_ACK(ACCEPTED).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Callable

from uavloc_gcs.dialect import mavlink as mav
from uavloc_gcs.mission import WireItem

from .flavour import Flavour

# Commands a fake vehicle stores and (mostly) flies. Positional = x/y/z is a location.
POSITIONAL = frozenset({16, 17, 18, 19, 21, 22, 31, 84, 85, 195, 201})
NON_POSITIONAL = frozenset({20, 93, 112, 113, 114, 159, 177, 178, 179, 183, 184, 189, 200, 203, 205, 206,
                            211, 214, 1000, 2000, 2001, 2500, 2501, 3000})
NAV_LOITER_TURNS = 18  # PX4 refuses it in a mission (MAV_MISSION_UNSUPPORTED)
NAN_PARAM4_OK = frozenset({16, 21, 22, 84})  # ArduPilot sanity_check_params
LOCATION_ALT_MAX_M = 83000.0
_AP_FRAMES = frozenset({0, 2, 3, 5, 6, 10, 11})
_PX4_GLOBAL = frozenset({0, 3, 5, 6})
_AP_DOWNLOAD_FRAME = {5: 0, 6: 3, 11: 10}
_INT_FRAME = {0: 5, 3: 6, 10: 11}

SEVERITY_WARNING = mav.MAV_SEVERITY_WARNING
SEVERITY_INFO = mav.MAV_SEVERITY_INFO


@dataclass(frozen=True)
class Peer:
    """Who sent a message: the network address (any hashable) and the MAVLink ids."""

    address: object
    sysid: int
    compid: int


@dataclass(frozen=True)
class Reply:
    """A message to send; ``to`` None means every connected peer."""

    msg: object
    to: Peer | None = None
    component: int = 1  # 1 = autopilot, 191 = the onboard (companion) computer


@dataclass
class _Upload:
    peer: Peer
    mission_type: int
    count: int
    items: list
    next_seq: int = 0
    last_request_s: float = 0.0
    last_activity_s: float = 0.0


@dataclass
class MissionServer:
    """Mission storage and the transfer protocol for one vehicle (one MAVLink system)."""

    flavour: Flavour
    sysid: int
    home_item: Callable[[], WireItem]  # ArduPilot item 0 on download: the current home
    on_changed: Callable[[int], None] = lambda mission_type: None
    stores: dict = field(default_factory=lambda: {0: [], 1: [], 2: []})
    upload: _Upload | None = None
    _last_done: tuple | None = None  # (peer ids, mission_type, last seq) of the last completed upload
    _download_next: int | None = None  # PX4: the seq the downloading GCS may ask for next
    _warned: set = field(default_factory=set)
    # Download snapshot per mission type, (store list, items), so that serving item i is O(1)
    # (rebuilding the list per request made a 500-item read-back quadratic); dropped whenever the
    # store changes, and ignored when the store list was replaced (reboot).
    _download_cache: dict = field(default_factory=dict)

    # ------------------------------------------------------------------------ queries
    def mission(self) -> list[WireItem]:
        return list(self.stores[0])

    def busy(self) -> bool:
        return self.upload is not None

    # ------------------------------------------------------------------------ entry points
    def handle(self, msg, peer: Peer, wall_s: float) -> list[Reply]:
        name = msg.get_type()
        handler = {
            "MISSION_COUNT": self._on_count,
            "MISSION_ITEM_INT": self._on_item,
            "MISSION_ITEM": self._on_item,
            "MISSION_REQUEST_LIST": self._on_request_list,
            "MISSION_REQUEST_INT": self._on_request,
            "MISSION_REQUEST": self._on_request,
            "MISSION_CLEAR_ALL": self._on_clear,
            "MISSION_ACK": self._on_ack,
        }.get(name)
        if handler is None or getattr(msg, "target_system", self.sysid) not in (0, self.sysid):
            return []
        return handler(msg, peer, wall_s)

    def tick(self, wall_s: float) -> list[Reply]:
        """Re-send the pending item request, or give the upload up, as the autopilot would."""
        up = self.upload
        if up is None:
            return []
        if wall_s - up.last_activity_s > self.flavour.upload_timeout_s:
            self.upload = None
            if self.flavour.name == "ardupilot":
                return [self._ack(up.peer, mav.MAV_MISSION_OPERATION_CANCELLED, up.mission_type),
                        _text(SEVERITY_WARNING, "Mission upload timeout")]
            return [_text(SEVERITY_WARNING, "Operation timeout")]
        if wall_s - up.last_request_s >= self.flavour.item_retry_s:
            up.last_request_s = wall_s
            return [self._request(up)]
        return []

    def _changed(self, mtype: int) -> None:
        self._download_cache.pop(mtype, None)
        self.on_changed(mtype)

    def clear(self, mission_type: int = 0) -> None:
        types = (0, 1, 2) if mission_type == mav.MAV_MISSION_TYPE_ALL else (mission_type,)
        for t in types:
            if t in self.stores:
                self.stores[t] = []
                self._changed(t)

    # ------------------------------------------------------------------------ upload
    def _on_count(self, msg, peer: Peer, wall_s: float) -> list[Reply]:
        mtype = getattr(msg, "mission_type", 0)
        if mtype not in self.stores:
            return [self._ack(peer, mav.MAV_MISSION_UNSUPPORTED, mtype)]
        up = self.upload
        if up is not None:
            same_gcs = (up.peer.sysid, up.peer.compid) == (peer.sysid, peer.compid)
            if self.flavour.name == "px4":
                if same_gcs and up.next_seq == 0 and up.count == msg.count:
                    up.last_request_s = up.last_activity_s = wall_s
                    return [self._request(up)]  # a repeated COUNT: request item 0 again
                return [self._ack(peer, mav.MAV_MISSION_ERROR, mtype), _text(SEVERITY_WARNING, "WPM: REJ. CMD: Busy")]
            if not same_gcs:
                return [self._ack(peer, mav.MAV_MISSION_DENIED, mtype)]
            self.upload = None  # ArduPilot: the same GCS starts over
        if msg.count == 0:
            self.clear(mtype)
            return [self._ack(peer, mav.MAV_MISSION_ACCEPTED, mtype)]
        if msg.count > self.flavour.max_items:
            refusal = [self._ack(peer, mav.MAV_MISSION_NO_SPACE, mtype)]
            if not self.flavour.atomic_upload:  # ArduPilot says its limit (MissionItemProtocol.cpp)
                refusal.append(_text(SEVERITY_WARNING, f"Only {self.flavour.max_items} items are supported"))
            return refusal
        if not self.flavour.atomic_upload:
            # ArduPilot truncates on MISSION_COUNT: uploads are not atomic.
            self.stores[mtype] = self.stores[mtype][: msg.count]
            self._changed(mtype)
        self.upload = _Upload(peer, mtype, msg.count, [], 0, wall_s, wall_s)
        return [self._request(self.upload)]

    def _on_item(self, msg, peer: Peer, wall_s: float) -> list[Reply]:
        mtype = getattr(msg, "mission_type", 0)
        up = self.upload
        if up is None:
            done = self._last_done
            if done and done == ((peer.sysid, peer.compid), mtype, msg.seq):
                return [self._ack(peer, mav.MAV_MISSION_ACCEPTED, mtype)]  # our final ACK was lost
            return []
        if (peer.sysid, peer.compid) != (up.peer.sysid, up.peer.compid) or mtype != up.mission_type:
            return [self._ack(peer, mav.MAV_MISSION_DENIED, mtype)] if self.flavour.name == "ardupilot" else []
        if msg.seq != up.next_seq:
            if self.flavour.nack_out_of_sequence:
                return [self._ack(peer, mav.MAV_MISSION_INVALID_SEQUENCE, mtype)]
            return []
        replies: list[Reply] = []
        if msg.get_type() == "MISSION_ITEM" and self.flavour.name == "ardupilot" and "item" not in self._warned:
            self._warned.add("item")
            replies.append(_text(SEVERITY_WARNING, "got MISSION_ITEM; GCS should send MISSION_ITEM_INT"))
        item = _wire_item(msg)
        result = self._validate(item)
        if result != mav.MAV_MISSION_ACCEPTED:
            self.upload = None
            return replies + [self._ack(peer, result, mtype)]
        up.last_activity_s = wall_s
        if self.flavour.atomic_upload:
            up.items.append(item)
        else:
            store = self.stores[mtype]
            if item.seq < len(store):
                store[item.seq] = item
            else:
                store.append(item)
            self._changed(mtype)
        up.next_seq += 1
        if up.next_seq < up.count:
            up.last_request_s = wall_s
            return replies + [self._request(up)]
        if self.flavour.atomic_upload:
            self.stores[mtype] = up.items
        self.upload = None
        self._last_done = ((peer.sysid, peer.compid), mtype, item.seq)
        self._changed(mtype)
        return replies + [self._ack(peer, mav.MAV_MISSION_ACCEPTED, mtype)]

    def _validate(self, it: WireItem) -> int:
        ap = self.flavour.name == "ardupilot"
        if ap and self.flavour.home_is_item0 and it.seq == 0 and it.mission_type == 0:
            return mav.MAV_MISSION_ACCEPTED  # replaced by home anyway
        positional = it.command in POSITIONAL
        if not positional and it.command not in NON_POSITIONAL:
            return mav.MAV_MISSION_UNSUPPORTED
        params = (it.param1, it.param2, it.param3, it.param4)
        if ap:
            for k, p in enumerate(params):
                if math.isinf(p) or (math.isnan(p) and not (k == 3 and it.command in NAN_PARAM4_OK)):
                    return mav.MAV_MISSION_INVALID_PARAM1 + k
            if positional:
                if it.frame not in _AP_FRAMES:
                    return mav.MAV_MISSION_UNSUPPORTED_FRAME
                if abs(it.x) > 900_000_000:
                    return mav.MAV_MISSION_INVALID_PARAM5_X
                if abs(it.y) > 1_800_000_000:
                    return mav.MAV_MISSION_INVALID_PARAM6_Y
                if not math.isfinite(it.z) or abs(it.z) >= LOCATION_ALT_MAX_M:
                    return mav.MAV_MISSION_INVALID_PARAM7
            return mav.MAV_MISSION_ACCEPTED
        if it.command == NAV_LOITER_TURNS:  # measured on PX4 SITL (docs/science/looks.md)
            return mav.MAV_MISSION_UNSUPPORTED
        if positional:
            if it.frame == mav.MAV_FRAME_MISSION:
                return mav.MAV_MISSION_UNSUPPORTED
            if it.frame not in _PX4_GLOBAL:
                return mav.MAV_MISSION_UNSUPPORTED_FRAME
            return mav.MAV_MISSION_ACCEPTED
        if it.frame != mav.MAV_FRAME_MISSION:
            return mav.MAV_MISSION_UNSUPPORTED
        return mav.MAV_MISSION_ACCEPTED

    def _request(self, up: _Upload) -> Reply:
        p = up.peer
        if self.flavour.request_int:
            msg = mav.MAVLink_mission_request_int_message(p.sysid, p.compid, up.next_seq, up.mission_type)
        else:
            msg = mav.MAVLink_mission_request_message(p.sysid, p.compid, up.next_seq, up.mission_type)
        return Reply(msg, p)

    def _on_ack(self, msg, peer: Peer, wall_s: float) -> list[Reply]:
        up = self.upload
        if up is not None and (peer.sysid, peer.compid) == (up.peer.sysid, up.peer.compid):
            if msg.type != mav.MAV_MISSION_ACCEPTED:  # the GCS cancelled the upload
                self.upload = None
        return []  # an ACK after a download needs no answer

    # ------------------------------------------------------------------------ download / clear
    def _on_request_list(self, msg, peer: Peer, wall_s: float) -> list[Reply]:
        mtype = getattr(msg, "mission_type", 0)
        if mtype not in self.stores:
            return [self._ack(peer, mav.MAV_MISSION_UNSUPPORTED, mtype)]
        if self.upload is not None:
            code = mav.MAV_MISSION_DENIED if self.flavour.name == "ardupilot" else mav.MAV_MISSION_ERROR
            return [self._ack(peer, code, mtype)]
        self._download_cache.pop(mtype, None)  # a new download serves the mission as it is now
        count = len(self._download_snapshot(mtype))
        self._download_next = 0
        return [Reply(mav.MAVLink_mission_count_message(peer.sysid, peer.compid, count, mtype), peer)]

    def _on_request(self, msg, peer: Peer, wall_s: float) -> list[Reply]:
        mtype = getattr(msg, "mission_type", 0)
        if mtype not in self.stores or self.upload is not None:
            return []  # during an upload, our own requests are what matter
        items = self._download_snapshot(mtype)
        if not 0 <= msg.seq < len(items):
            return [self._ack(peer, mav.MAV_MISSION_INVALID_SEQUENCE, mtype)]
        if self.flavour.strict_download_order and self._download_next is not None:
            # PX4 serves the expected item or a repeat of the previous one; anything else aborts
            if msg.seq not in (self._download_next, self._download_next - 1):
                self._download_next = None
                return [self._ack(peer, mav.MAV_MISSION_ERROR, mtype)]
            self._download_next = msg.seq + 1
        it = items[msg.seq]
        if msg.get_type() == "MISSION_REQUEST_INT":
            out = mav.MAVLink_mission_item_int_message(
                peer.sysid, peer.compid, it.seq, it.frame, it.command, it.current, it.autocontinue,
                it.param1, it.param2, it.param3, it.param4, it.x, it.y, it.z, mtype)
            return [Reply(out, peer)]
        replies = []
        if self.flavour.name == "ardupilot" and "request" not in self._warned:
            self._warned.add("request")
            replies.append(_text(SEVERITY_WARNING, "got MISSION_REQUEST; use MISSION_REQUEST_INT!"))
        scale = 1e-7 if it.command in POSITIONAL else 1.0
        out = mav.MAVLink_mission_item_message(
            peer.sysid, peer.compid, it.seq, it.frame, it.command, it.current, it.autocontinue,
            it.param1, it.param2, it.param3, it.param4, it.x * scale, it.y * scale, it.z, mtype)
        return replies + [Reply(out, peer)]

    def _download_snapshot(self, mtype: int) -> list[WireItem]:
        """The items a download serves, rebuilt only when the store changed (or was replaced)."""
        store = self.stores[mtype]
        cached = self._download_cache.get(mtype)
        if cached is None or cached[0] is not store:
            cached = self._download_cache[mtype] = (store, self._download_items(mtype))
        return cached[1]

    def _download_items(self, mtype: int) -> list[WireItem]:
        items = list(self.stores[mtype])
        if mtype == 0 and self.flavour.home_is_item0 and items:
            items[0] = self.home_item()
        if self.flavour.name == "ardupilot":
            items = [replace(it, frame=_AP_DOWNLOAD_FRAME.get(it.frame, it.frame), current=0) for it in items]
        if self.flavour.positionless_download_frame0:
            items = [it if it.command in POSITIONAL else replace(it, frame=0, x=0, y=0) for it in items]
        if self.flavour.download_int_frames:
            items = [replace(it, frame=_INT_FRAME.get(it.frame, it.frame)) if it.command in POSITIONAL else it
                     for it in items]
        return [replace(it, seq=i) for i, it in enumerate(items)]

    def _on_clear(self, msg, peer: Peer, wall_s: float) -> list[Reply]:
        mtype = getattr(msg, "mission_type", 0)
        if self.upload is not None and self.flavour.name == "px4":
            return [self._ack(peer, mav.MAV_MISSION_ERROR, mtype)]
        self.upload = None
        self.clear(mtype)
        return [self._ack(peer, mav.MAV_MISSION_ACCEPTED, mtype)]

    def _ack(self, peer: Peer, result: int, mtype: int) -> Reply:
        return Reply(mav.MAVLink_mission_ack_message(peer.sysid, peer.compid, result, mtype), peer)


def _wire_item(msg) -> WireItem:
    """A received MISSION_ITEM_INT (or float MISSION_ITEM, converted to degE7) as a WireItem."""
    x, y = msg.x, msg.y
    if msg.get_type() == "MISSION_ITEM":
        if msg.command in POSITIONAL and msg.frame != mav.MAV_FRAME_MISSION:
            x, y = int(round(msg.x * 1e7)), int(round(msg.y * 1e7))
        else:
            x, y = int(round(msg.x)), int(round(msg.y))
    return WireItem(int(msg.seq), int(msg.frame), int(msg.command), int(msg.current), int(msg.autocontinue),
                    float(msg.param1), float(msg.param2), float(msg.param3), float(msg.param4),
                    int(x), int(y), float(msg.z), int(getattr(msg, "mission_type", 0)))


def _text(severity: int, text: str) -> Reply:
    return Reply(mav.MAVLink_statustext_message(severity, text.encode()[:50]))
