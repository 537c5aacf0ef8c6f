"""The live map over a mountain, in headless Chromium: the contour lines of the scenario's DEM are
drawn under the area (issue 28 item 6; until now only the pictures had been looked at). The
server alone, fed a store with a short track: no search is needed to draw the ground."""

from __future__ import annotations

import os
import shutil

from tests.uavloc_gcs.service.test_web_browser import _served, _shown, _wait, pytestmark  # noqa: F401
from uavloc_gcs.examples import scenario_path
from uavloc_gcs.scenario import load_scenario
from uavloc_gcs.service.store import Store, TelemetryRow
from uavloc_gcs.service.web import MapFeed


def test_the_live_map_draws_the_terrain_contours_under_the_area(tmp_path):
    sc = load_scenario(scenario_path("mountains"))
    store = Store(tmp_path / "search.sqlite", commit_interval_s=0.01)
    store.set_meta("epoch_unix_s", 1_795_000_000.0)
    rows = []
    for k in range(5):
        lat, lon = sc.frame.to_wgs84(100.0 * k, 50.0)
        rows.append(TelemetryRow(float(k), 1, float(lat), float(lon), 100.0, 90.0, "AUTO", k, False))
    store.add_telemetry(rows)
    store.flush()

    try:
        with _served(MapFeed(sc, store.path), tmp_path / "chromium-profile") as (server, driver):
            driver.get(server.url)
            lines = _wait("contour lines on the map", lambda: _shown(driver, "svg g.terrain .contour"), 60)
            levels = sorted({float(c["data-level"]) for c in lines})
            # the Ammonoosuc flank rises some 400 m across the area: several round levels
            assert len(levels) >= 4 and levels[-1] - levels[0] >= 200.0, levels
            assert all(lv % 10 == 0 for lv in levels), levels
            labels = _shown(driver, "svg g.terrain text.clabel")  # each line says its height
            assert {float(t["data-level"]) for t in labels} == set(levels)
            text = driver.execute_script("return Array.from(document.querySelectorAll('svg text.clabel'))"
                                         ".map(t => t.textContent)")
            assert f"{round(levels[0])} m" in text, text
            assert _shown(driver, "svg polygon.area") and _shown(driver, "svg polyline.track")
            shot = tmp_path / "live_map_terrain.png"
            driver.save_screenshot(str(shot))
            assert shot.read_bytes()[:4] == b"\x89PNG"
            if os.environ.get("UAVLOC_WEB_SCREENSHOT"):
                shutil.copy(shot, os.environ["UAVLOC_WEB_SCREENSHOT"])
    finally:
        store.close()
