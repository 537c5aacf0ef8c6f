"""The live map's feed and server without a browser: what the page gets from a store and a
snapshot, the token, the event stream, background tiles and port handling."""

from __future__ import annotations

import asyncio
import json
import math
import socket
import sqlite3

import aiohttp
import numpy as np
import pytest

from tests.e2e_helpers import small_scenario
from uavloc_gcs.errors import ConfigError
from uavloc_gcs.observations import SlotBatch
from uavloc_gcs.service.liveview import PersonStatusView, StatusSnapshot, VehicleStatus
from uavloc_gcs.service.store import EstimateRow, Store, TelemetryRow
from uavloc_gcs.service.web import MapFeed, MapServer, WebOptions
from uavloc_gcs.service.web.server import _dumps

SC = small_scenario()


def _slots(eids, t0=1.0):
    n = len(eids)
    return SlotBatch.from_columns(np.arange(n) + t0, np.ones(n), np.zeros((n, 3)), eids, np.full(n, -80.0),
                                  np.ones(n))


def _telemetry(store, vehicle, xy, t0=0.0):
    rows = []
    for k, (e, n) in enumerate(xy):
        lat, lon = SC.frame.to_wgs84(e, n)
        rows.append(TelemetryRow(t0 + k, vehicle, float(lat), float(lon), 60.0, 90.0 - k, "AUTO", k, False))
    store.add_telemetry(rows)


@pytest.fixture
def store(tmp_path):
    s = Store(tmp_path / "search.sqlite", commit_interval_s=0.01)
    s.set_meta("epoch_unix_s", 1_795_000_000.0)
    s.add_slots(_slots([70, 70, 5]))  # 70 heard first: P01, then 5: P02
    _telemetry(s, 1, [(0, 0), (0, 50), (0, 100)])  # flying north
    _telemetry(s, 2, [(0, 0), (40, 0)])  # flying east
    s.add_estimates([EstimateRow(10.0, 5, 100.0, 50.0, 0.0, 0.0, 9.0, 20.0, True, False, ""),
                     EstimateRow(11.0, 70, 200.0, 150.0, 0.5, 0.0, 40.0, 60.0, False, True, "mirror ambiguity")])
    s.add_plan(12.0, {"t_s": 12.0, "tasks": [{"vehicle": "1", "targets": [70], "waypoints_xy_m": [[210, 140], [0, 0]]}]})
    s.add_event("connect", "vehicle 1 connected", t_s=0.0, vehicle=1)
    s.add_event("plan", "vehicle 1 looks at 70, 5", t_s=12.0, vehicle=1)
    s.add_event("end", "1 of 2 people located; not located: person 70: mirror ambiguity.", t_s=30.0)
    s.flush()
    yield s
    s.close()


def test_feed_reads_the_store_labels_people_and_computes_headings(store):
    feed = MapFeed(SC, store.path)
    assert feed.poll()
    st = feed.state()
    assert [p["name"] for p in st["people"]] == ["P01 #70", "P02 #5"]  # order first heard, not id
    p70, p5 = st["people"]
    assert p70["state"] == "heard" and p70["ambiguous"] and p70["radius95_m"] == 40.0
    assert p5["state"] == "located" and p5["time_utc"] == "2026-11-18T11:06:50.0Z"
    v1, v2 = st["vehicles"]
    assert v1["heading_deg"] == 0.0 and v2["heading_deg"] == 90.0
    assert abs(v1["north_m"] - 100.0) < 0.5 and v1["battery_pct"] == 88.0
    assert len(st["tracks"]["1"]) == 3
    assert st["plan"]["tasks"][0]["looks_xy_m"] == [[210.0, 140.0]]  # home is not a look
    assert st["plan"]["tasks"][0]["labels"] == ["P01 #70"]
    assert [e["text"] for e in st["events"]] == ["vehicle 1 connected", "vehicle 1 looks at P01 #70, P02 #5",
                                                 "1 of 2 people located; not located: P01 #70: mirror ambiguity."]
    assert not feed.poll()  # nothing new


def test_feed_sends_only_what_a_page_has_not_seen(store):
    feed = MapFeed(SC, store.path)
    feed.poll()
    cur = feed.cursor()
    assert feed.delta(cur)["tracks_append"] == {} and feed.delta(cur)["events_append"] == []
    _telemetry(store, 1, [(0, 150), (0, 151), (0, 200)], t0=10.0)  # 1 m is below the track step
    store.add_event("lost", "vehicle 2 silent", t_s=13.0, vehicle=2)
    store.flush()
    assert feed.poll()
    d = feed.delta(cur)
    assert d["tracks_append"] == {"1": [[0.0, 150.0], [0.0, 200.0]]}
    assert [e["kind"] for e in d["events_append"]] == ["lost"]
    assert feed.delta(cur)["tracks_append"] == {}


def test_feed_shows_both_mirror_candidates_from_the_snapshot(store):
    view = PersonStatusView(70, 30.0, False, "mirror ambiguity", 200.0, 150.0, 11.0, 0.0, 0.0, True, 200.0, 50.0, 25.0)
    snap = StatusSnapshot(20.0, [VehicleStatus(1, "localizing", "AUTO", 80.0, 2, 5)], [view], 3, 15.0, 1)
    feed = MapFeed(SC, store.path, snapshot=lambda: snap)
    feed.poll()
    st = feed.state()
    (p,) = st["people"]
    assert (p["mirror_east_m"], p["mirror_north_m"], p["mirror_radius95_m"]) == (200.0, 50.0, 25.0)
    assert st["vehicles"][0]["phase"] == "localizing" and st["t_s"] == 20.0 and st["slots"] == 3
    # a mirror the area rules out (outside it, as the policy judges) is not shown as a candidate
    outside = PersonStatusView(70, 30.0, False, "95 % radius 30.0 m > 15 m", 200.0, 150.0, 11.0, 0.0, 0.0, True,
                               200.0, -150.0, 25.0)
    snap = StatusSnapshot(20.0, [], [outside], 3, 15.0, 1)
    (p,) = feed.state()["people"]
    assert not p["ambiguous"] and p["mirror_east_m"] is None
    assert json.loads(_dumps({"a": math.nan, "b": [math.inf, 1.0]})) == {"a": None, "b": [None, 1.0]}


def _run(coro):
    return asyncio.run(coro)


async def _serve(feed, **kw):
    return await MapServer(feed, WebOptions(port=0, period_s=0.05, **kw)).start()


def test_server_page_state_and_stream(store):
    async def go():
        server = await _serve(MapFeed(SC, store.path))
        try:
            assert server.url.startswith("http://127.0.0.1:") and "token" not in server.url
            async with aiohttp.ClientSession() as http:
                async with http.get(server.url) as r:
                    assert r.status == 200 and "<svg" in await r.text()
                async with http.get(server.url + "static/app.js") as r:
                    assert r.status == 200 and "EventSource" in await r.text()
                async with http.get(server.url + "static/secret.txt") as r:
                    assert r.status == 404
                async with http.get(server.url + "api/state", headers={"Host": "evil.example:80"}) as r:
                    assert r.status == 403  # no token: only this machine's names (DNS rebinding)
                async with http.get(server.url + "api/state", headers={"Host": "localhost"}) as r:
                    assert r.status == 200
                async with http.get(server.url + "api/state") as r:
                    assert (await r.json())["static"]["name"] == "e2e"
                async with http.get(server.url + "api/stream") as r:
                    events, track2 = [], []
                    async for line in r.content:
                        if line.startswith(b"event: "):
                            events.append(line[7:].strip().decode())
                            if events == ["state"]:  # now the store moves on
                                _telemetry(store, 2, [(100, 0), (200, 0)], t0=20.0)
                                store.flush()
                        elif line.startswith(b"data: ") and events[-1] == "delta":
                            track2 += json.loads(line[6:])["tracks_append"].get("2", [])
                            if [200.0, 0.0] in track2:
                                break
                    assert track2[-2:] == [[100.0, 0.0], [200.0, 0.0]]
        finally:
            await server.stop()

    _run(asyncio.wait_for(go(), 30))


def test_stopping_the_server_ends_open_event_streams_at_once(store):
    """Ctrl-C of `uavloc demo` with the map open in a browser took 124 s: aiohttp waited its
    shutdown timeout for the endless event stream. stop() now ends the streams first."""
    async def go():
        server = await _serve(MapFeed(SC, store.path))
        stopped = False
        try:
            async with aiohttp.ClientSession() as http:
                async with http.get(server.url + "api/stream") as r:
                    async for line in r.content:
                        if line.startswith(b"event: state"):
                            break
                    await asyncio.wait_for(server.stop(), 10.0)  # 60 s and more before
                    stopped = True
                    await asyncio.wait_for(r.content.read(), 10.0)  # returns: the server closed it
        finally:
            if not stopped:
                await server.stop()

    _run(asyncio.wait_for(go(), 60))


def test_other_addresses_need_the_token(store):
    assert WebOptions(host="0.0.0.0").resolved_token()  # the LAN gets a random token
    assert WebOptions().resolved_token() is None

    async def go():
        server = await _serve(MapFeed(SC, store.path), token="s3cret")
        try:
            base = server.url.split("?")[0]
            assert server.url.endswith("?token=s3cret")
            # like a browser, keep cookies of an IP address host
            async with aiohttp.ClientSession(cookie_jar=aiohttp.CookieJar(unsafe=True)) as http:
                async with http.get(base + "api/state") as r:
                    assert r.status == 403 and "token" in await r.text()
                async with http.get(base + "?token=wrong") as r:
                    assert r.status == 403
                async with http.get(server.url) as r:  # the printed URL sets the cookie ...
                    assert r.status == 200
                async with http.get(base + "api/state") as r:  # ... the page's script then works
                    assert r.status == 200
        finally:
            await server.stop()

    _run(go())


def test_background_tiles_from_a_folder_and_from_mbtiles(store, tmp_path):
    png = b"\x89PNG\r\n\x1a\nfake"
    (tmp_path / "xyz" / "15" / "17161").mkdir(parents=True)
    (tmp_path / "xyz" / "15" / "17161" / "11476.png").write_bytes(png)
    mb = tmp_path / "area.mbtiles"
    conn = sqlite3.connect(mb)
    conn.execute("CREATE TABLE tiles (zoom_level INTEGER, tile_column INTEGER, tile_row INTEGER, tile_data BLOB)")
    conn.execute("INSERT INTO tiles VALUES (2, 1, 0, ?)", (b"\xff\xd8jpeg",))  # row 0 = the southern row
    conn.commit()
    conn.close()

    async def fetch(spec, path):
        server = await _serve(MapFeed(SC, store.path), tiles=spec)
        try:
            async with aiohttp.ClientSession() as http:
                async with http.get(server.url + "api/state") as r:
                    template = (await r.json())["config"]["tiles"]
                async with http.get(server.url + path) as r:
                    return template, r.status, await r.read(), r.content_type
        finally:
            await server.stop()

    assert _run(fetch(str(tmp_path / "xyz"), "tiles/15/17161/11476")) == ("tiles/{z}/{x}/{y}", 200, png, "image/png")
    assert _run(fetch(str(tmp_path / "xyz"), "tiles/15/17161/11477"))[1] == 404
    assert _run(fetch(str(mb), "tiles/2/1/3")) == ("tiles/{z}/{x}/{y}", 200, b"\xff\xd8jpeg", "image/jpeg")
    url = "https://tiles.example/{z}/{x}/{y}.png"
    assert _run(fetch(url, "tiles/2/1/3"))[:2] == (url, 404)  # a URL is fetched by the browser
    with pytest.raises(ConfigError, match="neither a tile URL"):
        _run(fetch(str(tmp_path / "missing"), ""))


def test_a_busy_port_is_one_sentence_or_a_free_port_for_the_default(store):
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]

        async def go(fallback):
            server = await MapServer(MapFeed(SC, store.path), WebOptions(port=port, port_fallback=fallback)).start()
            await server.stop()
            return server.port

        with pytest.raises(ConfigError, match="--web-port"):
            _run(go(False))
        assert _run(go(True)) not in (port, 0)


def test_bad_web_options_are_one_sentence_before_anything_starts(tmp_path):
    import subprocess
    import sys

    for args, words in ((["--map-tiles", str(tmp_path / "none")], "--map-tiles"),
                        (["--web-port", "70000"], "--web-port"),
                        (["--map-tiles", "https://tiles.example/x.png"], "{z}")):
        proc = subprocess.run([sys.executable, "-m", "uavloc_gcs", "demo", "--out", str(tmp_path / "o"), *args],
                              capture_output=True, text=True, timeout=60)
        assert proc.returncode == 2, proc.stderr
        assert proc.stderr.count("\n") == 1 and words in proc.stderr
        assert not (tmp_path / "o").exists()  # nothing started, nothing written


@pytest.mark.slow
def test_web_keep_serves_the_final_result_as_the_files_say_until_ctrl_c(tmp_path):
    """With --web-keep the map stays up after the search and shows the written results (the
    same label, state and radius as people.csv); Ctrl-C then ends the demo normally."""
    import csv
    import os
    import signal
    import subprocess
    import sys
    import time
    import urllib.request
    from pathlib import Path

    root = Path(__file__).resolve().parents[3]
    out = tmp_path / "demo"
    env = {**os.environ, "PYTHONPATH": f"{root}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "uavloc_gcs", "demo", "--scenario", str(root / "examples" / "small.toml"),
         "--people", "2", "--speedup", "30", "--base-port", "0", "--web-port", "0", "--web-keep", "--out", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    try:
        url, deadline = None, time.monotonic() + 240
        for line in proc.stdout:
            if line.startswith("live map: "):
                url = line.split(": ", 1)[1].strip()
            if "until Ctrl-C" in line or time.monotonic() > deadline:
                break
        assert url is not None and proc.poll() is None
        with urllib.request.urlopen(url + "api/state", timeout=30) as r:
            state = json.loads(r.read())
        assert state["finished"]
        rows = {r["label"]: r for r in csv.DictReader((out / "people.csv").open()) if r["state"] != "never heard"}
        shown = {p["label"]: p for p in state["people"]}
        assert set(shown) == set(rows) and rows
        for label, row in rows.items():
            assert shown[label]["state"] == row["state"]
            # the page shows 0.1 m and the CSV 0.01 m of the same radius (11.7499 -> 11.7 and 11.75)
            assert abs(shown[label]["radius95_m"] - float(row["radius95_m"])) <= 0.05 + 1e-6
        # the people located by time, as results.txt says it (nothing when nobody was located)
        by = [line for line in (out / "results.txt").read_text().splitlines() if line.startswith("Located by")]
        assert state["located_by"] == (by[0] if by else "")
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=60) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_the_operator_says_a_waiting_vehicle_has_a_fresh_pack_and_nothing_else(store):
    """POST /api/vehicles/{id}/pack-fresh (issue 38 item 2): recorded in the store as `uavloc
    pack-fresh` records it, only for a vehicle the map shows waiting for a pack, only with the
    page's command header and from the page's own origin; every refusal one sentence."""
    from uavloc_gcs.service.store import PACK_FRESH_REQUEST, StoreReader

    snap = StatusSnapshot(20.0, [VehicleStatus(1, "waiting for pack", "LAND", 12.0),
                                 VehicleStatus(2, "localizing", "AUTO", 80.0)], [], 3, 15.0, 1)
    hdr = {"X-Uavloc-Command": "pack-fresh"}

    def requests():
        with StoreReader(store.path) as rd:
            return [e.vehicle for e in rd.events(PACK_FRESH_REQUEST)]

    async def go():
        feed = MapFeed(SC, store.path, snapshot=lambda: snap)
        server = await _serve(feed)
        try:
            async with aiohttp.ClientSession() as http:
                async def post(vid, headers):
                    async with http.post(server.url + f"api/vehicles/{vid}/pack-fresh", headers=headers) as r:
                        return r.status, (await r.json())["text"]

                # a form or a script of another site: refused before anything is read
                status, text = await post(1, {})
                assert status == 403 and "X-Uavloc-Command" in text
                status, text = await post(1, {**hdr, "Origin": "http://evil.example"})
                assert status == 403 and "evil.example" in text
                status, text = await post(2, hdr)
                assert status == 409 and text == "vehicle 2 does not wait for a pack (it is localizing); nothing done"
                status, text = await post(7, hdr)
                assert status == 404 and "no vehicle 7" in text and "[1, 2]" in text
                assert requests() == []
                status, text = await post(1, {**hdr, "Origin": server.url.rstrip("/")})
                assert status == 202 and text.startswith("vehicle 1: fresh pack recorded")
                assert requests() == [1]
                feed.finished = True
                status, text = await post(1, hdr)
                assert status == 409 and "ended" in text and requests() == [1]
        finally:
            await server.stop()

    _run(asyncio.wait_for(go(), 30))
