"""The achieved-POD accumulator: coverage from flown positions, not from the plan."""

import numpy as np
import pytest

from tests.e2e_helpers import FIELD, small_scenario
from uavloc_gcs.search.coverage import Coverage, final_summary, summarize, window_probs



def _lane(cov, vehicle, y, x0, x1, t0=0.0, speed=15.0, alt=60.0, dt=0.5):
    n = int(abs(x1 - x0) / (speed * dt)) + 1
    xs = np.linspace(x0, x1, n)
    t = t0 + np.abs(xs - x0) / speed
    cov.add_track(vehicle, t, np.column_stack([xs, np.full(n, y), np.full(n, alt)]))
    return float(t[-1])


def test_paper_world_lane_covers_its_band_only_at_survey_altitude():
    sc = small_scenario()
    r = sc.horizontal_range_m
    cov = Coverage(sc)
    xy = cov.grid.xy_m
    assert cov.overall() == 0.0 and cov.summary().nothing_flown
    # a lane at y = 60 m flown at survey altitude: every cell within R of it is searched
    _lane(cov, 1, 60.0, xy[:, 0].min() - 20, xy[:, 0].max() + 20)
    pod = cov.pod(1)
    near = np.abs(xy[:, 1] - 60.0) < r - 1.0
    far = np.abs(xy[:, 1] - 60.0) > r + 1.0
    assert near.any() and far.any()
    assert np.all(pod[near] == 1.0) and np.all(pod[far] == 0.0)
    # the same lane flown low (taking off, landing) by another vehicle adds nothing
    cov2 = Coverage(sc)
    _lane(cov2, 2, 180.0, xy[:, 0].min(), xy[:, 0].max(), alt=10.0)
    assert cov2.overall() == 0.0
    s = cov.summary(target=0.9, density_per_km2=100.0)
    assert s.unsearched_m2 == pytest.approx(np.sum(pod == 0) * cov.grid.cell_area_m2)
    assert s.expected_missed == pytest.approx(100.0 * s.unsearched_m2 / 1e6)
    assert "Unsearched" in s.sentence() and "east" in s.unsearched_where()


def test_a_gap_in_the_telemetry_is_not_flown():
    sc = small_scenario()
    cov = Coverage(sc)
    xy = cov.grid.xy_m
    # two positions 60 s apart at the two ends of the area: the ground does not know the path between
    cov.add_position(1, 0.0, (xy[:, 0].min(), 60.0, 60.0))
    cov.add_position(1, 60.0, (xy[:, 0].max(), 60.0, 60.0))
    mid = np.abs(xy[:, 0] - xy[:, 0].mean()) < 50
    assert np.all(cov.pod(1)[mid] == 0.0)


def test_burst_world_pod_grows_with_passes_and_is_below_one():
    sc = small_scenario(extra=FIELD)
    cov = Coverage(sc)
    xy = cov.grid.xy_m
    cell = int(np.argmin(np.linalg.norm(xy - xy.mean(axis=0), axis=1)))
    y = float(xy[cell, 1])
    t = _lane(cov, 1, y, xy[:, 0].min(), xy[:, 0].max())
    one = float(cov.pod(1)[cell])
    assert 0.0 < one < 0.9, "a fly-by at 15 m/s catches a phone bursting every 20-135 s only sometimes"
    _lane(cov, 1, y, xy[:, 0].max(), xy[:, 0].min(), t0=t + 30.0)  # a second, separate pass
    two = float(cov.pod(1)[cell])
    # the same phones stay rare probers, or silent, from pass to pass: less than two independent passes
    assert one < two < 1 - (1 - one) ** 2
    assert cov.pod(2)[cell] < two
    # the live figure stays near search.pod's model of the same flown tracks (the final claims')
    final = final_summary(cov)
    assert abs(final.pod1[cell] - two) < 0.1, (final.pod1[cell], two)
    assert abs(final.overall1 - cov.overall()) < 0.1
    p1, p2 = window_probs(sc, np.array([0.0, 10.0, 1000.0]))
    assert p1[0] == 0.0 and p1[1] < p1[2] and np.all(p2 <= p1)


def test_summary_of_nothing_flown_says_so():
    sc = small_scenario()
    cov = Coverage(sc)
    s = summarize(cov.grid, cov.pod(1), cov.pod(2), 0.9, None)
    assert s.nothing_flown and s.sentence().startswith("Nothing flew")
    assert s.expected_missed is None


def test_a_restarted_daemon_gets_back_what_was_flown_from_the_store(tmp_path):
    from uavloc_gcs.search.coverage import add_stored
    from uavloc_gcs.service.store import Store, TelemetryRow

    sc = small_scenario()
    xs = np.linspace(0.0, 400.0, 60)
    ll = sc.frame.to_wgs84_latlon(np.column_stack([xs, np.full(60, 100.0)]))
    with Store(tmp_path / "s.sqlite") as st:
        st.add_telemetry([TelemetryRow(float(i), 1, float(a), float(b), 60.0, 90.0, "AUTO", 1, False)
                          for i, (a, b) in enumerate(ll)])
    fresh = Coverage(sc)
    _lane(fresh, 1, 100.0, 0.0, 400.0, speed=400.0 / 59.0, dt=1.0)
    resumed = Coverage(sc)
    assert add_stored(resumed, tmp_path / "s.sqlite") == 60
    assert resumed.overall() > 0.5
    assert np.allclose(resumed.pod(1), fresh.pod(1), atol=0.02)


def _half_flown(sc):
    """Coverage of the small scenario with only its southern half flown by vehicle 1."""
    cov = Coverage(sc)
    t = 0.0
    for i, y in enumerate(range(10, 130, 40)):
        a, b = (0.0, 400.0) if i % 2 == 0 else (400.0, 0.0)
        t = _lane(cov, 1, float(y), a, b, t0=t)
    return cov, t


def test_replans_while_passes_are_flown_do_not_use_up_the_rounds():
    """The CI failure of 2026-11-26: every replan while vehicle 1 flew its passes counted as a new
    round (the area's POD had risen), the cap of rounds was reached with the lanes unflown and the
    search ended with part of the area unsearched. A round now counts once its ETA is past."""
    from types import SimpleNamespace

    from uavloc_gcs.planning.problem import VehicleState
    from uavloc_gcs.search import coverage as cm
    from uavloc_gcs.search import passes
    from uavloc_gcs.search.policy import SearchPlan, VehicleTask

    sc = small_scenario()
    cov, t = _half_flown(sc)
    policy = SimpleNamespace(coverage=cov, scenario=sc, speed_m_s=15.0)
    vehicles = [VehicleState("1", (200.0, 120.0), (0.0, 0.0), 1e6)]
    plan = SearchPlan((VehicleTask("1", np.array([[0.0, 0.0]]), (), t),), 0.0, 0.0)
    first = passes.add_passes(policy, t, vehicles, plan)
    assert cov.pass_rounds == 1 and len(first.tasks[0].waypoints_xy_m) > 2  # lanes, then home
    end = cov._round_end_s
    assert end > t
    # replans before the passes' ETA (the POD rises as they are flown) stay in round 1
    for k in range(1, 6):
        _lane(cov, 1, 160.0 + 10 * k, 0.0, 50.0, t0=t + 5 * k)
        passes.add_passes(policy, t + 5 * k, vehicles, plan)
    assert cov.pass_rounds == 1
    assert cov._round_end_s == end  # nor do they push the round's end (a search would never end)
    assert passes.passes_wanted(policy)
    passes.add_passes(policy, end + 1.0, vehicles, plan)  # the round is over: a new one
    assert cov.pass_rounds == 2
    # the reason the passes ended is said as it was
    assert final_summary(cov).passes_end == ""
    cov.pass_rounds = cm.MAX_PASS_ROUNDS
    assert "rounds of extra passes" in final_summary(cov).passes_end
    cov.passes_exhausted = True
    assert "energy" in final_summary(cov).passes_end


def test_air_to_ground_live_pod_follows_the_flight_height():
    """Under an air-to-ground environment the live figure looks hearing up by the flight's own height
    (a lane at 60 m hears a cell 90 m aside more often than one at 32 m) and stays near the model.
    (Positions below half the fleet altitude do not count at all: coverage.py's survey rule.)"""
    sc = small_scenario(extra=FIELD.replace("[channel]\n", "[channel]\nenvironment = \"urban\"\n"))
    assert sc.channel.environment == "urban"
    pods = {}
    for alt in (60.0, 32.0):
        cov = Coverage(sc)
        xy = cov.grid.xy_m
        cell = int(np.argmin(np.linalg.norm(xy - xy.mean(axis=0), axis=1)))
        _lane(cov, 1, float(xy[cell, 1]) + 90.0, xy[:, 0].min(), xy[:, 0].max(), alt=alt)
        pods[alt] = float(cov.pod(1)[cell])
        final = final_summary(cov)
        assert abs(final.pod1[cell] - pods[alt]) < 0.1, (alt, final.pod1[cell], pods[alt])
    assert 0.0 < pods[32.0] < 0.7 * pods[60.0]
