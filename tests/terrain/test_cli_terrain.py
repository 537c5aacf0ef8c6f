"""``uavloc plan`` over terrain: the one line about the ground, AMSL missions, one-sentence refusals."""

from __future__ import annotations

import json

from uavloc_gcs.cli import main

from .dems import EXAMPLES
from .test_clearance import RIDGE_AREA, ridge_scenario


def run(capsys, *args):
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_plan_over_the_mountain_says_so_and_writes_terrain_following_missions(tmp_path, capsys):
    code, out, err = run(capsys, "plan", EXAMPLES / "mountains.toml", "--out", tmp_path / "p")
    assert code == 0, err
    assert "Terrain: mount_washington_srtm3.tif (66 m cells, heights above the EGM96 geoid)" in out
    doc = json.loads((tmp_path / "p" / "uav1.plan").read_text())
    alts = [it["params"][6] for it in doc["mission"]["items"] if it["command"] == 16]
    assert min(alts) > 1126.0 and max(alts) > 1400.0  # AMSL, up the mountain


def test_plan_without_a_dem_says_the_ground_is_flat_once(tmp_path, capsys):
    code, out, _ = run(capsys, "plan", EXAMPLES / "small.toml", "--out", tmp_path / "p")
    assert code == 0 and out.count("flat at the launch point's height") == 1


def test_plan_refuses_a_ridge_above_the_ceiling_in_one_sentence_and_writes_nothing(tmp_path, capsys):
    ridge_scenario(tmp_path)  # writes ridge.tif
    (tmp_path / "r.toml").write_text(RIDGE_AREA + '\n[terrain]\ndem = "ridge.tif"\nmax_height_above_launch_m = 200\n')
    code, out, err = run(capsys, "plan", tmp_path / "r.toml", "--out", tmp_path / "p")
    assert code == 2
    line = err.strip().splitlines()[-1]
    assert "crosses ground" in line and "terrain.max_height_above_launch_m = 200 m" in line
    assert not (tmp_path / "p").exists()


def test_plan_refuses_a_bad_dem_naming_the_key(tmp_path, capsys):
    (tmp_path / "bad.tif").write_bytes(b"II*\x00garbage")
    (tmp_path / "r.toml").write_text(RIDGE_AREA + '\n[terrain]\ndem = "bad.tif"\n')
    code, _, err = run(capsys, "plan", tmp_path / "r.toml", "--out", tmp_path / "p")
    assert code == 2 and "terrain.dem" in err and "not a DEM that GDAL can read" in err
