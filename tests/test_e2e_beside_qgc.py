"""Beside QGroundControl: the search runs through a real MAVLink router (MAVProxy, from PyPI)
while a second ground station on the same router -- a stand-in for QGC, system id 255 -- sends
heartbeats and downloads every vehicle's mission again and again.

The daemon is system 245 (the default), so the vehicles keep two ground stations apart; the
search must still end with everyone located and every vehicle home, and the stand-in's mission
downloads must succeed (they see the missions the daemon uploaded).
"""

from __future__ import annotations

import asyncio
import shutil
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from tests.e2e_helpers import small_scenario
from tests.test_e2e_daemon import check_everyone_found
from uavloc_gcs.cli._fleet import start_fleet_process
from uavloc_gcs.service.daemon import DaemonOptions
from uavloc_gcs.service.run import run_search

pytestmark = pytest.mark.slow  # a whole search or demo: `pytest -m 'not slow and not sitl'` leaves it out

MAVPROXY = shutil.which("mavproxy.py") or str(Path(sys.executable).with_name("mavproxy.py"))


class QgcStandIn:
    """A second ground station: heartbeats as system 255 (QGC's id) and a full mission download
    from every vehicle every ``period_s`` (what QGC does when the operator opens the plan view)."""

    def __init__(self, connection: str, vehicles: list[int], period_s: float = 2.0):
        self.connection, self.vehicles, self.period_s = connection, vehicles, period_s
        self.downloads: dict[int, list[int]] = {v: [] for v in vehicles}  # item counts downloaded
        self.failures: list[str] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=lambda: asyncio.run(self._main()), daemon=True)

    async def _main(self) -> None:
        from uavloc_gcs.errors import LinkError
        from uavloc_gcs.link import download_mission, open_link

        async with await open_link(self.connection, source_system=255, source_component=190) as link:
            while not self._stop.is_set():
                for v in self.vehicles:
                    try:
                        items = await download_mission(link, v, 1)
                        self.downloads[v].append(len(items))
                    except LinkError as exc:
                        self.failures.append(f"vehicle {v}: {exc}")
                await asyncio.sleep(self.period_s)

    def __enter__(self) -> "QgcStandIn":
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join(30)


def two_free_ports() -> tuple[int, int]:
    """Two different free UDP ports for the router's two outputs (both held while choosing:
    free_port() alone returns the same port twice)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as a, socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as b:
        a.bind(("127.0.0.1", 0))
        b.bind(("127.0.0.1", 0))
        return a.getsockname()[1], b.getsockname()[1]


@pytest.mark.skipif(not Path(MAVPROXY).exists(), reason="MAVProxy is not installed (pip install MAVProxy, "
                    "part of the test extra) - it is the real router this test puts between the ground stations")
def test_search_through_a_router_beside_a_second_ground_station(tmp_path):
    sc = small_scenario("ardupilot", speedup=15.0)
    fleet = start_fleet_process(sc, speedup=sc.simulation.speedup, seed=sc.simulation.seed, base_port=0)
    daemon_port, qgc_port = two_free_ports()
    masters = [f"--master={conn}" for _, conn in fleet.endpoints]
    router = subprocess.Popen(
        [MAVPROXY, *masters, f"--out=udpin:127.0.0.1:{daemon_port}", f"--out=udpin:127.0.0.1:{qgc_port}",
         "--daemon", "--non-interactive", "--nowait", "--source-system=250", "--default-modules=",
         f"--state-basedir={tmp_path}"],
        cwd=tmp_path, stdin=subprocess.DEVNULL, stdout=open(tmp_path / "mavproxy.log", "wb"),
        stderr=subprocess.STDOUT, start_new_session=True)
    try:
        time.sleep(2.0)  # MAVProxy opens its ports
        assert router.poll() is None, (tmp_path / "mavproxy.log").read_text(errors="replace")[-2000:]
        conns = [(i + 1, f"udpout:127.0.0.1:{daemon_port}") for i in range(len(fleet.endpoints))]
        opts = DaemonOptions(store_path=tmp_path / "search.sqlite", tlog_dir=tmp_path, resume=False,
                             connect_timeout_s=30.0, lost_timeout_s=8.0)
        assert opts.source_system == 245
        with QgcStandIn(f"udpout:127.0.0.1:{qgc_port}", [1, 2]) as qgc:
            result = run_search(sc, conns, opts, tmp_path)
    finally:
        router.terminate()
        try:
            router.wait(10)
        except subprocess.TimeoutExpired:
            router.kill()
            router.wait(10)
        fleet.stop()
    check_everyone_found(sc, result)
    # the second ground station worked too: it downloaded each vehicle's missions during the search
    assert all(len(n) >= 3 for n in qgc.downloads.values()), (qgc.downloads, qgc.failures[:5])
    assert all(max(n) > 1 for n in qgc.downloads.values()), qgc.downloads  # it saw real missions
