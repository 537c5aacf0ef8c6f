"""The live map's "fresh pack fitted" button in headless Chromium (issue 38 item 2): shown for a
vehicle waiting for a pack and no other, two clicks (the first asks), and the operator's word is
in the store, where the daemon takes it as it takes `uavloc pack-fresh`
(tests/uavloc_gcs/service/test_daemon_sorties.py). The server alone, fed a snapshot with one
vehicle waiting: no search is needed to press a button."""

from __future__ import annotations

import os

from tests.e2e_helpers import small_scenario
from tests.uavloc_gcs.service.test_web_browser import _served, _wait, pytestmark  # noqa: F401
from uavloc_gcs.service.liveview import StatusSnapshot, VehicleStatus
from uavloc_gcs.service.store import PACK_FRESH_REQUEST, Store, StoreReader
from uavloc_gcs.service.web import MapFeed


def test_the_fresh_pack_button_asks_once_and_records_the_operators_word(tmp_path):
    sc = small_scenario()
    store = Store(tmp_path / "search.sqlite", commit_interval_s=0.01)
    store.set_meta("epoch_unix_s", 1_795_000_000.0)
    store.flush()
    snap = StatusSnapshot(20.0, [VehicleStatus(1, "waiting for pack", "LAND", 12.0),
                                 VehicleStatus(2, "localizing", "AUTO", 80.0)], [], 0, 15.0, 1)
    def requests():
        with StoreReader(store.path) as rd:
            return [e.vehicle for e in rd.events(PACK_FRESH_REQUEST)]

    try:
        with _served(MapFeed(sc, store.path, snapshot=lambda: snap), tmp_path / "chromium-profile") as (server, driver):
            driver.get(server.url)

            def buttons():
                return driver.execute_script(
                    "return Array.from(document.querySelectorAll('#vehicles button.fresh'))"
                    ".map(b => [b.getAttribute('data-vehicle'), b.textContent])")

            assert _wait("the fresh-pack button", buttons, 60) == [["1", "fresh pack fitted"]]  # not vehicle 2's row
            click = "document.querySelector('#vehicles button.fresh[data-vehicle=\"1\"]').click()"
            driver.execute_script(click)
            assert _wait("the button asking to be sure", lambda: buttons() == [["1", "sure? click again"]], 10)
            assert requests() == []  # one click records nothing
            if os.environ.get("UAVLOC_WEB_SCREENSHOT"):
                driver.save_screenshot(os.environ["UAVLOC_WEB_SCREENSHOT"])
            driver.execute_script(click)
            said = _wait("the server's sentence under the button", lambda: driver.execute_script(
                "const s = document.querySelector('#vehicles tr[data-vehicle=\"1\"] .said'); return s && s.textContent"),
                20)
            assert said.startswith("vehicle 1: fresh pack recorded"), said
            assert requests() == [1]
    finally:
        store.close()
