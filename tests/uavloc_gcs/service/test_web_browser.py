"""The live map in a real browser: a demo search on the fake fleet, the page in headless Chromium
(Debian's chromium + chromium-driver, driven by selenium). Vehicles must move on the map and
estimates appear without a reload; a screenshot is saved (to $UAVLOC_WEB_SCREENSHOT too if set)."""

from __future__ import annotations

import os
import queue
import shutil
import signal
import subprocess
import sys
import threading
import time
from contextlib import contextmanager
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
CHROMIUM = next((p for p in (shutil.which("chromium"), shutil.which("chromium-browser")) if p), None)
DRIVER = shutil.which("chromedriver")

try:
    import selenium  # noqa: F401
except ImportError:
    selenium = None

pytestmark = [pytest.mark.skipif(
    CHROMIUM is None or DRIVER is None or selenium is None,
    reason="headless Chromium is not installed: run `apt-get install -y chromium chromium-driver` and "
           "`pip install selenium` (.ci/run does both) to test the live map in a real browser"),
    pytest.mark.slow]  # a whole demo in a browser: `pytest -m 'not slow and not sitl'` leaves it out

FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--disable-dev-shm-usage", "--window-size=1400,900")


@contextmanager
def _served(feed, profile: Path):
    """A live-map server for ``feed`` on its own event loop in a thread, and a headless Chromium;
    yields (server, driver); stops both (pass or fail)."""
    import asyncio

    from uavloc_gcs.service.web import MapServer, WebOptions

    loop = asyncio.new_event_loop()
    started = threading.Event()
    box: dict = {}

    async def serve():
        box["server"] = await MapServer(feed, WebOptions(port=0, period_s=0.2)).start()
        started.set()

    thread = threading.Thread(target=lambda: (loop.run_until_complete(serve()), loop.run_forever()), daemon=True)
    thread.start()
    driver = None
    try:
        assert started.wait(30), "the map server started"
        driver = _browser(profile)
        yield box["server"], driver
    finally:
        if driver is not None:
            driver.quit()
        if "server" in box:
            asyncio.run_coroutine_threadsafe(box["server"].stop(), loop).result(30)
        loop.call_soon_threadsafe(loop.stop)
        thread.join(10)


def _browser(profile: Path):
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for f in FLAGS:
        opts.add_argument(f)
    opts.add_argument(f"--user-data-dir={profile}")
    return webdriver.Chrome(options=opts, service=Service(executable_path=DRIVER))


def _wait(what: str, check, timeout_s: float, proc=None):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = check()
        if value:
            return value
        if proc is not None and proc.poll() is not None:
            break
        time.sleep(0.3)
    raise AssertionError(f"timed out waiting for {what}")


# The page redraws its SVG on every update: read what it shows in one script call (element
# handles would go stale between two calls).
_READ = """return Array.from(document.querySelectorAll(arguments[0])).map(
    e => Object.fromEntries(Array.from(e.attributes).map(a => [a.name, a.value])));"""


def _shown(driver, css: str) -> list[dict]:
    return driver.execute_script(_READ, css)


def _vehicles(driver) -> dict[str, tuple[float, float]]:
    return {v["data-id"]: (float(v["data-east"]), float(v["data-north"])) for v in _shown(driver, "svg g.vehicle")}


def test_live_map_shows_vehicles_moving_and_estimates_appearing(tmp_path):
    out = tmp_path / "demo"
    env = {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "uavloc_gcs", "demo", "--scenario", str(ROOT / "examples" / "small.toml"),
         "--people", "3", "--speedup", "6", "--base-port", "0", "--web-port", "0", "--out", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env, cwd=tmp_path)
    lines: queue.Queue = queue.Queue()
    log: list[str] = []

    def pump():
        for line in proc.stdout:
            log.append(line)
            lines.put(line)

    threading.Thread(target=pump, daemon=True).start()
    driver = None
    try:
        def url():
            while not lines.empty():
                line = lines.get()
                if line.startswith("live map: "):
                    return line.split(": ", 1)[1].strip()
            return None

        page = _wait("the printed URL", url, 60, proc)
        assert page.startswith("http://127.0.0.1:")
        driver = _browser(tmp_path / "chromium-profile")
        driver.get(page)
        first = _wait("vehicles on the map", lambda: _vehicles(driver), 60, proc)

        def moved():
            now = _vehicles(driver)
            return any(v in now and abs(now[v][0] - p[0]) + abs(now[v][1] - p[1]) > 30.0 for v, p in first.items())

        _wait("a vehicle to move 30 m on the page (no reload)", moved, 90, proc)
        # a person can be drawn for one update before the store has committed its first slot (and
        # so its label): wait for a labelled one
        people = _wait("labelled estimates on the map",
                       lambda: [p for p in _shown(driver, "svg g.person") if p.get("data-label")], 120, proc)
        assert people[0]["data-label"].startswith("P0")
        assert people[0]["data-state"] in ("heard", "located", "given up")
        assert _shown(driver, "svg polygon.area") and _shown(driver, "svg polyline.track")
        assert _shown(driver, "svg g.scalebar")
        text = lambda css: driver.execute_script("return document.querySelector(arguments[0]).innerText", css)
        assert "P01 #" in text("#people")
        assert "connected on" in text("#events")  # the timeline
        assert text("#link") == "live"
        # let the search go on a little so the picture shows someone located and (often) a plan
        _wait("someone located", lambda: _shown(driver, "svg g.person[data-state=located]"), 120, proc)
        # the achieved POD of every cell (search/coverage.py) under the tracks, and the area's in the header
        cells = _wait("the POD layer", lambda: _shown(driver, "svg g.pod rect.podcell"), 60, proc)
        assert any(float(c["data-pod"]) > 0 for c in cells), "cells flown over have a POD above 0"
        assert "POD " in text("#summary") and "target" in text("#summary")
        shot = tmp_path / "live_map.png"
        driver.save_screenshot(str(shot))
        assert shot.read_bytes()[:4] == b"\x89PNG"
        if os.environ.get("UAVLOC_WEB_SCREENSHOT"):
            shutil.copy(shot, os.environ["UAVLOC_WEB_SCREENSHOT"])
        # the map is what is tested here; the demo's own end is tests/test_cli_demo.py's (waiting for
        # it took 150 s of the fast suite): Ctrl-C, and the demo stops as documented
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=120) == 128 + signal.SIGINT, "".join(log)[-3000:]
    finally:
        if driver is not None:
            driver.quit()
        if proc.poll() is None:
            proc.kill()
            proc.wait()
