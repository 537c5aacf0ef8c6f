"""A fix must not rest on where a phone was not heard (issue 42 item 0).

Reproduction: a paper demo beside two CPU burners (seed 5) declared a walker located with a 7.3 m
radius 142 m from the truth. The walker turned during the last look; with the silences of the
passes around (where vehicles listened without hearing the phone), the constant-velocity model
found a sharp mode at the area's edge; the heard slots alone put the walker 11 m from the truth.
The slots and silences are that demo's, from its store. The truth at the estimate's reference time
(253.95 s on the daemon's clock, 24 s behind the fleet's: world seed 5 at 277.95 s) is (659.8, 535.1).
"""

from pathlib import Path

import numpy as np

from uavloc_gcs.estimation import ChannelModel, Silence
from uavloc_gcs.estimation.fitting import FitJob, run_fit
from uavloc_gcs.estimation.slots_csv import read_slots_csv
from uavloc_gcs.examples import scenario_path
from uavloc_gcs.scenario import load_scenario

DATA = Path(__file__).parents[2] / "data" / "issue42"
TRUTH = np.array([659.8, 535.1])


def _case():
    sc = load_scenario(scenario_path("paper"))
    slots = read_slots_csv(DATA / "turning_walker_slots.csv", sc.frame)
    rows = np.loadtxt(DATA / "turning_walker_silences.csv", delimiter=",", skiprows=1)
    return sc, slots, Silence(rows[:, 0], rows[:, 1:4])


def test_a_sharp_estimate_that_only_the_silences_support_is_flagged():
    sc, slots, silence = _case()
    ch = ChannelModel.from_scenario(sc)
    job = FitJob(int(slots.emitter_id[0]), 1, slots, 1.5, float(slots.t_s.max()), True, None, silence, None,
                 check_within_m=sc.people.required_accuracy_m)
    res = run_fit(job, ch, None)
    est = res.estimate
    # the estimator's own answer is sharp and wrong: this is what the check is for
    assert est.radius95_m <= 15.0 and np.hypot(*(est.position_xy_m - TRUTH)) > 100.0
    assert res.contradicted.startswith("the slots where it was heard put it")
    # without the silences the heard slots agree with the truth
    plain = run_fit(FitJob(job.emitter_id, 1, slots, 1.5, job.t_ref_s, True), ch, None).estimate
    assert np.hypot(*(plain.position_xy_m - TRUTH)) <= 1.5 * plain.radius95_m


def test_the_policy_does_not_locate_a_contradicted_person(monkeypatch):
    from uavloc_gcs.search import SearchPolicy

    sc, slots, silence = _case()
    policy = SearchPolicy(sc)
    monkeypatch.setattr(policy, "_silence", lambda p: silence)
    policy.ingest(slots)
    policy.update(float(slots.t_s.max()) + 1.0)
    (st,) = policy.people(float(slots.t_s.max()) + 1.0)
    assert not st.located and "only where it was not heard points there" in st.reason
