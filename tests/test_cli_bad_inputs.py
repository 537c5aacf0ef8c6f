"""Issue 29 item 3: every bad input a newcomer tried is answered in one sentence naming the flag or
key, exit 2 (3 only for the link), nothing left behind and nothing uploaded that the target
autopilot would not take."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from mission_io import plan as plan_file
from sim_link.vehicles.fleet import FakeFleet
from uavloc_gcs.mission import flight_mission
from uavloc_gcs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"


def uavloc(*args, cwd=ROOT, timeout=120):
    return subprocess.run([sys.executable, "-m", "uavloc_gcs", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, cwd=cwd)


def one_sentence(r, *needles, code=2):
    """The run ended with ``code`` and one stderr line (argparse's usage aside) holding ``needles``."""
    assert r.returncode == code, (r.returncode, r.stdout[-2000:], r.stderr[-2000:])
    assert "Traceback" not in r.stderr, r.stderr
    lines = [ln for ln in r.stderr.strip().splitlines() if ln.startswith("uavloc ")]
    assert len(lines) == 1, r.stderr
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


# ---------------------------------------------------------------------------------------------
# upload: nothing reaches the vehicle that it would not take

@pytest.fixture
def ardupilot_vehicle():
    sc = load_scenario(EXAMPLES / "small.toml").replace(fleet={"autopilot": "ardupilot", "vehicles": 1})
    f = FakeFleet(sc, speedup=1, seed=1, base_port=0).start_in_thread()
    yield f
    f.stop()


def _plan(tmp_path, command=None):
    pts = [(47.3977 + 0.0002 * i, 8.5456) for i in range(4)]
    plan = flight_mission(pts, alt_m=40.0, speed_m_s=8.0, autopilot="ardupilot",
                          home_latlon_deg=(47.3977, 8.5456), home_alt_amsl_m=488.0)
    path = tmp_path / "m.plan"
    plan_file.write(path, plan)
    if command is not None:
        d = json.loads(path.read_text())
        d["mission"]["items"][2]["command"] = command
        path.write_text(json.dumps(d))
    return path


@pytest.mark.parametrize("command, needle", [(99999, "does not fit MAVLink's command field"),
                                             (12345, "is not a MAVLink command")])
def test_a_command_no_autopilot_knows_is_refused_before_connecting(ardupilot_vehicle, tmp_path, command, needle):
    (_, conn), = ardupilot_vehicle.endpoints
    r = uavloc("upload", _plan(tmp_path, command), "--to", conn)
    one_sentence(r, "item 3", "command", needle)
    assert ardupilot_vehicle.vehicle(1).mission_items == []  # nothing sent


def test_autopilot_flag_that_contradicts_the_heartbeat_uploads_nothing(ardupilot_vehicle, tmp_path):
    (_, conn), = ardupilot_vehicle.endpoints
    r = uavloc("upload", _plan(tmp_path), "--to", conn, "--autopilot", "px4")
    one_sentence(r, "--autopilot px4", "ArduPilot")
    assert ardupilot_vehicle.vehicle(1).mission_items == []
    r = uavloc("download", "--from", conn, "--autopilot", "px4", "--out", tmp_path / "back.plan")
    one_sentence(r, "--autopilot px4")
    assert not (tmp_path / "back.plan").exists()


@pytest.mark.parametrize("args, flag", [(["--timeout", "-1"], "--timeout"), (["--timeout", "nan"], "--timeout"),
                                        (["--system", "300"], "--system"), (["--system", "0"], "--system")])
def test_link_flags_out_of_range_are_bad_input_not_link_failures(tmp_path, args, flag):
    r = uavloc("upload", _plan(tmp_path), "--to", "udpout:127.0.0.1:9", *args)
    one_sentence(r, f"argument {flag}")


# ---------------------------------------------------------------------------------------------
# route

def test_route_refuses_binary_files_and_picture_suffixes_before_writing(tmp_path):
    (tmp_path / "garbage.plan").write_bytes(bytes(range(256)) * 2)
    one_sentence(uavloc("route", "garbage.plan", cwd=tmp_path), "garbage.plan", "JSON")
    r = uavloc("route", "route_paper.json", "--png", "r.jpg", "--out", "r.json", cwd=tmp_path)
    one_sentence(r, "--png r.jpg", ".png or .svg")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["garbage.plan"]


@pytest.mark.slow
def test_ctrl_c_during_an_ortools_route_is_not_success_and_writes_nothing(tmp_path):
    pytest.importorskip("ortools")
    import signal
    import time

    p = subprocess.Popen([sys.executable, "-m", "uavloc_gcs", "route", "route_paper", "--solver", "ortools",
                          "--time-limit", "60", "--out", "o.json"], cwd=tmp_path, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    time.sleep(4)  # whether the solver has started or Python is still importing, Ctrl-C must not be success
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 130, err
    assert "Traceback" not in err
    assert "interrupted" in err or "stopped by Ctrl-C" in err
    assert not (tmp_path / "o.json").exists()


# ---------------------------------------------------------------------------------------------
# plan, bench: flags are blamed on the flag

def _inproc(capsys, *args):
    from uavloc_gcs.cli import main

    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return subprocess.CompletedProcess(args, code, out.out, out.err)


@pytest.mark.parametrize("value, needle", [("0.5", "too narrow"), ("1", "too narrow"), ("-5", "more than 0"),
                                           ("nan", "finite")])
def test_plan_lane_spacing_is_refused_quickly_naming_the_flag(tmp_path, capsys, value, needle):
    r = _inproc(capsys, "plan", "paper", "--lane-spacing", value, "--out", tmp_path / "o")
    line = one_sentence(r, "--lane-spacing", needle)
    assert "paper.toml" not in line  # the operator typed it: the scenario file is not to blame
    assert list(tmp_path.iterdir()) == []


def test_a_scenario_without_fleet_says_the_default_fleet_is_assumed(tmp_path, capsys):
    (tmp_path / "s.toml").write_text("[area]\norigin_lat_deg = 47.0\norigin_lon_deg = 8.0\nwidth_m = 400\n"
                                     "height_m = 300\n")
    r = _inproc(capsys, "plan", tmp_path / "s.toml", "--out", tmp_path / "o")
    assert r.returncode == 0
    assert "has no [fleet] section, so the default fleet is assumed: 4 ArduPilot vehicles at 100 m and 25 m/s" \
        in r.stdout


@pytest.mark.parametrize("args", [["localize", "--runs", "-1"], ["localize", "--runs", "0"],
                                  ["looks", "--people", "0"], ["plan", "--time-limit", "nan"]])
def test_bench_counts_out_of_range_are_one_sentence(capsys, args):
    r = _inproc(capsys, "bench", *args)
    one_sentence(r, f"argument {args[1]}")


# ---------------------------------------------------------------------------------------------
# demo, daemon, localize: flags named, nothing left behind

@pytest.mark.parametrize("args, flag", [(["--people", "-1"], "--people"), (["--people", "100000"], "--people"),
                                        (["--speedup", "0"], "--speedup"), (["--seed", "-1"], "--seed"),
                                        (["--loss", "2"], "--loss"), (["--base-port", "70000"], "--base-port")])
def test_demo_flags_are_blamed_on_the_flag(tmp_path, capsys, args, flag):
    r = _inproc(capsys, "demo", "--scenario", "paper", "--no-web", "--out", tmp_path / "d", *args)
    line = one_sentence(r, f"argument {flag}")
    assert "paper.toml" not in line
    assert list(tmp_path.iterdir()) == []


def test_demo_into_a_directory_that_cannot_be_made_is_one_sentence(capsys):
    r = _inproc(capsys, "demo", "--scenario", "small", "--no-web", "--out", "/proc/uavloc-x")
    one_sentence(r, "/proc/uavloc-x")


def test_a_daemon_that_never_reached_its_vehicle_leaves_nothing_behind(tmp_path):
    cfg = (EXAMPLES / "sitl_arducopter.toml").read_text().replace(
        'connections = ["udpin:127.0.0.1:14550"]', 'connections = ["udpout:127.0.0.1:9"]')
    (tmp_path / "m.toml").write_text(cfg)
    r = uavloc("daemon", "--config", tmp_path / "m.toml", "--no-web", "--connect-timeout", "2",
               "--out", tmp_path / "out", timeout=300)
    one_sentence(r, "no heartbeat", code=3)
    assert not (tmp_path / "out").exists()  # no .uavloc.lock, search.sqlite or empty .tlog


def test_the_daemon_refuses_a_scenario_without_fleet(tmp_path):
    text = (EXAMPLES / "sitl_arducopter.toml").read_text()
    start = text.index("[fleet]")
    end = text.index("[", start + 1)
    text = text[:start] + text[end:]  # four default vehicles: four connections, so only [fleet] is missing
    text = text.replace('connections = ["udpin:127.0.0.1:14550"]',
                        "connections = [" + ", ".join(f'"udpout:127.0.0.1:{9 + i}"' for i in range(4)) + "]")
    (tmp_path / "m.toml").write_text(text)
    r = uavloc("daemon", "--config", tmp_path / "m.toml", "--no-web", "--out", tmp_path / "out")
    one_sentence(r, "key 'fleet'", "default fleet")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.toml"]


@pytest.mark.parametrize("value, needle", [("nan", "argument --t-ref: must be a finite number"),
                                           ("1e12", "--t-ref 1e+12: must be within an hour")])
def test_localize_t_ref_far_from_the_slots_is_refused(tmp_path, capsys, value, needle):
    r = _inproc(capsys, "localize", EXAMPLES / "slots_small.csv", "--scenario", "small", "--t-ref", value,
                "--out", tmp_path / "o")
    one_sentence(r, needle)
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------------------------------------
# item 5: what the pictures say

def test_result_map_labels_give_the_located_their_lat_lon_and_radius():
    from types import SimpleNamespace as P

    import matplotlib

    matplotlib.use("Agg")
    import numpy as np

    from uavloc_gcs.render.estimates import result_figure

    area = np.array([[0, 0], [1120, 0], [1120, 640], [0, 640]], float)
    people = [P(emitter_id=1, label="P01", state="located", east_m=300, north_m=200, radius95_m=6,
                lat_deg=42.625311, lon_deg=13.283122),
              P(emitter_id=2, label="P02", state="given up", east_m=600, north_m=500, radius95_m=120,
                lat_deg=42.628, lon_deg=13.29)]
    fig = result_figure(people, area_xy_m=area, tracks_xy_m={}, truth_xy_m={1: np.array([300.0, 200.0])})
    texts = [t.get_text() for t in fig.axes[0].texts]
    assert "P01 (6 m)\n42.625311, 13.283122" in texts and "P02" in texts
    ax = fig.axes[0]
    truth = [c for c in ax.collections if c.get_label() == "true position (simulation)"]
    located = [c for c in ax.collections if c.get_label().startswith("located")]
    assert truth[0].get_zorder() > located[0].get_zorder()  # the cross is not hidden under the truth
    rings = [c for c in ax.collections if c.get_zorder() == 5.5]
    assert len(rings) == 1  # the 6 m circle, invisible at 1 km, has its ring


def test_localize_picture_labels_are_short_and_match_the_table(tmp_path, capsys):
    r = _inproc(capsys, "localize", EXAMPLES / "slots_small.csv", "--scenario", "small", "--out", tmp_path / "o")
    assert r.returncode == 0
    rows = [ln.split() for ln in r.stdout.splitlines() if ln[:1] == "E"]
    assert [row[0] for row in rows] == ["E1", "E2", "E3"]


def test_bench_looks_runs_the_shipped_rules_by_default_and_all_on_request():
    import argparse

    from benchmarks.looks import VARIANTS, add_arguments

    p = argparse.ArgumentParser()
    add_arguments(p)
    assert p.parse_args([]).variants == "default"  # was all 23 variants: 331 s for one run
    assert "all" in p.format_help() and len(VARIANTS) > 2


def test_experiment_figures_with_one_people_count_and_no_figure_c(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    from sim_link.experiments.plots import plot_all

    rows = [{"method": m, "people": 5, "completion_time_mean_s": v, "completion_time_ci95_s": float("nan"),
             "runtime_mean_s": rt, "runtime_ci95_s": float("nan"), "oracle_completion_time_mean_s": 160.0}
            for m, v, rt in [("MLE-EPSO (M)", 173.0, 2.8), ("MLE-EPSO (NM)", 162.0, 0.0), ("RL-NM", 195.0, 20.0)]]
    import matplotlib.pyplot as plt

    made = []
    real_savefig = plt.Figure.savefig

    def keep(fig, path, *a, **k):
        made.append(fig)
        return real_savefig(fig, path, *a, **k)

    plt.Figure.savefig = keep
    try:
        paths = plot_all(rows, rows, [], tmp_path, 15.0)
    finally:
        plt.Figure.savefig = real_savefig
    assert [p.name for p in paths] == ["fig_a_completion_time.png", "fig_b_runtime.png"]
    ax_a, ax_b = made[0].axes[0], made[1].axes[0]
    assert list(ax_a.get_xticks()) == [5]  # not 4.8 ... 5.2
    assert ax_a.get_ylim()[1] > 195.0 * 1.05  # RL-NM's marker is not on the frame
    assert "MLE-EPSO (NM)" not in [t.get_text() for t in ax_b.get_legend().get_texts()]  # 0 s: no point on a log axis
    made[1].canvas.draw()
    labels = [t.get_text() for t in ax_b.get_yticklabels() + ax_b.get_yticklabels(minor=True) if t.get_text()]
    assert labels and not any("10^" in s or "times" in s for s in labels), labels


# ---------------------------------------------------------------------------------------------
# issue 40 item 4: bench flags that were tracebacks or ran nothing

@pytest.mark.parametrize("args, needle", [
    (["plan", "--families", "nope"], "argument --families: unknown 'nope'; choose from paper, clustered"),
    (["plan", "--families", "paper,mtsp,nope"], "unknown 'nope'"),
    (["plan", "--paper-sizes", "10,0"], "argument --paper-sizes: entry '0': must be at least 1"),
    (["sense", "--frames", "0"], "argument --frames: must be at least 1"),
    (["sense", "--frames", "-1"], "argument --frames: must be at least 1"),
    (["sense", "--repeats", "0"], "argument --repeats: must be at least 1"),
    (["identity", "--people", "-1"], "argument --people: entry '-1': must be at least 1"),
    (["identity", "--people", "10,x"], "argument --people: entry 'x': 'x' is not a whole number"),
    (["identity", "--models", "0"], "argument --models: entry '0'"),
    (["link", "--loss", "1"], "argument --loss: entry '1': must be at most 0.9"),
    (["demos", "--scenario", "paper,nope"], "argument --scenario: 'nope' is neither a file nor a shipped scenario"),
    (["localize", "--family", "nope"], "--family nope: no family's name contains it; the families are 'one leg"),
    (["localize", "--family", "nope", "--emission", "bursts"], "no family's name contains it"),
])
def test_bench_lists_and_counts_are_one_sentence(capsys, args, needle):
    r = _inproc(capsys, "bench", *args)
    one_sentence(r, needle)
    assert r.stdout == ""  # refused before the benchmark printed (or ran) anything


def test_bench_demos_keep_where_nothing_can_be_written(capsys):
    r = _inproc(capsys, "bench", "demos", "--runs", "1", "--keep", "/proc/uavloc-test")
    one_sentence(r, "--keep /proc/uavloc-test: cannot write in /proc")


@pytest.mark.parametrize("line, key", [("comm_range_m = 1e9", "fleet.comm_range_m"),
                                       ("energy_budget_j = 1e308", "fleet.energy_budget_j")])
def test_absurd_scenario_values_are_refused_before_planning(tmp_path, capsys, line, key):
    """Issue 40: both passed, and plan printed a 300-digit kJ figure."""
    (tmp_path / "s.toml").write_text("[area]\norigin_lat_deg = 47.0\norigin_lon_deg = 8.0\nwidth_m = 400\n"
                                     f"height_m = 300\n[fleet]\n{line}\n")
    r = _inproc(capsys, "plan", tmp_path / "s.toml", "--out", tmp_path / "o")
    one_sentence(r, f"s.toml, key '{key}'", "is not plausible (give at most")
    assert r.stdout == "" and sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


# ---------------------------------------------------------------------------------------------
# issue 40: a mission longer than the autopilot holds is refused before it is sent (a 10,001-item
# upload was refused by the vehicle, exit 3); figures in uavloc_gcs/link/mission_capacity.py

def _long_plan(tmp_path, kind, wire_items, suffix=".plan"):
    from mission_io import waypoints as wpl_file
    from uavloc_gcs.mission import to_wire

    lat, lon = 47.3977, 8.5456
    extra = len(to_wire(flight_mission([(lat, lon)], alt_m=40.0, speed_m_s=8.0, autopilot=kind,
                                       home_latlon_deg=(lat, lon), home_alt_amsl_m=488.0), kind)) - 1
    pts = [(lat + 1e-5 * (k % 100), lon + 1e-5 * (k // 100)) for k in range(wire_items - extra)]
    plan = flight_mission(pts, alt_m=40.0, speed_m_s=8.0, autopilot=kind, home_latlon_deg=(lat, lon),
                          home_alt_amsl_m=488.0)
    assert len(to_wire(plan, kind)) == wire_items
    path = tmp_path / f"long{suffix}"
    (plan_file if suffix == ".plan" else wpl_file).write(path, plan)
    return path


def test_a_mission_the_vehicle_has_no_room_for_is_bad_input_in_its_words(ardupilot_vehicle, tmp_path):
    """The fake ArduPilot holds 650 items, as the ArduCopter SITL, and says so as it does."""
    (_, conn), = ardupilot_vehicle.endpoints
    r = uavloc("upload", _long_plan(tmp_path, "ardupilot", 651), "--to", conn)
    one_sentence(r, "long.plan: vehicle 1 (ArduPilot)", "has no room for 651 mission items",
                 "(it says \"Only 650 items are supported\") and keeps the mission it had", "split the mission")
    assert ardupilot_vehicle.vehicle(1).mission_items == []


@pytest.mark.parametrize("kind, items, suffix, needle", [
    ("px4", 10_001, ".plan", "10,001 mission items (on the wire) are more than any PX4 vehicle holds (10,000"),
    ("ardupilot", 4_369, ".plan", "4,369 mission items (on the wire) are more than any ArduPilot vehicle holds (4,368"),
    ("px4", 65_536, ".waypoints", "more than MAVLink's mission protocol can number (65,535)"),
])
def test_a_mission_no_vehicle_holds_is_refused_before_connecting(tmp_path, kind, items, suffix, needle):
    args = ["--autopilot", kind] if suffix == ".plan" else []
    r = uavloc("upload", _long_plan(tmp_path, kind, items, suffix), "--to", "udpout:127.0.0.1:9", *args)
    one_sentence(r, needle)  # exit 2 at once: a connection attempt would end in 3 (no heartbeat)


def test_mission_capacity_edges():
    from uavloc_gcs.link.mission_capacity import too_long

    assert too_long(4368, "ardupilot") is None and too_long(4369, "ardupilot")
    assert too_long(10_000, "px4") is None and too_long(10_001, "px4")
    assert too_long(65_535, "generic") is None and too_long(65_536, "generic")


def test_no_help_text_shows_a_doubled_percent_sign(capsys):
    """`experiment paper --help` printed "95 %%" (a description is not %-formatted, a flag's help is)."""
    from uavloc_gcs.cli import COMMANDS
    from uavloc_gcs.cli.bench import BENCHMARKS

    pages = [[c, "--help"] for c in COMMANDS] + [["experiment", "paper", "--help"]]
    pages += [["bench", b, "--help"] for b in BENCHMARKS]
    for args in pages:
        r = _inproc(capsys, *args)
        assert r.returncode == 0, (args, r.stderr)
        assert "%%" not in r.stdout and r.stdout.strip(), args
    assert "with 95 % confidence intervals" in _inproc(capsys, "experiment", "paper", "--help").stdout


# ---------------------------------------------------------------------------------------------
# issue 40: items the autopilot refuses mid-upload (ArduPilot is then left with half a mission)
# are refused before the upload starts; link/mission_checks.py

def _plan_with(tmp_path, index, **changes):
    path = _plan(tmp_path)
    d = json.loads(path.read_text())
    item = d["mission"]["items"][index]
    for key, value in changes.items():
        if key == "alt":
            item["params"][6] = value
            item["Altitude"] = value
        else:
            item[key] = value
    bad = tmp_path / "bad.plan"
    bad.write_text(json.dumps(d))
    return bad


def test_an_item_ardupilot_refuses_leaves_its_mission_as_it_was(ardupilot_vehicle, tmp_path):
    (_, conn), = ardupilot_vehicle.endpoints
    r = uavloc("upload", _plan(tmp_path), "--to", conn)
    assert r.returncode == 0, r.stderr
    held = list(ardupilot_vehicle.vehicle(1).mission_items)
    d = json.loads((tmp_path / "m.plan").read_text())
    k = next(i for i, it in enumerate(d["mission"]["items"]) if it["command"] == 16)
    r = uavloc("upload", _plan_with(tmp_path, k, alt=1e30), "--to", conn)
    one_sentence(r, f"bad.plan, item {k + 1}, field 'altitude'", "beyond ArduPilot's altitudes")
    assert ardupilot_vehicle.vehicle(1).mission_items == held  # was: truncated to the items before it


@pytest.mark.parametrize("autopilot, changes, needle", [
    ("auto", {"frame": 99}, "field 'frame': frame 99 is not a MAVLink frame (MAV_FRAME)"),
    ("px4", {"frame": 10}, "field 'frame': PX4 takes location items only in frames GLOBAL and GLOBAL_RELATIVE_ALT"),
    ("ardupilot", {"alt": 90000.0}, "field 'altitude': 90000 m is beyond ArduPilot's altitudes"),
])
def test_items_no_vehicle_of_the_autopilot_takes_are_refused_before_connecting(tmp_path, autopilot, changes, needle):
    path = _plan(tmp_path)
    k = next(i for i, it in enumerate(json.loads(path.read_text())["mission"]["items"]) if it["command"] == 16)
    r = uavloc("upload", _plan_with(tmp_path, k, **changes), "--to", "udpout:127.0.0.1:9", "--autopilot", autopilot)
    one_sentence(r, f"item {k + 1}", needle)  # exit 2 at once: connecting would end in 3 (no heartbeat)


def test_an_upload_of_no_items_is_refused_it_would_clear_the_mission(tmp_path):
    r = uavloc("upload", ROOT / "tests" / "data" / "files" / "empty.plan", "--to", "udpout:127.0.0.1:9")
    one_sentence(r, "empty.plan: holds no mission items: nothing to upload")


# ---------------------------------------------------------------------------------------------
# issue 40: more bad inputs found across the commands

def _route_instance(tmp_path, change):
    d = json.loads((EXAMPLES / "route_paper.json").read_text())
    change(d)
    path = tmp_path / "inst.json"
    path.write_text(json.dumps(d))
    return path


@pytest.mark.parametrize("change, needle", [
    (lambda d: d.update(speed_m_s=1e308), "field 'speed_m_s': 1e+308 m/s is beyond any multirotor (at most 60"),
    (lambda d: d["targets"][0].update(xy_m=[1e300, 0]), "field 'targets[0].xy_m': 1e+300, 0 m is more than 1000 km"),
    (lambda d: d["targets"][0].update(radius_m=1e300), "field 'targets[0].radius_m': radius must be 0 to 1e+06 m"),
])
def test_absurd_route_instances_are_one_sentence(tmp_path, capsys, change, needle):
    """Were an overflow warning and "needs nan J", a 300-digit coordinate, an overflow warning."""
    r = _inproc(capsys, "route", _route_instance(tmp_path, change), "--out", tmp_path / "p.json")
    one_sentence(r, needle)
    assert not (tmp_path / "p.json").exists() and "Warning" not in r.stderr


@pytest.mark.parametrize("args", [["plan", "small"], ["localize", EXAMPLES / "slots_small.csv", "--scenario", "small"],
                                  ["experiment", "paper", "--runs", "1"]])
def test_an_empty_out_is_not_the_current_directory(tmp_path, capsys, monkeypatch, args):
    """``--out "$UNSET"`` wrote the plan into the current directory."""
    monkeypatch.chdir(tmp_path)
    r = _inproc(capsys, *args, "--out", "")
    one_sentence(r, "--out needs a directory name, got an empty one (for the current directory give .)")
    assert list(tmp_path.iterdir()) == []


def test_preview_png_empty_is_refused_not_ignored(capsys):
    r = _inproc(capsys, "preview", ROOT / "tests" / "data" / "small" / "uav1.plan", "--png", "")
    one_sentence(r, "--png needs a file name, got an empty one")


def test_download_tlog_and_out_the_same_file(tmp_path, capsys):
    r = _inproc(capsys, "download", "--from", "udpout:127.0.0.1:9", "--out", tmp_path / "x.plan",
                "--tlog", tmp_path / "x.plan")
    one_sentence(r, "--tlog", "is also the --out file")


def test_experiment_methods_naming_no_method(tmp_path, capsys):
    """Ran nothing and wrote empty figures, exit 0."""
    r = _inproc(capsys, "experiment", "paper", "--methods", ",", "--out", tmp_path / "e")
    one_sentence(r, "--methods ',' names no method; choose from MLE-EPSO (M)")
    assert not (tmp_path / "e").exists()


def test_a_slot_csv_saved_by_a_spreadsheet_reads(tmp_path, capsys):
    """'CSV UTF-8' from a spreadsheet starts with a byte-order mark: the header was said to be wrong."""
    (tmp_path / "bom.csv").write_bytes(b"\xef\xbb\xbf" + (EXAMPLES / "slots_small.csv").read_bytes())
    r = _inproc(capsys, "localize", tmp_path / "bom.csv", "--scenario", "small", "--out", tmp_path / "o")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "o" / "estimates.csv").is_file()


@pytest.mark.parametrize("args, needle", [
    (["--slot-ms", "nan"], "argument --slot-ms: must be a finite number"),
    (["--clock-offset-s", "inf"], "argument --clock-offset-s: must be a finite number"),
    (["--learn-min-frames", "-1", "--learn-team", "t.txt"], "argument --learn-min-frames: must be at least 1"),
    (["--sysid", "999", "--mavlink", "udpout:127.0.0.1:9"], "argument --sysid: must be at most 255"),
    (["--slot-ms", "100", "--mavlink", "udpout:127.0.0.1:9"], "16-bit count of microseconds, at most 65.535 ms"),
])
def test_sense_numbers_are_checked_before_reading(tmp_path, capsys, monkeypatch, args, needle):
    monkeypatch.chdir(tmp_path)
    pcap = ROOT / "tests" / "uavloc_gcs" / "sense" / "real" / "ieee802.11_exthdr.pcap"
    r = _inproc(capsys, "sense", pcap, *args, *([] if "--mavlink" in args or "--learn-team" in args else
                                                  ["--out", "o"]))
    one_sentence(r, needle)
    assert list(tmp_path.iterdir()) == []


def test_sitl_seed_is_checked_before_any_vehicle_starts(capsys):
    r = _inproc(capsys, "sitl", "small", "--seed", "-1")
    one_sentence(r, "argument --seed: must be at least 0")


def test_plan_notes_a_scan_common_boards_cannot_hold(tmp_path, capsys):
    """One ArduPilot vehicle, 12 m lanes over 4 x 3.95 km: 702 items, more than a 16 KB board (and
    the SITL) holds; the plan is written, with the note."""
    (tmp_path / "s.toml").write_text("[area]\norigin_lat_deg = 47.0\norigin_lon_deg = 8.0\nwidth_m = 4000\n"
                                     "height_m = 3950\n[fleet]\nvehicles = 1\nenergy_budget_j = 20000000\n"
                                     "[scan]\nlane_spacing_m = 12\n")
    r = _inproc(capsys, "plan", tmp_path / "s.toml", "--out", tmp_path / "o")
    assert r.returncode == 0, r.stderr
    assert ("Note: uav1's scan has 702 mission items: ArduPilot boards with 16 KB of storage (and SITL) refuse more "
            "than 650") in r.stdout
    assert (tmp_path / "o" / "uav1.plan").is_file()


def test_daemon_tlog_path_that_cannot_be_written_is_refused_before_connecting(tmp_path, capsys):
    """Was a FileNotFoundError traceback once the daemon opened its first vehicle's log."""
    cfg = (EXAMPLES / "sitl_arducopter.toml").read_text().replace(
        'connections = ["udpin:127.0.0.1:14550"]', 'connections = ["udpout:127.0.0.1:9"]\ntlog_path = "/proc/uavloc-x"')
    (tmp_path / "m.toml").write_text(cfg)
    r = _inproc(capsys, "daemon", "--config", tmp_path / "m.toml", "--no-web", "--out", tmp_path / "out")
    one_sentence(r, "m.toml, key 'link.tlog_path': /proc/uavloc-x: cannot write in /proc")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.toml"]
