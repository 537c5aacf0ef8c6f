"""Where estimates are computed (issue 42): in the caller or in a worker process, with the same
answers; a stopped search does not wait for a fit; a worker that dies is replaced."""

import os
import time
from pathlib import Path

import numpy as np
import pytest

from sim_link.world import World
from uavloc_gcs.estimation import ChannelModel
from uavloc_gcs.estimation.fitting import FitJob, FitResult, InlineFitter, ProcessFitter, run_fit
from uavloc_gcs.observations import SlotBatch
from uavloc_gcs.scenario import load_scenario

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"
P = np.array([560.0, 320.0])


@pytest.fixture(scope="module")
def job_and_channel():
    sc = load_scenario(EXAMPLES / "paper.toml")
    world = World.with_people(sc, [P], seed=21)
    legs = []
    for (a, b), t0 in ((((360.0, 280.0), (760.0, 280.0)), 0.0), (((590.0, 520.0), (590.0, 120.0)), 25.0)):
        a, b = np.asarray(a), np.asarray(b)
        n = 640
        f = np.arange(n) / n
        t = t0 + f * 16.0
        legs.append(world.hear_track(1, t, np.column_stack([a + np.outer(f, b - a), np.full(n, 100.0)])))
    slots = SlotBatch.concat(legs)
    job = FitJob(int(slots.emitter_id[0]), 1, slots, 1.5, float(slots.t_s.max()), True)
    return job, ChannelModel.from_scenario(sc)


def wait_for(fitter, timeout_s=60.0):
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout_s:
        out = fitter.results()
        if out:
            return out
        time.sleep(0.05)
    raise AssertionError("no fit result within the time limit")


def test_worker_process_gives_the_same_estimate_as_the_caller(job_and_channel):
    job, channel = job_and_channel
    inline = InlineFitter(channel)
    inline.submit(job)
    (a,) = inline.results()
    proc = ProcessFitter(channel, max_batch=2)
    try:
        assert proc.can_take()
        proc.submit(job)
        proc.submit(FitJob(job.emitter_id, 2, job.slots, job.max_speed_m_s, job.t_ref_s, True))
        assert not proc.can_take() and proc.in_flight() == 2  # a batch of at most max_batch
        b, b2 = wait_for(proc)  # the batch comes back whole
    finally:
        proc.close()
    assert (b.version, b2.version) == (1, 2)
    assert a.estimate is not None and b.estimate is not None, (a.error, b.error, a.crash, b.crash)
    assert (a.emitter_id, a.version) == (b.emitter_id, b.version) == (job.emitter_id, 1)
    np.testing.assert_array_equal(a.estimate.position_xy_m, b.estimate.position_xy_m)
    assert a.estimate.radius95_m == b.estimate.radius95_m
    assert proc.can_take()


def slow_fit(job, channel, dem):
    """A fit that keeps the worker busy for a minute of pure-Python work."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < 60.0:
        sum(range(1000))
    return run_fit(job, channel, dem)


def test_closing_does_not_wait_for_a_fit_under_way(job_and_channel):
    job, channel = job_and_channel
    proc = ProcessFitter(channel, fit=slow_fit)
    proc.submit(job)
    time.sleep(1.0)
    workers = list(proc._pool._processes.values())
    assert workers and all(p.is_alive() for p in workers)
    t0 = time.monotonic()
    proc.close()
    assert time.monotonic() - t0 < 10.0
    assert not any(p.is_alive() for p in workers)


def dying_fit(job, channel, dem):
    """The worker dies on the job with version 0 (as if killed), and fits the others."""
    if job.version == 0:
        os._exit(3)
    return run_fit(job, channel, dem)


def test_a_worker_that_dies_is_replaced_and_the_job_comes_back_as_a_crash(job_and_channel):
    job, channel = job_and_channel
    proc = ProcessFitter(channel, fit=dying_fit)
    try:
        proc.submit(FitJob(job.emitter_id, 0, job.slots, job.max_speed_m_s, job.t_ref_s, True))
        (crash,) = wait_for(proc)
        assert isinstance(crash, FitResult) and crash.estimate is None and "died" in crash.crash
        proc.submit(job)
        (ok,) = wait_for(proc)
        assert ok.estimate is not None and ok.version == 1
    finally:
        proc.close()
