"""A byte link to an autopilot from a pymavlink-style connection string, for the companion emulator.

``tcp:HOST:PORT`` (client, e.g. ArduPilot SITL ``tcp:127.0.0.1:5760``), ``udpout:HOST:PORT`` or
``udp:HOST:PORT`` (send to; the autopilot learns us from our first datagram), ``udpin:HOST:PORT``
(listen; reply to whoever sent last, e.g. PX4 SITL's ``udpin:0.0.0.0:14540``).
"""

from __future__ import annotations

import asyncio
from typing import Callable

from uavloc_gcs.errors import ConfigError, LinkError


def parse_url(url: str) -> tuple[str, str, int]:
    """(kind, host, port) from a connection string; ConfigError naming it when malformed."""
    kind, _, rest = url.partition(":")
    host, _, port = rest.rpartition(":")
    if kind not in ("tcp", "udp", "udpout", "udpin") or not host or not port.isdigit():
        raise ConfigError(f"connection string {url!r} is not tcp:HOST:PORT, udpout:HOST:PORT or udpin:HOST:PORT",
                          key="autopilot")
    return ("udpout" if kind == "udp" else kind), host, int(port)


class ByteLink:
    """Bytes in via ``on_bytes``, out via :meth:`send`; ``close`` ends it."""

    def __init__(self, on_bytes: Callable[[bytes], None]):
        self.on_bytes = on_bytes
        self._send: Callable[[bytes], None] | None = None
        self._close: Callable[[], None] = lambda: None
        self.closed = asyncio.Event()

    def send(self, data: bytes) -> None:
        if self._send is not None:
            self._send(data)

    def close(self) -> None:
        self._close()
        self.closed.set()


class _Udp(asyncio.DatagramProtocol):
    def __init__(self, link: ByteLink, fixed_peer):
        self.link, self.peer, self.transport = link, fixed_peer, None

    def connection_made(self, transport) -> None:
        self.transport = transport

    def datagram_received(self, data: bytes, addr) -> None:
        if self.peer is None or self.peer[0] in ("0.0.0.0", ""):
            self.peer = addr
        self.link.on_bytes(data)

    def error_received(self, exc) -> None:  # loopback ICMP "port unreachable" while the peer is down
        pass

    def send(self, data: bytes) -> None:
        if self.peer is not None and self.transport is not None:
            self.transport.sendto(data, self.peer)


async def open_link(url: str, on_bytes: Callable[[bytes], None], *, timeout_s: float = 5.0) -> ByteLink:
    kind, host, port = parse_url(url)
    link = ByteLink(on_bytes)
    loop = asyncio.get_running_loop()
    if kind == "tcp":
        try:
            reader, writer = await asyncio.wait_for(asyncio.open_connection(host, port), timeout_s)
        except (OSError, asyncio.TimeoutError) as exc:
            raise LinkError(f"cannot connect to {url} ({exc or 'timeout'})", operation="connect") from None

        async def pump() -> None:
            while data := await reader.read(4096):
                on_bytes(data)
            link.closed.set()

        task = asyncio.create_task(pump())
        link._send = writer.write
        link._close = lambda: (task.cancel(), writer.close())
        return link
    if kind == "udpin":
        proto = _Udp(link, None)
        transport, _ = await loop.create_datagram_endpoint(lambda: proto, local_addr=(host, port))
    else:
        proto = _Udp(link, (host, port))
        local = "127.0.0.1" if host in ("localhost",) or host.startswith("127.") else "0.0.0.0"
        transport, _ = await loop.create_datagram_endpoint(lambda: proto, local_addr=(local, 0))
    link._send = proto.send
    link._close = transport.close
    return link
