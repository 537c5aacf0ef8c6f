"""``uavloc demo``, the README's main command, end to end on a small scenario."""

import csv
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.mark.slow
def test_demo_runs_to_the_end_and_writes_its_results(tmp_path):
    out = tmp_path / "demo"
    proc = subprocess.run(
        [sys.executable, "-m", "uavloc_gcs", "demo", "--scenario", str(EXAMPLES / "small.toml"),
         "--people", "2", "--speedup", "30", "--base-port", "26900", "--out", str(out), "--no-web"],
        capture_output=True, text=True, timeout=240,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "true error" in proc.stdout  # the results table, next to the simulated truth
    assert "All vehicles are home" in proc.stdout
    # the statement is said once, after the table (issue 40 item 3: it was printed twice)
    assert proc.stdout.count("All vehicles are home") == 1
    assert "the search has ended; the results follow" in proc.stdout
    for name in ("people.csv", "people.geojson", "people.kml", "result.png", "search.sqlite", "uav1.tlog"):
        assert (out / name).stat().st_size > 0, name
    assert "live map:" not in proc.stdout  # --no-web keeps it headless
    rows = list(csv.DictReader((out / "people.csv").open()))
    assert len(rows) == 2
    assert sorted(r["label"] for r in rows) == ["P01", "P02"]
    for r in (r for r in rows if r["state"] != "never heard"):  # when the position was true: UTC, mission s
        assert r["time_utc"].endswith("Z") and float(r["t_ref_s"]) > 0.0
        assert f"{r['label']} #{r['emitter_id']}" in proc.stdout  # the same label in the table
    assert (out / "result.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_demo_with_a_bad_scenario_is_one_sentence(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[area]\nwidth_m = 10\n")
    proc = subprocess.run([sys.executable, "-m", "uavloc_gcs", "demo", "--scenario", str(bad), "--out",
                           str(tmp_path / "o")], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "bad.toml" in proc.stderr
    assert not (tmp_path / "o").exists()
