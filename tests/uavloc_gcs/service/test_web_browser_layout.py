"""The live map of issue 29 item 5 in headless Chromium, at a narrow width: the map keeps a usable
height, each located person's lat/lon is in the people table, a run of like events is one line of
the timeline, and the clock stops when the search ends."""

from __future__ import annotations

import os
import queue
import subprocess
import sys
import threading

from .test_web_browser import ROOT, _browser, _shown, _wait, pytestmark  # noqa: F401 (skips without Chromium)


def test_narrow_live_map_latlon_events_and_clock(tmp_path):
    out = tmp_path / "demo"
    env = {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "uavloc_gcs", "demo", "--scenario", "small", "--people", "2", "--speedup", "10",
         "--base-port", "0", "--web-port", "0", "--web-keep", "--out", str(out)],
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

        page = _wait("the printed URL", url, 120, proc)
        driver = _browser(tmp_path / "chromium-profile")
        driver.set_window_size(420, 900)
        driver.get(page)
        text = lambda css: driver.execute_script("return document.querySelector(arguments[0]).innerText", css)
        height = lambda css: driver.execute_script(
            "return document.querySelector(arguments[0]).getBoundingClientRect().height", css)
        _wait("vehicles on the map", lambda: _shown(driver, "svg g.vehicle"), 120, proc)
        assert height("#map") >= 250, height("#map")  # was a 70 px strip at 420 px width
        _wait("someone located", lambda: _shown(driver, "svg g.person[data-state=located]"), 300, proc)
        latlon = _wait("lat/lon in the people table",
                       lambda: driver.execute_script(
                           "return Array.from(document.querySelectorAll('#people .latlon')).map(e => e.innerText)"),
                       30, proc)
        lat, lon = (float(v) for v in latlon[0].split(","))
        assert 40 < lat < 50 and 0 < lon < 20, latlon  # small.toml is over Zurich
        _wait("the search to finish", lambda: text("#link").startswith("search finished"), 600, proc)
        clock = text("#clock")
        import time

        time.sleep(3)
        assert text("#clock") == clock  # it stopped with the search (--web-keep serves on)
        events = driver.execute_script(
            "return Array.from(document.querySelectorAll('#events li')).map(e => e.dataset.key)")
        assert events and all(a != b for a, b in zip(events, events[1:])), events  # no run of like events
    finally:
        if driver is not None:
            driver.quit()
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
