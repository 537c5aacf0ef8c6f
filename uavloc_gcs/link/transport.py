"""Byte transports under a MAVLink link: UDP (listen / connect), TCP (client / server), serial.

A transport only moves bytes. It hands every received chunk to ``on_bytes(data, peer)`` where
``peer`` identifies where the bytes came from (a UDP address, a TCP connection, the serial port),
and ``send(data, peer)`` writes to one peer or, with ``peer=None``, to every known peer. Framing,
signing and routing by system id live in :mod:`uavloc_gcs.link.connection`.

Connection strings (the mavutil/MAVProxy spelling, without its guessing):

==========================  =============================================================
``udpin:HOST:PORT``         listen; peers are learned from the packets they send
``udpout:HOST:PORT``        send to HOST:PORT from an ephemeral port (replies come back)
``tcp:HOST:PORT``           TCP client; reconnects after the peer goes away
``tcpin:HOST:PORT``         TCP server; every accepted connection is a peer
``serial:DEVICE[:BAUD]``    serial port (pyserial), default 57600 baud
==========================  =============================================================

An empty HOST in ``udpin``/``tcpin`` binds to loopback (SPEC §4: listen on loopback by default).
"""

from __future__ import annotations

import abc
import asyncio
import contextlib
import logging
import os
from dataclasses import dataclass
from typing import Callable, Hashable

from ..errors import ConfigError, LinkError

log = logging.getLogger(__name__)

OnBytes = Callable[[bytes, Hashable], None]

DEFAULT_SERIAL_BAUD = 57600
TCP_CONNECT_TIMEOUT_S = 5.0
TCP_RECONNECT_INTERVAL_S = 1.0
READ_CHUNK_BYTES = 65536
SCHEMES = ("udpin", "udpout", "tcp", "tcpin", "serial")


@dataclass(frozen=True)
class Endpoint:
    """A parsed connection string."""

    scheme: str
    host: str = ""
    port: int = 0
    device: str = ""
    baud: int = DEFAULT_SERIAL_BAUD

    def __str__(self) -> str:
        if self.scheme == "serial":
            return f"serial:{self.device}:{self.baud}"
        return f"{self.scheme}:{self.host}:{self.port}"


def parse_connection(text: str) -> Endpoint:
    """Parse ``udpin:HOST:PORT`` etc. (see module docstring); bad strings raise ConfigError."""
    scheme, sep, rest = text.partition(":")
    scheme = scheme.strip().lower()
    if not sep or scheme not in SCHEMES:
        raise ConfigError(
            f"connection {text!r} must start with one of {', '.join(s + ':' for s in SCHEMES)}",
            key="connection",
        )
    if scheme == "serial":
        device, _, baud_text = rest.rpartition(":")
        if not device or not baud_text.isdigit():
            device, baud_text = rest, str(DEFAULT_SERIAL_BAUD)
        if not device:
            raise ConfigError(f"connection {text!r} names no serial device", key="connection")
        return Endpoint("serial", device=device, baud=int(baud_text))
    host, _, port_text = rest.rpartition(":")
    if not port_text.isdigit() or not 0 <= int(port_text) <= 65535:
        raise ConfigError(f"connection {text!r} needs a port number 0-65535 after the host", key="connection")
    host = host.strip("[]")
    if scheme in ("udpout", "tcp") and (not host or int(port_text) == 0):
        raise ConfigError(f"connection {text!r} needs the peer's host and a non-zero port", key="connection")
    return Endpoint(scheme, host=host or "127.0.0.1", port=int(port_text))


class Transport(abc.ABC):
    """Moves bytes to and from peers; owned and closed by one :class:`Link`."""

    endpoint: Endpoint

    @abc.abstractmethod
    def send(self, data: bytes, peer: Hashable | None = None) -> None:
        """Write ``data`` to ``peer`` (None: all known peers). Never blocks."""

    @property
    @abc.abstractmethod
    def peers(self) -> list[Hashable]:
        """Peers currently reachable."""

    @abc.abstractmethod
    async def close(self) -> None:
        """Stop receiving and release the socket/port."""

    @property
    def local_address(self) -> tuple[str, int] | None:
        """Bound (host, port) for socket transports, else None."""
        return None


async def open_transport(endpoint: Endpoint, on_bytes: OnBytes) -> Transport:
    """Open ``endpoint``; failures to bind/connect raise LinkError naming it."""
    opener = {
        "udpin": UdpTransport.listen,
        "udpout": UdpTransport.connect,
        "tcp": TcpClientTransport.connect,
        "tcpin": TcpServerTransport.listen,
        "serial": SerialTransport.open,
    }[endpoint.scheme]
    try:
        return await opener(endpoint, on_bytes)
    except (OSError, asyncio.TimeoutError) as err:
        raise LinkError(f"cannot open {endpoint}: {err.strerror or err}" if isinstance(err, OSError)
                        else f"cannot open {endpoint}: timed out", operation="connect") from err


# ---------------------------------------------------------------------------------------------
# UDP


class _Datagrams(asyncio.DatagramProtocol):
    def __init__(self, owner: "UdpTransport"):
        self.owner = owner

    def datagram_received(self, data: bytes, addr) -> None:
        self.owner._received(data, addr)

    def error_received(self, exc: Exception) -> None:
        # ICMP port unreachable while the vehicle is not up yet: not an error of ours.
        log.debug("udp %s: %s", self.owner.endpoint, exc)


class UdpTransport(Transport):
    """UDP socket. ``udpin`` learns peers from what it receives; ``udpout`` has one fixed peer."""

    def __init__(self, endpoint: Endpoint, on_bytes: OnBytes):
        self.endpoint = endpoint
        self._on_bytes = on_bytes
        self._udp: asyncio.DatagramTransport | None = None
        self._peers: dict[Hashable, None] = {}  # insertion-ordered set

    @classmethod
    async def listen(cls, endpoint: Endpoint, on_bytes: OnBytes) -> "UdpTransport":
        self = cls(endpoint, on_bytes)
        loop = asyncio.get_running_loop()
        self._udp, _ = await loop.create_datagram_endpoint(
            lambda: _Datagrams(self), local_addr=(endpoint.host, endpoint.port))
        return self

    @classmethod
    async def connect(cls, endpoint: Endpoint, on_bytes: OnBytes) -> "UdpTransport":
        self = cls(endpoint, on_bytes)
        loop = asyncio.get_running_loop()
        infos = await loop.getaddrinfo(endpoint.host, endpoint.port, type=2)  # SOCK_DGRAM
        remote = infos[0][4][:2]
        self._udp, _ = await loop.create_datagram_endpoint(lambda: _Datagrams(self), remote_addr=remote)
        self._peers[remote] = None
        return self

    def _received(self, data: bytes, addr) -> None:
        addr = tuple(addr[:2])
        if self.endpoint.scheme == "udpin":
            self._peers.setdefault(addr, None)
        self._on_bytes(data, addr)

    def send(self, data: bytes, peer: Hashable | None = None) -> None:
        if self._udp is None or self._udp.is_closing():
            return
        if self.endpoint.scheme == "udpout":
            self._udp.sendto(data)
            return
        for addr in ([peer] if peer is not None else list(self._peers)):
            self._udp.sendto(data, addr)

    @property
    def peers(self) -> list[Hashable]:
        return list(self._peers)

    @property
    def local_address(self) -> tuple[str, int] | None:
        return self._udp.get_extra_info("sockname")[:2] if self._udp else None

    async def close(self) -> None:
        if self._udp is not None:
            self._udp.close()
            self._udp = None


# ---------------------------------------------------------------------------------------------
# TCP


async def _pump(reader: asyncio.StreamReader, peer: Hashable, on_bytes: OnBytes) -> None:
    """Deliver everything ``reader`` yields until EOF."""
    while data := await reader.read(READ_CHUNK_BYTES):
        on_bytes(data, peer)


class TcpClientTransport(Transport):
    """TCP client (ArduPilot SITL's ``tcp:127.0.0.1:5760``). Reconnects when the peer drops."""

    def __init__(self, endpoint: Endpoint, on_bytes: OnBytes):
        self.endpoint = endpoint
        self._on_bytes = on_bytes
        self._writer: asyncio.StreamWriter | None = None
        self._task: asyncio.Task | None = None

    @classmethod
    async def connect(cls, endpoint: Endpoint, on_bytes: OnBytes) -> "TcpClientTransport":
        self = cls(endpoint, on_bytes)
        reader, self._writer = await self._open()
        self._task = asyncio.create_task(self._run(reader), name=f"tcp {endpoint}")
        return self

    async def _open(self):
        async with asyncio.timeout(TCP_CONNECT_TIMEOUT_S):
            return await asyncio.open_connection(self.endpoint.host, self.endpoint.port)

    async def _run(self, reader: asyncio.StreamReader) -> None:
        heard = False
        told = None

        def on_bytes(data: bytes, peer: Hashable) -> None:
            nonlocal heard
            heard = heard or b"\xfd" in data or b"\xfe" in data  # a MAVLink 2 / 1 start byte
            self._on_bytes(data, peer)

        while True:
            with contextlib.suppress(ConnectionError):
                await _pump(reader, "tcp", on_bytes)
            # say what happened once per kind, not every second of a retry loop
            what = ("connection lost; reconnecting every %.0f s" if heard else
                    "the connection closed without a MAVLink byte received (is a MAVLink vehicle listening there?); "
                    "retrying every %.0f s")
            if what != told:
                log.warning("%s: " + what, self.endpoint, TCP_RECONNECT_INTERVAL_S)
                told = what
            heard = False
            self._writer = None
            while self._writer is None:
                await asyncio.sleep(TCP_RECONNECT_INTERVAL_S)
                with contextlib.suppress(OSError, TimeoutError):
                    reader, self._writer = await self._open()

    def send(self, data: bytes, peer: Hashable | None = None) -> None:
        if self._writer is not None and not self._writer.is_closing():
            self._writer.write(data)

    @property
    def peers(self) -> list[Hashable]:
        return ["tcp"] if self._writer is not None else []

    async def close(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
        if self._writer is not None:
            self._writer.close()
            self._writer = None


class TcpServerTransport(Transport):
    """TCP server; each accepted connection is a peer named by its remote address."""

    def __init__(self, endpoint: Endpoint, on_bytes: OnBytes):
        self.endpoint = endpoint
        self._on_bytes = on_bytes
        self._server: asyncio.base_events.Server | None = None
        self._writers: dict[Hashable, asyncio.StreamWriter] = {}

    @classmethod
    async def listen(cls, endpoint: Endpoint, on_bytes: OnBytes) -> "TcpServerTransport":
        self = cls(endpoint, on_bytes)
        self._server = await asyncio.start_server(self._serve, endpoint.host, endpoint.port)
        return self

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        peer = tuple(writer.get_extra_info("peername")[:2])
        self._writers[peer] = writer
        try:
            await _pump(reader, peer, self._on_bytes)
        except ConnectionError:
            pass
        finally:
            self._writers.pop(peer, None)
            writer.close()

    def send(self, data: bytes, peer: Hashable | None = None) -> None:
        targets = [self._writers.get(peer)] if peer is not None else list(self._writers.values())
        for w in targets:
            if w is not None and not w.is_closing():
                w.write(data)

    @property
    def peers(self) -> list[Hashable]:
        return list(self._writers)

    @property
    def local_address(self) -> tuple[str, int] | None:
        return self._server.sockets[0].getsockname()[:2] if self._server else None

    async def close(self) -> None:
        for w in list(self._writers.values()):
            w.close()
        if self._server is not None:
            self._server.close()
            await self._server.wait_closed()
            self._server = None


# ---------------------------------------------------------------------------------------------
# Serial


class SerialTransport(Transport):
    """A serial port read through the event loop's reader callback (no polling thread)."""

    def __init__(self, endpoint: Endpoint, on_bytes: OnBytes):
        self.endpoint = endpoint
        self._on_bytes = on_bytes
        self._port = None

    @classmethod
    async def open(cls, endpoint: Endpoint, on_bytes: OnBytes) -> "SerialTransport":
        import serial  # pyserial; imported here so UDP-only users never need it

        self = cls(endpoint, on_bytes)
        try:
            self._port = serial.Serial(endpoint.device, endpoint.baud, timeout=0, write_timeout=None)
        except serial.SerialException as err:
            raise OSError(err.errno or 0, str(err)) from err
        asyncio.get_running_loop().add_reader(self._port.fileno(), self._readable)
        return self

    def _readable(self) -> None:
        try:
            data = os.read(self._port.fileno(), READ_CHUNK_BYTES)
        except BlockingIOError:
            return
        except OSError as err:  # unplugged USB radio
            log.warning("%s: %s", self.endpoint, err)
            asyncio.get_running_loop().remove_reader(self._port.fileno())
            return
        if data:
            self._on_bytes(data, "serial")

    def send(self, data: bytes, peer: Hashable | None = None) -> None:
        if self._port is not None:
            self._port.write(data)

    @property
    def peers(self) -> list[Hashable]:
        return ["serial"] if self._port is not None else []

    async def close(self) -> None:
        if self._port is not None:
            with contextlib.suppress(Exception):
                asyncio.get_running_loop().remove_reader(self._port.fileno())
            self._port.close()
            self._port = None
