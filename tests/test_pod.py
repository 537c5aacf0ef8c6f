"""The probability-of-detection model (uavloc_gcs/search/pod.py) against the simulated world."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from uavloc_gcs.scenario import load_scenario
from uavloc_gcs.search import pod


@pytest.fixture(scope="module")
def field():
    return load_scenario("examples/field.toml")


def _strip(sc0):
    """The field world over a 600 x 1000 m strip centred on the launch point, static people."""
    frame = sc0.frame
    xy = np.array([[-300, -500], [300, -500], [300, 500], [-300, 500]], float)
    ll = frame.to_wgs84_latlon(xy)
    launch = frame.to_wgs84_latlon(np.zeros((1, 2)))[0]
    return sc0.replace(
        area={"polygon_deg": [list(map(float, p)) for p in ll], "origin_lat_deg": None, "origin_lon_deg": None,
              "width_m": None, "height_m": None},
        launch={"lat_deg": float(launch[0]), "lon_deg": float(launch[1])},
        simulation={"motion": "static"})


def _pass(t_start, x0, x1, slot_s, speed=25.0, alt=100.0):
    t = np.arange(0.0, abs(x1 - x0) / speed, slot_s)
    x = x0 + np.sign(x1 - x0) * speed * t
    return t_start + t, np.column_stack([x, np.zeros_like(x), np.full_like(x, alt)])


def _heard_bursts(world, tracks):
    """Distinct bursts heard per person along the tracks (one vehicle)."""
    from uavloc_gcs.observations import SlotBatch

    heard = SlotBatch.concat([world.hear_track(1, t, xyz) for t, xyz in tracks])
    person = world.person_of(heard.address)
    all_t = np.concatenate([t for t, _ in tracks])
    f = world.emission.frames(all_t[0] - 1.0, all_t[-1] + 1.0)
    slot = all_t[np.maximum(np.searchsorted(all_t, f.t_s, side="right") - 1, 0)]
    burst_of = {(int(p), int(a), round(float(s), 6)): int(b) for p, a, s, b in zip(f.person, f.address, slot, f.burst)}
    b = np.array([burst_of[(int(p), int(a), round(float(t), 6))]
                  for p, a, t in zip(person, heard.address, heard.t_s)], dtype=int)
    return np.array([len(np.unique(b[person == i])) for i in range(len(world))])


@pytest.mark.parametrize("alt", [100.0, 40.0])
def test_pod_from_tracks_agrees_with_the_simulated_world(field, alt):
    """Two straight passes (25 m/s, at ``alt``) 10 minutes apart over 900 static phones in three burst
    worlds (field.toml's urban air-to-ground channel), three hours into the phones' lives (the steady
    state the model assumes): the fractions heard at least once and twice equal the area POD within
    Monte-Carlo error, at the flight's own height."""
    from sim_link.world import World

    sc = _strip(field)
    t0 = 3 * 3600.0
    slot = sc.channel.slot_s
    first = _pass(t0, -1500.0, 1500.0, slot, alt=alt)
    second = _pass(first[0][-1] + 600.0, 1500.0, -1500.0, slot, alt=alt)
    grid = pod.pod_from_tracks(sc, [(t[::40], x[::40]) for t, x in (first, second)], pod.grid_for(sc, 40.0))
    one_pass = pod.pod_from_tracks(sc, [(first[0][::40], first[1][::40])], pod.grid_for(sc, 40.0))
    counts, counts_one = [], []
    for seed in (1, 2, 3):
        counts.append(_heard_bursts(World(sc, seed=seed, people=300), [first, second]))
        counts_one.append(_heard_bursts(World(sc, seed=seed, people=300), [first]))
    counts, counts_one = np.concatenate(counts), np.concatenate(counts_one)
    n = len(counts)
    for k, got, want in ((1, np.mean(counts_one >= 1), one_pass.overall(1)),
                         (1, np.mean(counts >= 1), grid.overall(1)),
                         (2, np.mean(counts >= 2), grid.overall(2))):
        se = math.sqrt(want * (1 - want) / n)
        assert abs(got - want) < 4 * se + 0.01, (k, got, want, se)
    assert grid.overall(1) > 1.5 * one_pass.overall(1)  # the second pass is an independent look
    assert grid.overall(2) > (0.02 if alt >= 100 else 0.002)


def test_burst_timing_steady_state(field):
    bt = pod.BurstTiming.from_scenario(field)
    w = np.array([10.0, 60.0, 600.0, 3600.0])
    p1, p2 = bt.p_at_least(1, w), bt.p_at_least(2, w)
    assert np.all(np.diff(p1) > 0) and np.all(p2 <= p1) and np.all(np.diff(p2) > 0)
    # a short window: P(>= 1) = w / (mean gap) averaged over phones awake, times their awake share
    awake = 1 - bt.silence_share()
    assert p1[0] == pytest.approx(np.mean(awake * 10.0 / bt.mean_active_gap_s()), rel=0.05)
    # long silences make a 95 % window long: about an hour
    assert 1800 < bt.window_for(1, 0.95) < 2 * 3600
    assert bt.p_at_least(1, bt.window_for(1, 0.5)) >= 0.5
    quiet = field.replace(emission={"long_silence_per_gap": 0.0})
    assert pod.BurstTiming.from_scenario(quiet).window_for(1, 0.95) < 400
    paper = load_scenario("examples/paper.toml")
    cont = pod.BurstTiming.from_scenario(paper)
    assert cont.p_at_least(1, 0.03) == 1.0 and cont.p_at_least(1, 0.01) == 0.0
    assert cont.window_for(2, 0.95) == pytest.approx(0.05)


def test_p_burst_heard(field):
    from scipy.stats import norm

    from uavloc_gcs.a2g import A2GChannel

    # the log-distance channel (field.toml before issue 41): one frame, no spread: Phi((mu - S) / sigma);
    # the channel shares sum to 1 over 1/6/11
    one_frame = {"frames_per_burst_median_min": 1, "frames_per_burst_median_max": 1, "frames_per_burst_max": 1}
    logd = field.replace(channel={"environment": None, "path_loss_exponent": 2.3, "reference_power_dbm": -40.0})
    ch = logd.channel
    one = logd.replace(emission=one_frame, simulation={"tx_power_spread_db": 0.0})
    for d in (100.0, 149.0, 300.0):
        h = math.sqrt(d * d - 100.0**2) if d > 100 else 0.0
        mu = ch.reference_power_dbm - 10 * ch.path_loss_exponent * math.log10(d)
        want = norm.cdf((mu - ch.receiver_sensitivity_dbm) / ch.shadowing_sigma_db)
        assert pod.p_burst_heard(one, h, 100.0) == pytest.approx(want, abs=0.01)
    # the air-to-ground channel: one frame is the channel's frame probability, at any height
    one = field.replace(emission=one_frame, simulation={"tx_power_spread_db": 0.0})
    a2g = A2GChannel.from_scenario(field)
    for h, z in ((0.0, 100.0), (150.0, 60.0), (80.0, 30.0), (300.0, 100.0)):
        assert pod.p_burst_heard(one, h, z) == pytest.approx(float(a2g.frame_heard_probability(h, z)), abs=1e-6)
    # lower costs hearing at a distance, and a burst is heard further than a frame
    assert pod.p_burst_heard(field, 150.0, 30.0) < pod.p_burst_heard(field, 150.0, 100.0)
    assert pod.p_burst_heard(field, 150.0, 60.0) > pod.p_burst_heard(one, 150.0, 60.0)
    p = pod.p_burst_heard(field, np.array([0.0, 200.0, 400.0, 800.0]), 100.0, tx_offset_db=None)
    assert p[0] > 0.98 and np.all(np.diff(p) < 0) and p[-1] < 0.05
    # listening on one channel hears fewer bursts
    six = field.replace(channel={"listen_channels": [6]})
    assert pod.p_burst_heard(six, 200.0, 100.0) < pod.p_burst_heard(field, 200.0, 100.0)
    # the paper's gate
    paper = load_scenario("examples/paper.toml")
    assert list(pod.p_burst_heard(paper, np.array([100.0, 111.0, 112.0]), 100.0)) == [1.0, 1.0, 0.0]


def test_core_constants_equal_the_world():
    from sim_link.world import emission
    from uavloc_gcs.search import phones

    assert phones.PROBE_CHANNEL_SHARES == emission.CHANNEL_WEIGHTS
    assert phones.MIN_QUIET_S == emission.MIN_QUIET_S
    assert phones.FRAMES_LOG_SIGMA == emission.FRAMES_LOG_SIGMA


def test_paper_scan_pod_is_double_coverage():
    """The paper's world (continuous, gate): the paper scan hears every cell, most of them on two looks."""
    from uavloc_gcs.scan import plan_scan

    sc = load_scenario("examples/paper.toml")
    plan = plan_scan(sc)
    tracks = []
    for v in plan.vehicles:
        r = v.route_xy_m()
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(r, axis=0), axis=1))])
        t = np.arange(0.0, s[-1] / sc.fleet.speed_m_s, 1.0)
        xy = np.column_stack([np.interp(t * sc.fleet.speed_m_s, s, r[:, c]) for c in (0, 1)])
        tracks.append((t, np.column_stack([xy, np.full(len(t), sc.fleet.altitude_m)])))
    g = pod.pod_from_tracks(sc, tracks, pod.grid_for(sc, 40.0))
    assert g.overall(1) == 1.0
    # two looks (in-range runs more than 10 s apart): 84 % of people in docs/science/world.md
    assert 0.75 < g.overall(2) < 0.95, g.overall(2)
    fc = g.to_geojson(sc)
    assert len(fc["features"]) == int(g.inside.sum())
    f = fc["features"][0]
    assert set(f["properties"]) >= {"pod1", "pod2"} and len(f["geometry"]["coordinates"][0]) == 5
    lon, lat = f["geometry"]["coordinates"][0][0]
    assert abs(lat - sc.launch_latlon_deg[0]) < 0.02 and abs(lon - sc.launch_latlon_deg[1]) < 0.02
    json.dumps(fc)


def test_empty_grid(field):
    g = pod.grid_for(field)
    assert 900 < g.inside.sum() < 1500 and g.overall(1) == 0.0
    assert pod.pod_from_tracks(field, [], g).overall(2) == 0.0


def test_elicitation_adds_detections_as_the_world_does(field):
    """An on-board access point (0.2 Hz answers within the 50 % frame range): one pass over 600 phones
    in the steady state. Every phone answering within reach (``elicitation_join = "in-reach"``):
    heard at least once = the model's POD1 within Monte-Carlo error, and more than without
    elicitation. A mimicked network (the default, joined at a burst within reach): the model counts
    the bursts only, so it says what it says without the access point and the world hears at least
    that much (it never claims more than the world gives)."""
    from sim_link.world import World

    from benchmarks.pod_world import heard_bursts

    first = _pass(3 * 3600.0, -1500.0, 1500.0, field.channel.slot_s)
    track = [(first[0][::40], first[1][::40])]
    plain = pod.pod_from_tracks(_strip(field), track, pod.grid_for(_strip(field), 40.0))
    for join in ("in-reach", "scan"):
        sc = _strip(field).replace(emission={"elicitation_rate_hz": 0.2, "elicitation_join": join})
        grid = pod.pod_from_tracks(sc, track, pod.grid_for(sc, 40.0))
        counts = np.concatenate([heard_bursts(World(sc, seed=s, people=300), [first]) for s in (1, 2)])
        want = grid.overall(1)
        se = math.sqrt(want * (1 - want) / len(counts))
        if join == "in-reach":
            assert abs(np.mean(counts >= 1) - want) < 4 * se + 0.01
            assert want > plain.overall(1) + 0.05
        else:
            assert want == pytest.approx(plain.overall(1), abs=1e-6)
            assert np.mean(counts >= 1) > want - 4 * se
