"""The daemon against fake vehicles that behave as the real autopilots were measured to (issue 14):
nothing streamed until asked, PX4's stale "mission complete" after an upload, arming refused for
a while after boot. The whole search must still end with everyone located and the fleet home.
(The same behaviours against the real SITL: tests/sitl/test_daemon_search.py.)"""

import pytest

from tests.e2e_helpers import small_scenario
from tests.test_e2e_daemon import check_everyone_found
from uavloc_gcs.cli._fleet import start_fleet_process
from uavloc_gcs.service.daemon import DaemonOptions
from uavloc_gcs.service.run import run_search
from uavloc_gcs.service.store import StoreReader

pytestmark = pytest.mark.slow  # a whole search or demo: `pytest -m 'not slow and not sitl'` leaves it out

REAL = {"realistic_streams": True, "stale_mission_complete": True, "arm_refused_after_boot_s": None}


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_search_against_fakes_that_behave_like_the_real_autopilots(tmp_path, autopilot):
    sc = small_scenario(autopilot)
    fleet = start_fleet_process(sc, speedup=sc.simulation.speedup, seed=sc.simulation.seed, base_port=0,
                                vehicle_options=REAL)
    try:
        opts = DaemonOptions(store_path=tmp_path / "search.sqlite", tlog_dir=tmp_path, resume=False,
                             connect_timeout_s=30.0)
        conns = [(i + 1, c) for i, (_n, c) in enumerate(fleet.endpoints)]
        result = run_search(sc, conns, opts, tmp_path)
    finally:
        fleet.stop()
    check_everyone_found(sc, result)
    with StoreReader(tmp_path / "search.sqlite") as rd:
        scans_done = [e for e in rd.events("scan")]
        starts = [e for e in rd.events("start")]
    # the stale "complete" did not end any scan before it started: each finished after its start
    assert len(scans_done) == 2 and all(d.t_s > s.t_s + 10.0 for d, s in zip(scans_done, starts)), \
        [(e.t_s, e.text) for e in starts + scans_done]
    assert all(up <= 6 for _vid, _pl, up, _sk in result.outcome.uploads), result.outcome.uploads
