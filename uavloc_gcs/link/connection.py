"""A MAVLink link: one transport, pymavlink as the codec, signing, dispatch, stats and the .tlog.

>>> async with await open_link("udpin:127.0.0.1:14550", tlog_path="flight.tlog") as link:
...     hb = await link.wait_heartbeat(timeout_s=10)
...     with link.subscribe("MISSION_ACK", source_system=hb.get_srcSystem()) as acks:
...         await link.send(link.mav.mission_clear_all_encode(1, 1, 0))
...         ack = await acks.get(timeout_s=1.5)

Every exchange registers what it expects (a :class:`Subscription`) *before* it sends, so a fast
reply can never be missed. Received bytes are parsed as they arrive (event-loop callback, no
polling); each accepted message goes to the subscriptions that match it. With a signing key,
unsigned and wrongly signed packets are dropped and counted in :class:`LinkStats` (RADIO_STATUS
is let through unsigned, as the MAVLink signing guide recommends: SiK radios cannot sign).
Everything received, dropped packets included, is written to the ``.tlog``.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from dataclasses import dataclass
from typing import Callable, Hashable, Iterable

from ..dialect import mavlink
from ..dialect.signing import verify_signature_first
from ..errors import ConfigError, LinkError
from .tlog import TlogWriter
from .transport import Transport, open_transport, parse_connection

log = logging.getLogger(__name__)

Message = mavlink.MAVLink_message
Predicate = Callable[[Message], bool]

HEARTBEAT_INTERVAL_S = 1.0  # MAVLink microservice "heartbeat": 1 Hz
SIGNING_KEY_BYTES = 32
SIGNING_EPOCH_UNIX_S = 1420070400  # 2015-01-01, MAVLink 2 signing timestamp origin
MSG_ID_RADIO_STATUS = mavlink.MAVLINK_MSG_ID_RADIO_STATUS
MAV_AUTOPILOT_INVALID = mavlink.MAV_AUTOPILOT_INVALID


@dataclass
class LinkStats:
    """Counters since the link opened."""

    rx_bytes: int = 0
    rx_packets: int = 0  # accepted and dispatched
    tx_packets: int = 0
    tx_bytes: int = 0
    unsigned_dropped: int = 0
    bad_signature_dropped: int = 0
    crc_errors: int = 0
    junk_bytes: int = 0  # bytes outside any MAVLink frame


class Subscription:
    """Messages that match a filter, queued for :meth:`get` or handed to a callback.

    Use as a context manager (``with link.subscribe(...) as sub:``) so it is removed again.
    """

    def __init__(self, link: "Link", types: frozenset[str] | None, source_system: int | None,
                 source_component: int | None, predicate: Predicate | None,
                 callback: Callable[[Message], None] | None):
        self._link = link
        self._types = types
        self._system = source_system
        self._component = source_component
        self._predicate = predicate
        self._callback = callback
        self._queue: asyncio.Queue[Message] = asyncio.Queue()

    def matches(self, msg: Message) -> bool:
        return (
            (self._types is None or msg.get_type() in self._types)
            and (self._system is None or msg.get_srcSystem() == self._system)
            and (self._component is None or msg.get_srcComponent() == self._component)
            and (self._predicate is None or self._predicate(msg))
        )

    def _deliver(self, msg: Message) -> None:
        if self._callback is not None:
            self._callback(msg)
        else:
            self._queue.put_nowait(msg)

    async def get(self, timeout_s: float | None = None) -> Message:
        """Next matching message; raises TimeoutError after ``timeout_s`` seconds."""
        if not self._queue.empty():  # fast path: no timer needed
            return self._queue.get_nowait()
        if timeout_s is None:
            return await self._queue.get()
        async with asyncio.timeout(timeout_s):
            return await self._queue.get()

    def get_nowait(self) -> Message | None:
        """Next queued message or None."""
        try:
            return self._queue.get_nowait()
        except asyncio.QueueEmpty:
            return None

    def close(self) -> None:
        self._link._unsubscribe(self)

    def __enter__(self) -> "Subscription":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __aiter__(self):
        return self

    async def __anext__(self) -> Message:
        return await self.get()


class Link:
    """One MAVLink connection. Create with :func:`open_link`; close with :meth:`close`."""

    def __init__(self, description: str, *, source_system: int, source_component: int,
                 signing_key: bytes | None, tlog: TlogWriter | None):
        self.description = description
        self.mav = mavlink.MAVLink(None, srcSystem=source_system, srcComponent=source_component)
        self.mav.robust_parsing = True
        if signing_key is not None:
            s = self.mav.signing
            s.secret_key = bytes(signing_key)
            s.sign_outgoing = True
            s.timestamp = int((time.time() - SIGNING_EPOCH_UNIX_S) * 100_000)
            s.allow_unsigned_callback = lambda _mav, msg_id: msg_id == MSG_ID_RADIO_STATUS
        self.stats = LinkStats()
        self.heartbeats: dict[int, Message] = {}  # last autopilot HEARTBEAT per system id
        self._parsers: dict[Hashable, mavlink.MAVLink] = {}
        self._routes: dict[int, Hashable] = {}  # system id -> transport peer it was heard on
        self._subs: list[Subscription] = []
        self._tlog = tlog
        self._transport: Transport | None = None
        self._tasks: list[asyncio.Task] = []
        self._closed = False

    # -- receiving ------------------------------------------------------------------------

    def _parser_for(self, peer: Hashable) -> mavlink.MAVLink:
        parser = self._parsers.get(peer)
        if parser is None:
            parser = mavlink.MAVLink(None, self.mav.srcSystem, self.mav.srcComponent)
            parser.robust_parsing = True
            parser.signing = self.mav.signing  # one replay-protection state for all peers
            verify_signature_first(parser)
            self._parsers[peer] = parser
        return parser

    def _on_bytes(self, data: bytes, peer: Hashable) -> None:
        self.stats.rx_bytes += len(data)
        t_us = int(time.time() * 1e6) if self._tlog is not None else 0
        for msg in self._parser_for(peer).parse_buffer(data) or ():
            if isinstance(msg, mavlink.MAVLink_bad_data):
                self._count_bad(msg, t_us)
                continue
            self.stats.rx_packets += 1
            if self._tlog is not None:
                self._tlog.write(msg.get_msgbuf(), t_us)
            self._routes[msg.get_srcSystem()] = peer
            if msg.get_type() == "HEARTBEAT" and msg.autopilot != MAV_AUTOPILOT_INVALID:
                self.heartbeats[msg.get_srcSystem()] = msg
            self._dispatch(msg)

    def _count_bad(self, bad: "mavlink.MAVLink_bad_data", t_us: int) -> None:
        frame = bytes(bad.data)
        reason = str(bad.reason)
        if "signature" in reason:
            signed = frame[0] == 0xFD and frame[2] & mavlink.MAVLINK_IFLAG_SIGNED
            if signed:
                self.stats.bad_signature_dropped += 1
            else:
                self.stats.unsigned_dropped += 1
        elif "CRC" in reason:
            self.stats.crc_errors += 1
        else:
            self.stats.junk_bytes += len(frame)
            return
        log.debug("%s: dropped packet: %s", self.description, reason)
        if self._tlog is not None:
            self._tlog.write(frame, t_us)

    def _dispatch(self, msg: Message) -> None:
        for sub in list(self._subs):
            try:
                if sub.matches(msg):
                    sub._deliver(msg)
            except Exception:  # a subscriber's bug must not stop the link
                log.exception("%s: subscriber failed on %s", self.description, msg.get_type())

    # -- subscribing ----------------------------------------------------------------------

    def subscribe(self, types: str | Iterable[str] | None = None, *, source_system: int | None = None,
                  source_component: int | None = None, predicate: Predicate | None = None,
                  callback: Callable[[Message], None] | None = None) -> Subscription:
        """Receive messages of ``types`` (names like "MISSION_ACK") from ``source_system``.

        Without ``callback`` they queue for :meth:`Subscription.get`; with it, the callback runs
        in the receive path (keep it short). Close the subscription when done.
        """
        if isinstance(types, str):
            types = (types,)
        sub = Subscription(self, frozenset(types) if types is not None else None, source_system,
                           source_component, predicate, callback)
        self._subs.append(sub)
        return sub

    def _unsubscribe(self, sub: Subscription) -> None:
        with contextlib.suppress(ValueError):
            self._subs.remove(sub)

    async def recv_match(self, predicate: Predicate | None = None, *, types: str | Iterable[str] | None = None,
                         source_system: int | None = None, timeout_s: float) -> Message:
        """The next matching message; raises TimeoutError after ``timeout_s`` seconds."""
        with self.subscribe(types, source_system=source_system, predicate=predicate) as sub:
            return await sub.get(timeout_s)

    wait_for = recv_match

    async def wait_heartbeat(self, source_system: int | None = None, *, timeout_s: float) -> Message:
        """An autopilot HEARTBEAT (already seen, or the next one); LinkError if none in time."""
        if source_system is not None and source_system in self.heartbeats:
            return self.heartbeats[source_system]
        if source_system is None and self.heartbeats:
            return next(iter(self.heartbeats.values()))
        try:
            return await self.recv_match(lambda m: m.autopilot != MAV_AUTOPILOT_INVALID, types="HEARTBEAT",
                                         source_system=source_system, timeout_s=timeout_s)
        except TimeoutError:
            who = f"system {source_system}" if source_system is not None else "any vehicle"
            raise LinkError(f"no heartbeat from {who} on {self.description} within {timeout_s:g} s"
                            f"{self.signing_diagnosis()}", operation="connect") from None

    def signing_diagnosis(self) -> str:
        """Why nothing useful arrived, when signing is the reason (else ""): a vehicle that does
        not sign, or signs with another key, is dropped packet by packet and looks silent."""
        s = self.stats
        if self.mav.signing.secret_key is None or not (s.unsigned_dropped or s.bad_signature_dropped):
            return ""
        if s.unsigned_dropped and not s.bad_signature_dropped:  # (RADIO_STATUS may pass unsigned)
            return (f"; heard only unsigned packets ({s.unsigned_dropped} dropped): the vehicle does not sign "
                    f"on this link (set its signing key, or connect without --signing-key)")
        if s.bad_signature_dropped and not s.rx_packets:
            return (f"; heard only packets signed with another key ({s.bad_signature_dropped} dropped"
                    f"{f', and {s.unsigned_dropped} unsigned' if s.unsigned_dropped else ''}): check the signing key")
        return (f"; {s.unsigned_dropped} unsigned and {s.bad_signature_dropped} wrongly signed packets were dropped")

    # -- sending --------------------------------------------------------------------------

    def send_nowait(self, msg: Message) -> None:
        """Encode and send ``msg`` to the peer its target_system was heard on (else to all)."""
        if self._transport is None:
            raise LinkError(f"{self.description} is closed", operation="send")
        buf = msg.pack(self.mav)
        self.mav.seq = (self.mav.seq + 1) % 256
        target = getattr(msg, "target_system", 0)
        self._transport.send(buf, self._routes.get(target) if target else None)
        self.stats.tx_packets += 1
        self.stats.tx_bytes += len(buf)

    async def send(self, msg: Message) -> None:
        self.send_nowait(msg)

    async def _heartbeat_loop(self, interval_s: float) -> None:
        while True:
            self.send_nowait(self.mav.heartbeat_encode(
                mavlink.MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID, 0, 0, mavlink.MAV_STATE_ACTIVE))
            await asyncio.sleep(interval_s)

    # -- lifecycle ------------------------------------------------------------------------

    @property
    def local_address(self) -> tuple[str, int] | None:
        """The bound (host, port) of socket transports (useful with port 0)."""
        return self._transport.local_address if self._transport else None

    @property
    def systems(self) -> list[int]:
        """System ids heard on this link."""
        return list(self._routes)

    async def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError):
                await task
        if self._transport is not None:
            await self._transport.close()
            self._transport = None
        if self._tlog is not None:
            self._tlog.close()

    async def __aenter__(self) -> "Link":
        return self

    async def __aexit__(self, *exc) -> None:
        await self.close()


async def open_link(connection: str, *, source_system: int = 255, source_component: int = 190,
                    signing_key: bytes | None = None, tlog_path=None,
                    heartbeat_interval_s: float | None = HEARTBEAT_INTERVAL_S) -> Link:
    """Open ``connection`` ("udpin:HOST:PORT", "udpout:HOST:PORT", "tcp:HOST:PORT",
    "tcpin:HOST:PORT", "serial:DEVICE:BAUD") and start sending a GCS heartbeat every
    ``heartbeat_interval_s`` (None: never). Bad strings or keys raise ConfigError; sockets that
    cannot be opened raise LinkError."""
    endpoint = parse_connection(connection)
    if signing_key is not None and len(signing_key) != SIGNING_KEY_BYTES:
        raise ConfigError(f"signing key must be {SIGNING_KEY_BYTES} bytes, got {len(signing_key)}",
                          key="signing_key")
    tlog = TlogWriter(tlog_path) if tlog_path is not None else None
    link = Link(str(endpoint), source_system=source_system, source_component=source_component,
                signing_key=signing_key, tlog=tlog)
    try:
        link._transport = await open_transport(endpoint, link._on_bytes)
    except BaseException:
        if tlog is not None:
            tlog.close()
        raise
    if heartbeat_interval_s:
        link._tasks.append(asyncio.create_task(link._heartbeat_loop(heartbeat_interval_s),
                                               name=f"heartbeat {endpoint}"))
    return link


def parse_signing_key(text: str) -> bytes:
    """A signing key given as 64 hex digits (32 bytes), as on the command line."""
    try:
        key = bytes.fromhex(text.strip())
    except ValueError:
        raise ConfigError("signing key must be hexadecimal", key="signing_key") from None
    if len(key) != SIGNING_KEY_BYTES:
        raise ConfigError(f"signing key must be {2 * SIGNING_KEY_BYTES} hex digits ({SIGNING_KEY_BYTES} bytes), "
                          f"got {len(text.strip())}", key="signing_key")
    return key
