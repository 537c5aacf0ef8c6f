"""bench localize --emission bursts: its world and its figures are deterministic and sane."""

import numpy as np

from benchmarks.localize_bursts import BURST_FAMILIES, draw_run, frames_prior, run_burst_family


def test_frames_prior_is_the_worlds():
    p = frames_prior().p
    assert len(p) == 27 and np.all(p > 0)  # round(sent / 3) for sent in 3-80


def test_a_run_has_exactly_the_familys_bursts():
    fam = next(f for f in BURST_FAMILIES if f.name.startswith("2 bursts, crossing, static"))
    slots, tracks, (tf, xf), where, tries = draw_run(fam, np.random.default_rng(3))
    assert len(slots) >= 1 and len(tf) >= len(slots) and len(tracks) == 2
    assert np.all(slots.rssi_dbm > -92.0)


def test_burst_family_is_deterministic():
    fam = next(f for f in BURST_FAMILIES if f.name.startswith("2 bursts, crossing, static"))
    a = run_burst_family(fam, 2, 7, mmse=True)
    b = run_burst_family(fam, 2, 7, mmse=True)
    assert a["runs"] >= 1 and a["rmse"] == b["rmse"] and a["mmse"] == b["mmse"]
    assert a["vt"] < a["rmse"] and a["ess_min"] > 10
