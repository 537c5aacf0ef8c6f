"""The live map's web server (aiohttp), run inside the daemon's asyncio loop.

Routes: ``/`` the page, ``/static/*`` its script and style (package data, nothing fetched from
the internet), ``/api/state`` everything as JSON, ``/api/stream`` server-sent events (``state``
once, then ``delta`` whenever the store or the daemon moved on), ``/tiles/{z}/{x}/{y}`` a
background map from an offline XYZ folder or an MBTiles file when one is configured.
``POST /api/vehicles/{id}/pack-fresh``: the operator says a vehicle waiting for a pack has a fresh
one (issue 38; what ``uavloc pack-fresh`` does, through the store: service/swaps.py checks the
vehicle's own report before it is launched).

Bound to 127.0.0.1 by default. Any other address needs a token: the printed URL carries it
(``?token=...``); the page keeps it in a cookie for its script and stream.
"""

from __future__ import annotations

import asyncio
import hmac
import ipaddress
import json
import logging
import math
import secrets
import sqlite3
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from aiohttp import web

from ...errors import ConfigError, UavlocError
from ..store import request_pack_fresh
from ..swaps import WAITING_FOR_PACK
from .feed import MapFeed

log = logging.getLogger(__name__)

DEFAULT_PORT = 8765
_STATIC = {"app.js": "text/javascript", "style.css": "text/css", "index.html": "text/html"}
_COOKIE = "uavloc_token"
# The header the page's script sends with a command: a page of another site cannot send it without
# a CORS preflight this server never answers, so a form or image elsewhere cannot launch a vehicle.
COMMAND_HEADER = "X-Uavloc-Command"


@dataclass(frozen=True)
class WebOptions:
    """``port`` 0 = any free port; ``port_fallback``: take a free port if ``port`` is busy (the
    default port, not one the operator asked for). ``tiles``: an XYZ URL template
    (``https://host/{z}/{x}/{y}.png``), a folder ``DIR/{z}/{x}/{y}.png`` or a ``.mbtiles`` file."""

    host: str = "127.0.0.1"
    port: int = DEFAULT_PORT
    token: str | None = None
    tiles: str | None = None
    period_s: float = 0.5
    port_fallback: bool = False
    keep: bool = False  # go on serving the final map after the search, until Ctrl-C

    def resolved_token(self) -> str | None:
        """The token the server requires: the given one, or a new random one for a non-loopback
        address; None (no token) on loopback unless one was given."""
        if self.token:
            return self.token
        return None if is_loopback(self.host) else secrets.token_urlsafe(16)


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _finite(o):
    if isinstance(o, float):
        return o if math.isfinite(o) else None
    if isinstance(o, dict):
        return {k: _finite(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_finite(v) for v in o]
    return o


def _dumps(o) -> str:
    """JSON the browser parses: NaN and infinities become null."""
    return json.dumps(_finite(o), allow_nan=False, separators=(",", ":"))


class _Tiles:
    """Background tiles: an XYZ URL (the browser fetches it), a folder or an MBTiles file (served)."""

    def __init__(self, spec: str | None):
        self.url: str | None = None
        self.folder: Path | None = None
        self.mbtiles: Path | None = None
        if not spec:
            return
        if spec.startswith(("http://", "https://")):
            if not all(k in spec for k in ("{z}", "{x}", "{y}")):
                raise ConfigError(f"--map-tiles URL {spec!r} needs {{z}}, {{x}} and {{y}} in it")
            self.url = spec
            return
        p = Path(spec)
        if p.is_dir():
            self.folder = p
        elif p.is_file() and p.suffix == ".mbtiles":
            self.mbtiles = p
        else:
            raise ConfigError(f"--map-tiles {spec!r} is neither a tile URL, a folder of z/x/y tiles nor a .mbtiles file")

    def page_template(self) -> str | None:
        return self.url or ("tiles/{z}/{x}/{y}" if self.folder or self.mbtiles else None)

    def read(self, z: int, x: int, y: int) -> tuple[bytes, str] | None:
        if self.folder is not None:
            for ext, ctype in ((".png", "image/png"), (".jpg", "image/jpeg"), (".jpeg", "image/jpeg"),
                               (".webp", "image/webp")):
                f = self.folder / str(z) / str(x) / f"{y}{ext}"
                if f.is_file():
                    return f.read_bytes(), ctype
            return None
        if self.mbtiles is not None:
            conn = sqlite3.connect(f"file:{self.mbtiles}?mode=ro", uri=True)
            try:
                row = conn.execute("SELECT tile_data FROM tiles WHERE zoom_level=? AND tile_column=? AND tile_row=?",
                                   (z, x, (1 << z) - 1 - y)).fetchone()  # MBTiles rows count from the south
            finally:
                conn.close()
            if row is None:
                return None
            data = bytes(row[0])
            return data, "image/jpeg" if data[:2] == b"\xff\xd8" else "image/png"
        return None


class MapServer:
    """Serve ``feed`` over HTTP. ``await start()`` then ``url``; ``await stop()``."""

    def __init__(self, feed: MapFeed, options: WebOptions = WebOptions()):
        self.feed = feed
        self.opt = options
        self.token = options.resolved_token()
        self.tiles = _Tiles(options.tiles)
        self._runner: web.AppRunner | None = None
        self._poller: asyncio.Task | None = None
        self._changed = asyncio.Condition()
        self._closing = False  # set by stop(): open event streams end, so shutting down does not wait
        self.port: int | None = None

    @property
    def url(self) -> str:
        host = self.opt.host
        shown = "127.0.0.1" if host in ("0.0.0.0", "::", "") else host
        if ":" in shown:
            shown = f"[{shown}]"
        url = f"http://{shown}:{self.port}/"
        return url + (f"?token={self.token}" if self.token else "")

    # -- lifecycle -----------------------------------------------------------------------------
    async def start(self) -> "MapServer":
        app = web.Application(middlewares=[self._auth])
        app.router.add_get("/", self._index)
        app.router.add_get("/static/{name}", self._static)
        app.router.add_get("/api/state", self._state)
        app.router.add_get("/api/stream", self._stream)
        app.router.add_get("/tiles/{z}/{x}/{y}", self._tile)
        app.router.add_post("/api/vehicles/{vehicle}/pack-fresh", self._pack_fresh)
        # an open event stream held Ctrl-C of `uavloc demo` for 124 s (aiohttp waits up to its
        # shutdown timeout, 60 s, for handlers); stop() ends the streams, this bounds the rest
        self._runner = web.AppRunner(app, access_log=None, handle_signals=False, shutdown_timeout=2.0)
        await self._runner.setup()
        try:
            await self._bind(self.opt.port)
        except OSError as exc:
            if not self.opt.port_fallback:
                await self._runner.cleanup()
                raise ConfigError(f"cannot serve the live map on {self.opt.host}:{self.opt.port} ({exc.strerror}); "
                                  "choose another --web-port (0 = any free port) or --no-web") from None
            log.info("port %s busy, serving the live map on a free port", self.opt.port)
            await self._bind(0)
        self._poller = asyncio.create_task(self._poll_loop(), name="web-poll")
        return self

    async def _bind(self, port: int) -> None:
        site = web.TCPSite(self._runner, self.opt.host, port, reuse_address=True)
        await site.start()
        sockets = site._server.sockets if site._server is not None else []  # noqa: SLF001 (port 0)
        self.port = sockets[0].getsockname()[1] if sockets else port

    async def stop(self) -> None:
        self._closing = True
        async with self._changed:
            self._changed.notify_all()
        if self._poller is not None:
            self._poller.cancel()
            try:
                await self._poller
            except asyncio.CancelledError:
                pass
        if self._runner is not None:
            await self._runner.cleanup()

    async def _poll_loop(self) -> None:
        while True:
            try:
                await asyncio.to_thread(self.feed.poll)
            except Exception:  # noqa: BLE001 - the map must never stop the search
                log.exception("live map: reading the store failed")
            async with self._changed:
                self._changed.notify_all()
            await asyncio.sleep(self.opt.period_s)

    # -- handlers ------------------------------------------------------------------------------
    @web.middleware
    async def _auth(self, request: web.Request, handler):
        if self.token is None:
            # Without a token only this machine's names are answered: a web page elsewhere cannot
            # read the map through a DNS name re-pointed at 127.0.0.1 (DNS rebinding).
            host = (request.host or "").rsplit(":", 1)[0].strip("[]")
            if not is_loopback(host):
                return web.Response(status=403, text="uavloc live map: open it as 127.0.0.1 or localhost\n")
            return await handler(request)
        given = request.query.get("token") or request.cookies.get(_COOKIE) or ""
        if not hmac.compare_digest(given.encode(), self.token.encode()):
            return web.Response(status=403, text="uavloc live map: open the URL the daemon printed "
                                "(it carries ?token=...)\n")
        response = await handler(request)
        if request.query.get("token") and isinstance(response, web.Response):
            response.set_cookie(_COOKIE, self.token, httponly=True, samesite="Strict")
        return response

    async def _index(self, request: web.Request) -> web.Response:
        return self._package_file("index.html")

    async def _static(self, request: web.Request) -> web.Response:
        name = request.match_info["name"]
        if name not in _STATIC:
            raise web.HTTPNotFound(text=f"no {name}\n")
        return self._package_file(name)

    def _package_file(self, name: str) -> web.Response:
        body = resources.files(__package__).joinpath("static", name).read_bytes()
        return web.Response(body=body, content_type=_STATIC[name], headers={"Cache-Control": "no-cache"})

    def _config(self) -> dict:
        return {"tiles": self.tiles.page_template(), "period_s": self.opt.period_s}

    async def _state(self, request: web.Request) -> web.Response:
        return web.json_response({**self.feed.state(), "config": self._config()}, dumps=_dumps)

    async def _pack_fresh(self, request: web.Request) -> web.Response:
        """The operator's "fresh pack" for a vehicle the map shows waiting for one: recorded in the
        store as ``uavloc pack-fresh`` records it; the daemon takes it at its next poll and still
        refuses a pack the vehicle reports as not fresh. One sentence back, also when refused."""
        def no(status: int, text: str) -> web.Response:
            return web.json_response({"ok": False, "text": text}, status=status)

        if request.headers.get(COMMAND_HEADER) != "pack-fresh":
            return no(403, f"a command needs the {COMMAND_HEADER} header the live map's page sends")
        origin = request.headers.get("Origin")
        if origin is not None and origin.split("://", 1)[-1] != request.host:
            return no(403, f"a command from another site ({origin}) is refused")
        try:
            vid = int(request.match_info["vehicle"])
        except ValueError:
            return no(404, f"no vehicle {request.match_info['vehicle']!r}")
        if self.feed.finished:
            return no(409, "the search has ended; no vehicle waits for a pack")
        shown = {v["id"]: v for v in self.feed.state().get("vehicles", [])}
        if vid not in shown:
            return no(404, f"there is no vehicle {vid} in this search (vehicles {sorted(shown)})")
        if shown[vid].get("phase") != WAITING_FOR_PACK:
            return no(409, f"vehicle {vid} does not wait for a pack (it is {shown[vid].get('phase') or 'not reporting'}); "
                           "nothing done")
        try:
            await asyncio.to_thread(request_pack_fresh, self.feed.store_path, vid)
        except (UavlocError, sqlite3.Error) as exc:
            return no(503, f"the request for vehicle {vid} was not recorded: {exc}")
        log.info("live map: the operator says vehicle %d has a fresh pack", vid)
        return web.json_response({"ok": True, "text": f"vehicle {vid}: fresh pack recorded; it is launched once it "
                                                      "reports nothing that says otherwise"}, status=202)

    async def _stream(self, request: web.Request) -> web.StreamResponse:
        resp = web.StreamResponse(headers={"Content-Type": "text/event-stream", "Cache-Control": "no-cache",
                                           "X-Accel-Buffering": "no"})
        await resp.prepare(request)
        cursor = self.feed.cursor()
        await self._send(resp, "state", {**self.feed.state(), "config": self._config()})
        try:
            while not self._closing:
                async with self._changed:
                    try:
                        await asyncio.wait_for(self._changed.wait(), timeout=15.0)
                    except TimeoutError:
                        await resp.write(b": keep-alive\n\n")
                        continue
                if self._closing:
                    break
                await self._send(resp, "delta", self.feed.delta(cursor))
        except (ConnectionResetError, asyncio.CancelledError):
            pass
        return resp

    @staticmethod
    async def _send(resp: web.StreamResponse, event: str, data: dict) -> None:
        await resp.write(f"event: {event}\ndata: {_dumps(data)}\n\n".encode())

    async def _tile(self, request: web.Request) -> web.Response:
        try:
            z, x = int(request.match_info["z"]), int(request.match_info["x"])
            y = int(request.match_info["y"].split(".")[0])
        except ValueError:
            raise web.HTTPNotFound() from None
        found = await asyncio.to_thread(self.tiles.read, z, x, y)
        if found is None:
            raise web.HTTPNotFound()
        return web.Response(body=found[0], content_type=found[1], headers={"Cache-Control": "max-age=3600"})
