"""The simulated air-to-ground channel against its model (uavloc_gcs/a2g.py): Monte Carlo of the
world -- many phones at one place, each an independent path -- checked against P_LoS, the frame,
burst and count probabilities and the burst likelihood; the sharing of shadowing within a burst
and its decorrelation over the distance flown; determinism in pieces."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim_link.world import World
from uavloc_gcs.a2g import A2GChannel
from uavloc_gcs.examples import scenario_path
from uavloc_gcs.scenario import load_scenario

PHONES_XY = (500.0, 300.0)


@pytest.fixture(scope="module")
def field():
    """examples/field.toml (urban), every phone at its nominal power."""
    return load_scenario(scenario_path("field")).replace(simulation={"tx_power_spread_db": 0.0})


def _first_bursts(sc, n_phones: int, h: float, z: float, seconds: float = 200.0, seed: int = 3):
    """A vehicle hovering ``h`` from ``n_phones`` static phones at one place, ``z`` above them. Per
    phone, its first burst that starts in the window: frames sent (all on listened channels), and
    the heard slots (mean RSSI, frames). Returns (world, list of (sent, rssi, counts))."""
    world = World.with_people(sc, np.tile(PHONES_XY, (n_phones, 1)), seed=seed)
    t = np.arange(0.0, seconds, sc.channel.slot_s)
    xyz = np.tile([PHONES_XY[0] + h, PHONES_XY[1], z], (len(t), 1))
    heard = world.hear_track(1, t, xyz)
    frames = world.emission.frames(0.0, seconds + 1.0)
    person = world.person_of(heard.address)
    slot = np.floor(frames.t_s / sc.channel.slot_s + 1e-9).astype(int)
    burst_of = {(int(p), int(a), int(s)): int(b) for p, a, s, b in zip(frames.person, frames.address, slot, frames.burst)}
    out = []
    for i in range(n_phones):
        mine = frames.person == i
        if not np.any(mine):
            continue
        b0 = int(frames.burst[mine].min())
        in_b0 = mine & (frames.burst == b0)
        if frames.t_s[in_b0].max() > seconds - 1.0:
            continue  # the burst runs past the window
        rows = [j for j in np.nonzero(person == i)[0]
                if burst_of.get((i, int(heard.address[j]), int(round(heard.t_s[j] / sc.channel.slot_s)))) == b0]
        out.append((int(in_b0.sum()), heard.rssi_dbm[rows], heard.n_samples[rows].astype(float)))
    return world, out


@pytest.fixture(scope="module")
def mid(field):
    """A look from 60 m at 150 m on the ground: line of sight with probability 0.29."""
    return _first_bursts(field, 1500, 150.0, 60.0)


def test_world_draws_line_of_sight_with_al_hourani_probability(field, mid):
    world, _ = mid
    a2g = A2GChannel.from_scenario(field)
    paths = world._paths[1]
    drawn = paths.key != -2  # pairs with at least one burst heard by the vehicle's radios
    p = float(a2g.los_probability(150.0, 60.0))
    n = int(drawn.sum())
    assert n > 800
    assert paths.los[drawn].mean() == pytest.approx(p, abs=4 * math.sqrt(p * (1 - p) / n))


def test_frames_and_bursts_are_heard_as_the_model_says(field, mid):
    _, bursts = mid
    a2g = A2GChannel.from_scenario(field)
    sent = np.array([k for k, _, _ in bursts], float)
    heard = np.array([c.sum() for _, _, c in bursts])
    assert len(bursts) > 800
    # frames: a ratio over bursts whose frames share their fate (cluster standard error)
    p = float(a2g.frame_heard_probability(150.0, 60.0))
    se = math.sqrt(np.sum((heard - p * sent) ** 2)) / sent.sum()
    assert heard.sum() / sent.sum() == pytest.approx(p, abs=4 * se + 1e-3)
    # bursts: at least one frame heard, each with its own frame count
    pb = np.array([float(a2g.burst_heard_probability(150.0, 60.0, k)) for k in sent])
    assert np.mean(heard > 0) == pytest.approx(pb.mean(), abs=4 * math.sqrt(np.sum(pb * (1 - pb))) / len(pb) + 1e-3)
    # counts: the distribution of heard frames among bursts of 5-12 frames (chi-square, 0 / 1-2 / 3-5 / 6+)
    edges = [0, 1, 3, 6, 1000]
    obs = np.zeros(4)
    exp = np.zeros(4)
    for k, n in zip(sent, heard):
        if 5 <= k <= 12:
            pmf = a2g.heard_count_pmf(150.0, 60.0, int(k))
            for j in range(4):
                exp[j] += pmf[edges[j]:edges[j + 1]].sum()
            obs[np.searchsorted(edges, n, side="right") - 1] += 1
    chi2 = float(np.sum((obs - exp) ** 2 / exp))
    assert exp.min() > 20 and chi2 < 16.3  # 3 degrees of freedom, p = 0.001


def test_burst_likelihood_peaks_at_the_true_distance(field, mid):
    """Summed over the simulated bursts the log-likelihood is highest at the true horizontal distance
    (known counts; and with the count unknown, under the frames law of the bursts)."""
    _, bursts = mid
    a2g = A2GChannel.from_scenario(field)
    grid = np.arange(60.0, 301.0, 5.0)
    known = np.zeros(len(grid))
    unknown = np.zeros(len(grid))
    sent = np.array([k for k, _, _ in bursts])
    pmf = np.bincount(sent, minlength=81).astype(float)
    for k, rssi, counts in bursts:
        known += a2g.burst_log_likelihood(rssi, int(k - counts.sum()), grid, 60.0, counts=counts)
        unknown += a2g.burst_log_likelihood_unknown_sent(rssi, pmf, grid, 60.0, counts=counts)
    assert abs(grid[np.argmax(known)] - 150.0) <= 10.0
    assert abs(grid[np.argmax(unknown)] - 150.0) <= 15.0
    assert known.max() - known[np.abs(grid - 250.0) < 1e-9][0] > 10.0  # and it tells them apart


def test_frames_of_a_burst_share_the_shadowing(field):
    """Nearly overhead (line of sight, every frame far above the sensitivity): frames of one burst
    differ by the fast fading alone, bursts of different phones also by the shadowing."""
    _, bursts = _first_bursts(field, 400, 5.0, 40.0, seconds=160.0, seed=9)
    a2g = A2GChannel.from_scenario(field)
    within, means, sizes = [], [], []
    for _, rssi, counts in bursts:
        single = rssi[counts == 1]
        if len(single) >= 3:
            within.append(((single - single.mean()) ** 2).sum() / (len(single) - 1) * (len(single) - 1))
            sizes.append(len(single) - 1)
            means.append(single.mean())
    pooled = np.sum(within) / np.sum(sizes)
    fast, shadow = a2g.fast_db[0], a2g.shadow_db[0]
    assert pooled == pytest.approx(fast ** 2, rel=0.1)
    assert np.var(means) == pytest.approx(shadow ** 2, rel=0.25)  # plus fast^2 / n, a few %


def test_elicited_frames_decorrelate_over_the_distance_flown(field):
    """An access point makes the phones answer once a second while the vehicle circles them at 20 m
    radius (constant geometry, line of sight), 10 m/s: successive answers are 10 m apart, so their
    shadowing correlates by exp(-10 / 50); ten apart, by exp(-2)."""
    sc = field.replace(emission={"elicitation_rate_hz": 1.0})
    n = 120
    world = World.with_people(sc, np.tile(PHONES_XY, (n, 1)), seed=2)
    a2g = A2GChannel.from_scenario(sc)
    t = np.arange(0.0, 600.0, sc.channel.slot_s)
    ang = t * 10.0 / 20.0
    xyz = np.column_stack([PHONES_XY[0] + 20 * np.cos(ang), PHONES_XY[1] + 20 * np.sin(ang), np.full_like(t, 60.0)])
    heard = world.hear_track(1, t, xyz)
    person = world.person_of(heard.address)
    elicited = np.isin(heard.address, world.emission.network_address[world.emission.randomizes])
    rho = {}
    for lag in (1, 10):
        xs, ys = [], []
        for i in range(n):
            r = heard.rssi_dbm[elicited & (person == i) & (heard.n_samples == 1)]
            tt = heard.t_s[elicited & (person == i) & (heard.n_samples == 1)]
            if len(r) > 50:
                # pairs of answers about ``lag`` seconds apart (a Poisson stream: keep gaps within 20 %)
                j = np.searchsorted(tt, tt + lag)
                ok = j < len(tt)
                ok[ok] &= np.abs(tt[j[ok]] - tt[ok] - lag) < 0.2 * lag
                xs.append(r[ok] - r.mean())
                ys.append(r[j[ok]] - r.mean())
        x, y = np.concatenate(xs), np.concatenate(ys)
        rho[lag] = float(np.corrcoef(x, y)[0, 1])
    share = a2g.shadow_db[0] ** 2 / (a2g.shadow_db[0] ** 2 + a2g.fast_db[0] ** 2)
    assert rho[1] == pytest.approx(math.exp(-10.0 / 50.0) * share, abs=0.08)
    assert rho[10] == pytest.approx(math.exp(-100.0 / 50.0) * share, abs=0.08)


def test_a_far_phone_is_never_heard_and_the_planning_range_is_line_of_sight(field):
    world = World.with_people(field, [PHONES_XY], seed=1)
    t = np.arange(0.0, 3600.0, field.channel.slot_s)
    heard = world.hear_track(1, t, np.tile([PHONES_XY[0] + 1500.0, PHONES_XY[1], 100.0], (len(t), 1)))
    assert len(heard) == 0  # 1.5 km at 3.8 deg: line of sight 1.5 %, and then 15 dB short
    assert world.hearing_range_m() == pytest.approx(A2GChannel.from_scenario(field).state_range_m(0))


def test_air_to_ground_world_is_deterministic_in_pieces(field):
    sc = field.replace(simulation={"tx_power_spread_db": 3.0}, emission={"elicitation_rate_hz": 0.5})
    t = np.arange(0.0, 240.0, sc.channel.slot_s)
    xyz = np.column_stack([200.0 + 4.0 * t, np.full_like(t, 320.0), np.full_like(t, 40.0)])
    whole = World(sc, people=40, seed=5).hear_track(1, t, xyz)
    assert len(whole) > 20
    w = World(sc, people=40, seed=5)
    parts = []
    for a in range(0, len(t), 397):  # uneven pieces (bursts cut in two), a second vehicle interleaved
        w.hear_track(2, t[a : a + 397], xyz[a : a + 397] + [0, 60, 0])
        parts.append(w.hear_track(1, t[a : a + 397], xyz[a : a + 397]))
    got = parts[0].concat(parts)
    assert np.array_equal(got.address, whole.address) and np.array_equal(got.n_samples, whole.n_samples)
    assert np.allclose(got.rssi_dbm, whole.rssi_dbm, atol=1e-9)  # the shadowing's recursion in blocks


def test_without_an_environment_the_field_world_is_as_before_issue_41(field):
    """Golden numbers from the code before the air-to-ground channel (commit dda46b4): field.toml's
    log-distance channel of then, elicitation on (as it was then: every phone answers within reach,
    the named variant ``elicitation_join = "in-reach"``), one vehicle's slant flight."""
    sc = field.replace(channel={"environment": None, "path_loss_exponent": 2.3, "reference_power_dbm": -40.0},
                       simulation={"tx_power_spread_db": 3.0},
                       emission={"elicitation_rate_hz": 0.5, "elicitation_join": "in-reach"})
    w = World(sc, seed=7, people=12)
    t = np.arange(0.0, 300.0, 0.025)
    s = w.hear_track(1, t, np.column_stack([3.5 * t, 250.0 + 0.2 * t, np.full_like(t, 100.0)]))
    assert len(s) == 99 and int(s.n_samples.sum()) == 105 and int(s.address[:3].sum()) == 629913855096477
    assert np.round(s.rssi_dbm[:6], 9).tolist() == [-89.258049866, -85.898871706, -85.020001125, -89.337412977,
                                                    -87.370827042, -88.105891093]
    assert round(float(s.rssi_dbm.sum()), 6) == -8537.631657
