"""End to end on the fake fleet: a scenario geofence with a notch cut out of the search area. Every
position the vehicles reported, scan and looks and the ways home, lies inside the fence (issue 26
item 4: "and inside a geofence when the scenario gives one")."""

import numpy as np
import pytest
from shapely.geometry import Point, Polygon

from tests.e2e_helpers import small_scenario
from uavloc_gcs.cli._fleet import start_fleet_process
from uavloc_gcs.service.daemon import DaemonOptions
from uavloc_gcs.service.run import run_search
from uavloc_gcs.service.store import StoreReader

pytestmark = pytest.mark.slow  # a whole search or demo: `pytest -m 'not slow and not sitl'` leaves it out

# the small area is 400 m x 250 m from the launch corner; the team may not fly over its north-east
# part (x > 250 m, y > 120 m), where the lanes and looks would otherwise go
FENCE_XY = np.array([(-20, -20), (420, -20), (420, 120), (250, 120), (250, 270), (-20, 270)], float)


def test_every_reported_position_of_a_fenced_search_lies_inside_the_fence(tmp_path):
    base = small_scenario(seed=5)
    sc = base.replace(area={"geofence_deg": base.frame.to_wgs84_latlon(FENCE_XY).tolist(),
                            "geofence_margin_m": 20.0})
    fleet = start_fleet_process(sc, speedup=sc.simulation.speedup, seed=sc.simulation.seed, base_port=0)
    try:
        opts = DaemonOptions(store_path=tmp_path / "search.sqlite", tlog_dir=tmp_path, resume=False)
        conns = [(i + 1, c) for i, (_n, c) in enumerate(fleet.endpoints)]
        result = run_search(sc, conns, opts, tmp_path)
    finally:
        fleet.stop()
    fence = Polygon(FENCE_XY).buffer(1.0)
    notch = Polygon([(250, 120), (400, 120), (400, 250), (250, 250)])
    with StoreReader(tmp_path / "search.sqlite") as rd:
        tracks = rd.tracks()
        uploads = rd.events("upload")
    assert len(tracks) == 2 and all(len(t) > 50 for t in tracks.values())
    near_notch = 0
    for v, ll in tracks.items():
        xy = sc.frame.to_local_xy(ll)
        out = [q for q in xy if not fence.covers(Point(q))]
        assert not out, f"vehicle {v} flew outside the fence, e.g. at {out[0]} m"
        near_notch += sum(notch.distance(Point(q)) < 25.0 for q in xy)
    assert near_notch, "the search flew along the notch's edge (the test would hold for a search far from it)"
    assert uploads, "looks were flown (the fence held beyond the scan)"
    assert result.outcome.statement
