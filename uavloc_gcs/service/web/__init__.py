"""The operator's live map in a browser: :class:`MapFeed` (what it shows) and :class:`MapServer`
(aiohttp, in the daemon's asyncio loop). Started by ``service.run.run_search`` when asked."""

from .feed import MapFeed
from .server import DEFAULT_PORT, MapServer, WebOptions, is_loopback

__all__ = ["MapFeed", "MapServer", "WebOptions", "DEFAULT_PORT", "is_loopback"]
