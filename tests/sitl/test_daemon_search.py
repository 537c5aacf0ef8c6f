"""Whole ``uavloc daemon`` searches against the real SITL autopilots (issue 14, item 1; issue 24
item 5: the field world).

Each: the companion emulators supply the RSSI of 3 simulated static people in a 300 m x 300 m
area; the daemon runs as a child process to its end. The searches in the field world (probe bursts,
a receiver threshold), checked for what they may honestly claim (daemon_run.field_check), are in
test_sitl_command.py: today's search flies look after look there (docs/guide/sitl.md), so the
tests here, which are about the look phase and the vehicles' start and state, keep the paper's
world, where people are heard often enough for looks to locate:
exit 0, every person heard located, at most one outside their 95 % circle and none outside their
99.9 % circle, a handful of uploads per vehicle; so does the previously-flown PX4 test, which is about
the autopilot's state between two searches. Two ArduCopters at once and a PX4, started by ``uavloc
sitl`` itself: test_sitl_command.py. Durations are in docs/guide/sitl.md.
"""

from __future__ import annotations

import math
import re

import pytest

from . import daemon_run as dr

MAX_UPLOADS_PER_VEHICLE = 6  # the scan, then a handful of look missions (issue 14: "a handful")
# A 95 % circle leaves one person in twenty outside by design, so "every person of every search
# inside" would fail a well-calibrated estimator in most runs of the suite (0.95 ** 30 = 21 % pass
# for 30 people). Each search of 3 people allows at most one outside its 95 % circle (0.7 % chance
# when calibrated) and none outside its 99.9 % circle; the suite's coverage over all searches is
# printed at the end of the run (conftest.py).
MAX_OUTSIDE_95 = 1
R999_PER_R95 = math.sqrt(math.log(1000.0) / math.log(20.0))  # circular 2-D normal: 1.519


def _check(run, scenario, vehicles):
    (run.out / "daemon-output.txt").write_text(run.output)
    assert run.code == 0, run.output[-3000:]
    rows = dr.truth_check(scenario, run.people)
    print("  (person, true error m, 95 % radius m, located):", [(e, round(err, 1), round(r, 1), ok)
                                                              for e, err, r, ok in rows])
    print("  " + "\n  ".join(line for line in run.output.splitlines()
                               if "per vehicle" in line or "speed" in line.lower() or "people heard" in line))
    assert rows, "nobody was heard"
    dr.COVERAGE.extend((err, r95) for _, err, r95, _ in rows)
    why = f"(person, true error, 95 % radius, located): {rows}\n{run.output[-2000:]}"
    assert all(r[3] for r in rows), "someone heard was not located " + why
    assert sum(1 for r in rows if not r[1] <= r[2]) <= MAX_OUTSIDE_95, "too many outside their 95 % circle " + why
    assert all(r[1] <= R999_PER_R95 * r[2] for r in rows), "someone outside their 99.9 % circle " + why
    m = re.search(r"per vehicle \(plans for it, uploads incl\. the scan, plans not uploaded\): (.*)", run.output)
    assert m, "the daemon reports its plans and uploads per vehicle"
    if m:
        uploads = [int(x.split("/")[1]) for x in re.findall(r"\d+: (\d+/\d+/\d+)", m.group(1))]
        assert all(u <= MAX_UPLOADS_PER_VEHICLE for u in uploads), m.group(0)
    for v in vehicles:
        ok, why = dr.landed_and_disarmed(v)
        assert ok, f"vehicle {v.sitl.sysid}: {why}"


SPARSE_SCAN = "[scan]\nlane_spacing_m = 220.0\ncoverage = \"single\""  # two lanes: people are left for looks
LOOKS_REQUIRED_M = 7.0  # the accuracy asked for in the look test: the scan alone must not meet it


@pytest.mark.parametrize("kind", ["ardupilot", "px4"])
def test_a_search_with_looks_replans_without_churn(sitl, tmp_path, kind):
    """A sparse scan leaves people unlocated, so the look phase runs on the real autopilot: the
    daemon replans and uploads looks in flight; a handful of uploads per vehicle at most. (PX4 was
    a non-strict xfail until 2026-11-24: look geometry and radius, issue 12. Since that day's
    estimator fixes it passed 24 of 25 runs (the last two: the sixth session's CI run and a full
    suite run of the seventh); the one failure was inside a full suite run and its store was not
    kept. One person, 38 m off the lane, is the hard one: in 10 runs alone 1.9-15.2 m off inside
    10.0-14.9 m, once outside (15.2 m, 11.2 m), which the check allows for one in three.)
    Since the turn models and the near-twin radius (2026-11-25) ArduCopter's sparse scan alone
    located all three within 15 m (radii 5.9-10.6 m, no look), so the test asks for 10 m: in the
    simulator, on the same geometry, 120 of 120 people located with looks, 0.958 inside
    (``uavloc bench looks --scenario benchmarks/scenarios/sitl_sparse_scan.toml --people 3
    --runs 40`` with ``required_accuracy_m = 10``). On 2026-11-29 (CI of stop 47) the ArduCopter
    scan alone met 10 m (radii 5.9, 7.4, 10.0 m; no look, the test failed), so it asks for 7 m:
    in the simulator 30 of 30 located with looks, all inside, 169 s to complete (the same
    command, ``--runs 10``, ``required_accuracy_m = 7``; at 6 m one world's looks did not end
    in 13 min)."""
    v = dr.start_px4(sitl) if kind == "px4" else dr.start_arducopter(sitl)
    sc = dr.load(dr.scenario_text(f"{kind}-looks", kind, [v], scan=SPARSE_SCAN, required_m=LOOKS_REQUIRED_M,
                                  world="paper"), tmp_path / "mission.toml")
    with dr.Companions(sc, [v]):
        run = dr.run_daemon(tmp_path / "mission.toml", tmp_path / "out")
    print(f"{kind} with looks: {run.wall_s:.0f} s wall")
    _check(run, sc, [v])
    assert re.search(r"replans [1-9]", run.output), "the look phase ran"


@pytest.mark.parametrize("kind", ["px4"])
def test_a_previously_flown_vehicle_searches_again(sitl, tmp_path, kind):
    """PX4 keeps reporting the last mission "complete" after a flight; taken at face value it ended
    the next search right after its scan started (exit 1, no RTL). Two searches in a row on the
    same vehicle: the second must run to its end like the first. The paper's world: this is about
    the autopilot's state between searches, and two field searches would fly 4,000-6,000 s of
    mission today (docs/guide/sitl.md); ArduCopter never showed the stale state, so only PX4."""
    v = dr.start_px4(sitl) if kind == "px4" else dr.start_arducopter(sitl)
    for k in range(2):
        sc = dr.load(dr.scenario_text(f"{kind}-again{k}", kind, [v], seed=3 + k, world="paper"),
                     tmp_path / f"m{k}.toml")
        with dr.Companions(sc, [v]):
            run = dr.run_daemon(tmp_path / f"m{k}.toml", tmp_path / f"out{k}")
        print(f"{kind} search {k + 1}: {run.wall_s:.0f} s wall")
        _check(run, sc, [v])


@pytest.mark.parametrize("kind", ["ardupilot", "px4"])
def test_a_freshly_booted_vehicle_searches(sitl, tmp_path, kind):
    """The daemon started as soon as the autopilot sends its first heartbeat (not when it is ready
    to fly): ArduCopter refuses to arm for a while and PX4 reports health failures, so the start
    must wait, arm when ready and take off; the search then runs to its end like any other. (The
    suite's usual people, seed 3. With seed 5 a person 12 m from the launch point stayed mirror-
    ambiguous: every look flew a line through home, see the closing note of issue 12. PX4 was a
    non-strict xfail for that until 2026-11-24; 16 runs in a row have passed since.)"""
    wait = "heartbeat" if kind == "ardupilot" else "none"
    v = dr.start_px4(sitl, wait=wait) if kind == "px4" else dr.start_arducopter(sitl, wait=wait)
    # The paper's world: this is about the start, and today's search in the field world flies look
    # after look (a freshly booted ArduCopter there: still looking at 1,300 s of mission; PX4 did not
    # end within 900 s of wall time; docs/guide/sitl.md)
    sc = dr.load(dr.scenario_text(f"{kind}-fresh", kind, [v], world="paper"), tmp_path / "mission.toml")
    with dr.Companions(sc, [v]):
        run = dr.run_daemon(tmp_path / "mission.toml", tmp_path / "out")
    print(f"{kind} freshly booted: {run.wall_s:.0f} s wall")
    _check(run, sc, [v])
