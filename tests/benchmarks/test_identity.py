"""``uavloc bench identity``: its scores on known answers, its generator's truth, and a quick run."""

import argparse

import numpy as np

from benchmarks import identity as bench


def test_scores_on_a_known_answer():
    # bursts' reported people and true people: person 10 holds truths 1,1,2 (one wrong burst, one
    # merge); truth 3 is split over 20 and 30
    reported = np.array([10, 10, 10, 20, 30])
    truth = np.array([1, 1, 2, 3, 3])
    s = bench.score(reported, truth)
    assert s == dict(heard=3, reported=3, bursts=5, wrong=1, splits=1, merges=1)


def test_generator_truth_and_anchors():
    """Every address heard has a true owner; no linking (every address a person) is never wrong,
    fingerprints alone merge people; the linker reports about as many people as were heard."""
    world = bench.simulate(bench.FIELD, 10, 3, stable=0.14, duration_s=900.0, rng=np.random.default_rng(5))
    assert len(world.slots) > 0 and set(np.unique(world.slots.address).tolist()) <= set(world.truth)
    out = bench.evaluate(world)
    assert out["addresses"]["wrong"] == 0 and out["addresses"]["merges"] == 0
    assert out["fingerprint"]["reported"] <= 3 + out["fingerprint"]["heard"]  # models, plus stable phones
    lk = out["linker"]
    assert lk["bursts"] == out["addresses"]["bursts"]
    assert lk["reported"] < out["addresses"]["reported"]
    assert lk["wrong"] <= out["fingerprint"]["wrong"]


def test_main_runs_and_prints_every_method(capsys):
    p = argparse.ArgumentParser()
    bench.add_arguments(p)
    assert bench.main(p.parse_args(["--runs", "1", "--people", "5", "--models", "2", "--duration", "600",
                                    "--scenario", "paper"])) == 0
    out = capsys.readouterr().out
    for method in ("linker", "addresses", "fingerprint"):
        assert f" {method} " in out


def test_uavloc_localize_links_a_burst_world(tmp_path):
    """A slot CSV with the sensor's columns from a simulated world of 4 people: `uavloc localize`
    reports people (not addresses), each with its ';'-separated addresses and a link state, and the
    addresses of every person are the ones heard."""
    import csv
    import subprocess
    import sys
    from pathlib import Path

    from uavloc_gcs.estimation.slots_csv import dumps_slots_csv
    from uavloc_gcs.scenario import load_scenario

    root = Path(__file__).resolve().parents[2]
    sc = load_scenario(root / "examples" / "field.toml")
    world = bench.simulate(bench.Setting.from_scenario(sc), 4, 2, stable=0.0, duration_s=600.0,
                           rng=np.random.default_rng(7))
    src = tmp_path / "slots.csv"
    src.write_text(dumps_slots_csv(world.slots, sc.frame))
    r = subprocess.run([sys.executable, "-m", "uavloc_gcs", "localize", src, "--scenario",
                        root / "examples" / "field.toml", "--out", tmp_path / "o"],
                       capture_output=True, text=True, cwd=root, timeout=300)
    assert r.returncode == 0, r.stderr
    rows = list(csv.DictReader(open(tmp_path / "o" / "estimates.csv")))
    n_addr = len(np.unique(world.slots.address))
    assert 1 <= len(rows) < n_addr and f"{n_addr} address(es) heard, linked into {len(rows)} people" in r.stdout
    heard = set()
    for row in rows:
        assert row["link"] in ("sure", "uncertain") and (row["link"] == "uncertain") == bool(row["link_reason"])
        heard |= set(row["addresses"].split(";"))
    assert len(heard) == n_addr
