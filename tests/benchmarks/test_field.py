"""`uavloc bench field`: what each plan flies and how the table reads (the missions themselves run
in the benchmark, not here: minutes per world)."""

import math

import pytest

from benchmarks import field
from uavloc_gcs.examples import scenario_path
from uavloc_gcs.scenario import load_scenario


def test_each_plan_flies_its_own_scenario():
    sc = load_scenario(scenario_path("field"))
    assert field.scenario_for("paper", sc, 0.95).search.pod_target is None
    assert field.scenario_for("uavloc", sc, 0.95).search.pod_target == 0.95
    assert field.scenario_for("lawnmower", sc, 0.9).search.pod_target == 0.9


def _row(plan, seed, located, time_s, oracle=math.nan):
    return {"plan": plan, "seed": seed, "present": 10, "heard": 8, "located": located, "inside": located,
            "time_s": time_s, "oracle_s": oracle, "energy_kj": 100.0, "pod": 0.8, "why": []}


def test_the_table_reads_located_of_present_and_time_against_the_clairvoyant():
    rows = [_row("uavloc", 0, 5, 1200.0, 600.0), _row("uavloc", 1, 3, 1000.0, 400.0),
            _row("paper", 0, 0, 160.0), _row("paper", 1, 1, 180.0),
            _row("lawnmower", 0, 2, 1500.0), _row("lawnmower", 1, 2, 1700.0)]
    lines = field.table(rows, runs=2)
    by = {ln.split()[0]: ln for ln in lines[2:]}
    assert set(by) == {"uavloc", "paper", "lawnmower", "clairvoyant"}
    assert "8/20" in by["uavloc"] and "40%" in by["uavloc"]  # 8 located of 20 present
    assert "18:20" in by["uavloc"] and " 2.20 " in by["uavloc"]  # 1100 s mean / 500 s clairvoyant
    assert "8:20" in by["clairvoyant"]
    assert field._kind("given up: not located after 2 orbit looks of 236 s (heard on the last one)") == \
        "given up: not located after N orbit looks of N s"


def test_an_access_point_and_trapped_people_are_options_of_the_worlds():
    import argparse

    p = argparse.ArgumentParser()
    field.add_arguments(p)
    assert field.overrides(p.parse_args([])) == {}
    ch = field.overrides(p.parse_args(["--elicitation", "2", "--trapped"]))
    sc = load_scenario(scenario_path("field")).replace(**ch)
    assert sc.emission.elicitation_rate_hz == 2.0 and sc.people.max_speed_m_s == 0.0
    assert sc.simulation.motion == "static"
    em = load_scenario(scenario_path("field")).replace(
        **field.overrides(p.parse_args(["--elicitation", "2", "--mimicry", "0.5", "--join", "in-reach"]))).emission
    assert (em.elicitation_rate_hz, em.mimicry_share, em.elicitation_join) == (2.0, 0.5, "in-reach")


def test_the_time_limit_and_the_look_height_are_options_of_the_search():
    import argparse

    p = argparse.ArgumentParser()
    field.add_arguments(p)
    sc = load_scenario(scenario_path("field")).replace(
        **field.overrides(p.parse_args(["--time-limit", "45", "--look-height", "30"])))
    assert sc.search.time_limit_s == 2700.0 and sc.search.look_height_m == 30.0
    assert sc.search.pod_target == load_scenario(scenario_path("field")).search.pod_target  # the rest kept
    with pytest.raises(SystemExit):
        p.parse_args(["--time-limit", "0"])


def test_the_circles_of_people_heard_and_not_located_are_counted_against_the_truth():
    rows = [dict(_row("uavloc", 0, 0, 100.0), label="uavloc",
                 judged=[(False, 80.0, True), (False, 90.0, False), (False, 60.0, True), (True, 12.0, False)]),
            dict(_row("uavloc", 1, 0, 100.0), label="uavloc", judged=[(False, 70.0, True)]),
            dict(_row("paper", 0, 0, 100.0), label="paper", judged=[(True, 10.0, True)])]
    assert field.circle_lines(rows) == [
        "heard, not located, uavloc: 3 of 4 inside the 95 % circle reported (issue 41's goal: 95 %)"]


def test_the_people_narrowed_to_a_circle_a_team_can_search_are_counted_when_it_holds_them():
    rows = [dict(_row("uavloc", 0, 1, 100.0), label="uavloc", judged=[(True, 12.0, True), (False, 40.0, True),
                                                                       (False, 40.0, False), (False, 90.0, True),
                                                                       (False, 300.0, True)])]
    (line,) = field.narrowed_lines(rows)
    assert line.endswith("1 of 10 within 15 m / 1 of 10 within 30 m / 2 of 10 within 50 m / 3 of 10 within 100 m")


def test_every_circle_reported_is_counted_duplicates_included():
    rows = [dict(_row("uavloc", 0, 0, 100.0), label="uavloc", claims=[(False, 80.0, True), (False, 90.0, False),
                                                                       (True, 14.0, True)]),
            dict(_row("uavloc", 1, 0, 100.0), label="uavloc", claims=[(False, 60.0, True)])]
    assert field.claims_lines(rows) == [
        "every circle reported, uavloc: 4 people reported for 16 phones heard; circles that hold the phone behind "
        "them: 3 of 4"]


def test_packs_and_plans_options_are_checked_in_one_sentence():
    import argparse

    p = argparse.ArgumentParser()
    field.add_arguments(p)
    a = p.parse_args(["--packs", "1,3", "--plans", "uavloc"])
    assert a.packs == (1, 3) and a.plans == ("uavloc",)
    assert field.label("uavloc", 3) == "uavloc 3 packs" and field.label("paper", 1) == "paper"
    for bad in (["--packs", "0"], ["--packs", "x"], ["--plans", "nope"]):
        with pytest.raises(SystemExit):
            p.parse_args(bad)


def test_the_foreign_bursts_of_located_people_are_reported_against_the_goal():
    rows = [dict(_row("uavloc", 0, 2, 100.0), label="uavloc", foreign=[0.0, 0.25]),
            dict(_row("uavloc", 1, 1, 100.0), label="uavloc", foreign=[0.01]),
            dict(_row("paper", 0, 0, 100.0), label="paper", foreign=[])]
    lines = field.foreign_lines(rows)
    assert len(lines) == 1  # the paper located nobody: no line
    assert "uavloc: 8.7 % on average, 1 of 3 above 2 % (worst 25 %" in lines[0]
