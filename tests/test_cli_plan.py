"""`uavloc plan` and `uavloc preview` as a user runs them (subprocess), golden files, bad input."""

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from mission_io import plan as plan_file
from mission_io import waypoints as wpl_file
from uavloc_gcs.cli import main

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
GOLDEN = ROOT / "tests" / "data" / "small"
GOLDEN_FILES = ["uav1.plan", "uav1.waypoints", "uav2.plan", "uav2.waypoints", "scan.geojson", "scan.kml"]


def uavloc(*args, cwd=None):
    """Run the real command in a fresh interpreter, as a user would."""
    return subprocess.run([sys.executable, "-m", "uavloc_gcs", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd or ROOT, timeout=120)


@pytest.fixture
def uavloc_inproc(capsys):
    """The same entry point in this process (no interpreter start-up): for the many bad-input cases."""
    def run(*args):
        code = main([str(a) for a in args])
        out = capsys.readouterr()
        return subprocess.CompletedProcess(args, code, out.out, out.err)
    return run


@pytest.fixture(scope="module")
def small_out(tmp_path_factory):
    out = tmp_path_factory.mktemp("plan") / "small"
    res = uavloc("plan", EXAMPLES / "small.toml", "--out", out)
    assert res.returncode == 0, res.stderr
    return out, res


def test_plan_writes_every_file_and_prints_the_table(small_out):
    out, res = small_out
    assert sorted(p.name for p in out.iterdir()) == sorted(GOLDEN_FILES + ["preview.png"])
    assert (out / "preview.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    lines = res.stdout.splitlines()
    header = next(line for line in lines if line.startswith("vehicle"))
    assert header.split() == ["vehicle", "waypoints", "items", "length", "km", "time", "m:s", "energy", "kJ",
                              "%", "budget"]
    rows = [line.split() for line in lines if line.startswith("uav")]
    assert [r[0] for r in rows] == ["uav1", "uav2"]
    for r in rows:
        mission = plan_file.read(out / f"{r[0]}.plan")
        assert int(r[1]) == len(mission.waypoints()) and int(r[2]) == len(mission.items)
        assert 0 < float(r[6]) < 100
    assert res.stderr == ""


def test_plan_and_waypoints_describe_the_same_mission(small_out):
    out, _ = small_out
    for k in (1, 2):
        a = plan_file.read(out / f"uav{k}.plan")
        b = wpl_file.read(out / f"uav{k}.waypoints", autopilot=a.autopilot)
        assert a.autopilot == "px4" and a.same_as(b)
        assert (a.home_lat_deg, a.home_lon_deg) == (b.home_lat_deg, b.home_lon_deg)


_NUMBER = re.compile(r"-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")


def _same_text(a: str, b: str, tol: float = 1e-9) -> bool:
    """Identical text except numbers, which may differ by ``tol`` (relative, and absolute near 0):
    float noise from another numpy/pyproj build must not fail the golden test, anything else must."""
    if _NUMBER.sub("#", a) != _NUMBER.sub("#", b):
        return False
    xs, ys = _NUMBER.findall(a), _NUMBER.findall(b)
    return all(abs(float(x) - float(y)) <= tol * max(1.0, abs(float(x))) for x, y in zip(xs, ys))


def test_golden_files(small_out):
    """The output for examples/small.toml, to the last digit that matters. After an intended
    change, regenerate with UAVLOC_REGEN_GOLDEN=1 python -m pytest tests/test_cli_plan.py and
    review the diff."""
    out, _ = small_out
    if os.environ.get("UAVLOC_REGEN_GOLDEN"):
        GOLDEN.mkdir(parents=True, exist_ok=True)
        for name in GOLDEN_FILES:
            shutil.copyfile(out / name, GOLDEN / name)
    for name in GOLDEN_FILES:
        assert _same_text((out / name).read_text(), (GOLDEN / name).read_text()), \
            f"{name} differs from tests/data/small"


def test_golden_comparison_is_strict_where_it_matters():
    assert _same_text('"lat": 47.3977000000001', '"lat": 47.3977')
    assert not _same_text('"lat": 47.3977', '"lat": 47.3978')
    assert not _same_text('"frame": 3', '"frame": 2')
    assert not _same_text("0\t1\t16", "0\t1\t16\t0")


def test_geojson_has_area_launch_and_per_vehicle_features(small_out):
    fc = json.loads((small_out[0] / "scan.geojson").read_text())
    kinds = [(f["properties"]["kind"], f["properties"].get("vehicle")) for f in fc["features"]]
    assert ("area", None) in kinds and ("launch", None) in kinds
    for v in ("uav1", "uav2"):
        for kind in ("subarea", "lanes", "route", "waypoints"):
            assert (kind, v) in kinds


def test_plan_is_deterministic(small_out, tmp_path, uavloc_inproc):
    res = uavloc_inproc("plan", EXAMPLES / "small.toml", "--out", tmp_path / "again")
    assert res.returncode == 0
    for name in GOLDEN_FILES + ["preview.png"]:
        assert (tmp_path / "again" / name).read_bytes() == (small_out[0] / name).read_bytes(), name


def _one_sentence_error(res):
    assert res.returncode == 2
    assert res.stdout == ""
    err = res.stderr.strip()
    assert err.startswith("uavloc ") and "error:" in err and "\n" not in err and "Traceback" not in err
    return err


@pytest.mark.parametrize(
    "toml, fragment",
    [
        ("[area]\norigin_lat_deg = 47.0\n", "area.origin_lon_deg"),
        ("[area]\norigin_lat_deg = 47.0\norigin_lon_deg = 8.0\nwidth_m = 400\nheight_m = 300\n"
         "[fleet]\nenergy_budget_j = 5000\n", "needs"),
        ("[area]\norigin_lat_deg = 47.0\norigin_lon_deg = 8.0\nwidth_m = 400\nheight_m = 300\n"
         "[scan]\nlane_spacing_m = 500\n", "scan.lane_spacing_m"),
        ("[area]\npolygon_file = 'missing.geojson'\n", "area.polygon_file"),
        ("this is not toml", "not valid TOML"),
    ],
    ids=["missing-key", "energy", "lane-spacing", "area-file", "toml"],
)
def test_bad_scenarios_fail_cleanly_without_output(tmp_path, toml, fragment, uavloc_inproc):
    (tmp_path / "s.toml").write_text(toml)
    res = uavloc_inproc("plan", tmp_path / "s.toml", "--out", tmp_path / "out")
    err = _one_sentence_error(res)
    assert fragment in err
    if fragment != "needs":  # config errors name the scenario file; the energy error names the vehicle
        assert "s.toml" in err
    assert not (tmp_path / "out").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]  # no partial directory either


def test_infeasible_energy_message_has_the_numbers(tmp_path):
    (tmp_path / "s.toml").write_text("[area]\norigin_lat_deg = 47.0\norigin_lon_deg = 8.0\nwidth_m = 400\n"
                                     "height_m = 300\n[fleet]\nenergy_budget_j = 5000\n")
    err = _one_sentence_error(uavloc("plan", tmp_path / "s.toml", "--out", tmp_path / "out"))
    assert "uav1 needs" in err and "may use only 4.2 kJ" in err and "15% reserve" in err


def test_missing_scenario_and_output_path_that_is_a_file(tmp_path, uavloc_inproc):
    err = _one_sentence_error(uavloc_inproc("plan", tmp_path / "nope.toml", "--out", tmp_path / "out"))
    assert "nope.toml" in err and "not found" in err
    (tmp_path / "afile").write_text("x")
    err = _one_sentence_error(uavloc_inproc("plan", EXAMPLES / "small.toml", "--out", tmp_path / "afile"))
    assert "not a directory" in err


def test_coverage_override(tmp_path, uavloc_inproc):
    res = uavloc_inproc("plan", EXAMPLES / "small.toml", "--out", tmp_path / "o", "--coverage", "single")
    assert res.returncode == 0 and "single coverage" in res.stdout


@pytest.mark.parametrize("name", ["uav1.plan", "uav2.waypoints"])
def test_preview_prints_picture_and_table(small_out, name, tmp_path, uavloc_inproc):
    run = uavloc if name.endswith(".plan") else uavloc_inproc
    res = run("preview", small_out[0] / name, "--png", tmp_path / "p.png")
    assert res.returncode == 0, res.stderr
    out = res.stdout
    assert "H" in out and "*" in out and "north up" in out
    assert "NAV_TAKEOFF" in out and "DO_CHANGE_SPEED" in out and "NAV_RETURN_TO_LAUNCH" in out
    assert "pass-through" in out
    assert (tmp_path / "p.png").read_bytes()[:4] == b"\x89PNG"
    picture = [line for line in out.splitlines() if line.startswith("|") and line.endswith("|")]
    assert len(picture) >= 5 and len({len(line) for line in picture}) == 1


@pytest.mark.parametrize(
    "name, text, fragment",
    [
        ("bad.plan", '{"fileType": "Plan", "version": 1}', "groundStation"),
        ("bad.waypoints", "QGC WPL 110\n0\t1\t0\t16\n", "line 2"),
        ("bad.txt", "hello", "first line must be"),
    ],
)
def test_preview_of_malformed_file(tmp_path, name, text, fragment, uavloc_inproc):
    (tmp_path / name).write_text(text)
    err = _one_sentence_error(uavloc_inproc("preview", tmp_path / name))
    assert name in err and fragment in err


def test_preview_missing_file_and_bad_picture_suffix(small_out, tmp_path, uavloc_inproc):
    err = _one_sentence_error(uavloc_inproc("preview", tmp_path / "none.plan"))
    assert "not found" in err
    err = _one_sentence_error(uavloc_inproc("preview", small_out[0] / "uav1.plan", "--png", tmp_path / "p.jpg"))
    assert ".png or .svg" in err and not (tmp_path / "p.jpg").exists()


@pytest.mark.parametrize("args, fragment", [(["--lane-spacing", "-5"], "--lane-spacing"),
                                            (["--lane-spacing", "0.5"], "--lane-spacing: 0.5 m is too narrow"),
                                            (["--lane-spacing", "400"], "too wide")])
def test_bad_overrides(tmp_path, uavloc_inproc, args, fragment):
    err = _one_sentence_error(uavloc_inproc("plan", EXAMPLES / "small.toml", "--out", tmp_path / "o", *args))
    assert fragment in err and not (tmp_path / "o").exists()


def test_preview_of_a_mission_without_positions(tmp_path, uavloc_inproc):
    f = tmp_path / "rtl.waypoints"
    f.write_text("QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t0\t0\t0\t1\n1\t0\t2\t20\t0\t0\t0\t0\t0\t0\t0\t1\n")
    res = uavloc_inproc("preview", f)
    assert res.returncode == 0 and "no positional items" in res.stdout and "NAV_RETURN_TO_LAUNCH" in res.stdout


FILES = ROOT / "tests" / "data" / "files"


def _picture(out):
    return [line for line in out.splitlines() if line.startswith("|") and line.endswith("|")]


def test_preview_does_not_draw_mission_planner_placeholders(uavloc_inproc, tmp_path):
    res = uavloc_inproc("preview", FILES / "mp_placeholders.waypoints", "--png", tmp_path / "p.png")
    assert res.returncode == 0, res.stderr
    out = res.stdout
    assert "4 item(s) with lat/lon 0, 0" in out
    km = float(re.search(r"route ([0-9.]+) km", out).group(1))
    assert 0.2 < km < 1.0  # home, three waypoints, RTL: ~400 m, not thousands of km to Null Island
    pic = _picture(out)
    assert sum(line.count("o") for line in pic) == 3 and sum(line.count("H") for line in pic) == 1
    assert "here" in out and (tmp_path / "p.png").read_bytes()[:4] == b"\x89PNG"


def test_preview_of_a_zero_home_draws_no_home(uavloc_inproc):
    res = uavloc_inproc("preview", FILES / "zero_home.plan")
    assert res.returncode == 0
    assert "home not in the file" in res.stdout and not any("H" in line for line in _picture(res.stdout))
    km = float(re.search(r"route ([0-9.]+) km", res.stdout).group(1))
    assert km < 0.2


def test_preview_draws_fences_circles_and_rally_points(uavloc_inproc, tmp_path):
    res = uavloc_inproc("preview", FILES / "fences_rally.plan", "--png", tmp_path / "f.svg")
    assert res.returncode == 0, res.stderr
    out = res.stdout
    assert "geofence: 2 inclusion, 2 exclusion zone(s); 2 rally point(s)" in out
    pic = "".join(_picture(out))
    assert pic.count("R") == 2 and "x" in pic and "." in pic
    svg = (tmp_path / "f.svg").read_text()
    assert "exclusion zone" in svg and "exclusion circle" in svg and "rally point" in svg


def test_preview_of_a_qgc4_survey_and_of_files_that_are_not_missions(uavloc_inproc):
    res = uavloc_inproc("preview", FILES / "survey_qgc4.plan")
    assert res.returncode == 0 and "DO_SET_CAM_TRIGG_DIST" in res.stdout
    for name, fragment in [("fence_circle.waypoints", "geofence file, not a mission"),
                           ("rally.waypoints", "rally-point file, not a mission"),
                           ("legacy.mission", "legacy QGroundControl .mission"),
                           ("above_terrain_unresolved.plan", "calculated above terrain")]:
        err = _one_sentence_error(uavloc_inproc("preview", FILES / name))
        assert name in err and fragment in err
