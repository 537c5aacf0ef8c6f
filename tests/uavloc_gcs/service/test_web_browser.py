"""The live map in a real browser: a demo search on the fake fleet, the page in headless Chromium
(Debian's chromium + chromium-driver, driven by selenium). Vehicles must move on the map and
estimates appear without a reload; a screenshot is saved (to $UAVLOC_WEB_SCREENSHOT too if set)."""

from __future__ import annotations

import os
import queue
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
CHROMIUM = next((p for p in (shutil.which("chromium"), shutil.which("chromium-browser")) if p), None)
DRIVER = shutil.which("chromedriver")

try:
    import selenium  # noqa: F401
except ImportError:
    selenium = None

pytestmark = pytest.mark.skipif(
    CHROMIUM is None or DRIVER is None or selenium is None,
    reason="headless Chromium is not installed: run `apt-get install -y chromium chromium-driver` and "
           "`pip install selenium` (.ci/run does both) to test the live map in a real browser")

FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--disable-dev-shm-usage", "--window-size=1400,900")


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


def _vehicles(driver) -> dict[str, tuple[float, float]]:
    from selenium.webdriver.common.by import By

    return {e.get_attribute("data-id"): (float(e.get_attribute("data-east")), float(e.get_attribute("data-north")))
            for e in driver.find_elements(By.CSS_SELECTOR, "svg g.vehicle")}


def test_live_map_shows_vehicles_moving_and_estimates_appearing(tmp_path):
    from selenium.webdriver.common.by import By

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
        people = _wait("estimates on the map",
                       lambda: driver.find_elements(By.CSS_SELECTOR, "svg g.person"), 120, proc)
        assert people[0].get_attribute("data-label").startswith("P0")
        assert people[0].get_attribute("data-state") in ("heard", "located", "given up")
        assert driver.find_elements(By.CSS_SELECTOR, "svg polygon.area")
        assert driver.find_elements(By.CSS_SELECTOR, "svg polyline.track")
        assert driver.find_elements(By.CSS_SELECTOR, "svg g.scalebar text")
        table = driver.find_element(By.ID, "people").text
        assert "P01 #" in table
        assert "connected on" in driver.find_element(By.ID, "events").text  # the timeline
        assert driver.find_element(By.ID, "link").text == "live"
        # let the search go on a little so the picture shows tracks and (often) a plan
        _wait("someone located", lambda: driver.find_elements(By.CSS_SELECTOR, "svg g.person[data-state=located]"),
              120, proc)
        shot = tmp_path / "live_map.png"
        driver.save_screenshot(str(shot))
        assert shot.read_bytes()[:4] == b"\x89PNG"
        if os.environ.get("UAVLOC_WEB_SCREENSHOT"):
            shutil.copy(shot, os.environ["UAVLOC_WEB_SCREENSHOT"])
        assert proc.wait(timeout=300) == 0, "".join(log)[-3000:]
    finally:
        if driver is not None:
            driver.quit()
        if proc.poll() is None:
            proc.kill()
            proc.wait()
