"""What the scenario's phones send, as the estimator, the POD model and the looks assume it.

The probe bursts' frame counts (:func:`frames_prior`), the law of their rate (:func:`burst_rates`,
for the bursts nobody heard) and the share of a burst's frames on the channels the sensor listens
to (:func:`channel_share`), all from the scenario's ``[emission]`` and ``[channel]`` keys. Below the
policy, the POD model and the coverage accumulator, which all read them: ``search/`` imports run
from this module and the POD model up to the policy, never back.
"""

from __future__ import annotations

import math

import numpy as np

from ..scenario import Scenario

# Share of a probe burst's frames on 2.4 GHz channels 1 / 6 / 11 (the public captures' sniffers; the
# same numbers as sim_link/world/emission.py CHANNEL_WEIGHTS, a test keeps them equal).
PROBE_CHANNEL_SHARES = {1: 0.349, 6: 0.254, 11: 0.398}

# Burst-to-burst spread of one phone's frame count (log std), as fitted to the public captures
# (sim_link/world/emission.py FRAMES_LOG_SIGMA, docs/science/world.md).
FRAMES_LOG_SIGMA = 0.41

# The POD model's tables of the gap law (search/pod.py, search/pod_a2g.py)
N_QUANTILES = 16  # phone quantiles u (midpoints) of the gap law
ACTIVE_DT_S = 0.5  # grid of the active (no long silence) renewal process
ACTIVE_CAP_S = 3600.0  # its tables reach this window; every active phone has sent k <= 4 bursts by then
SILENCE_DRAWS = 48  # steady-state long-silence timelines per phone quantile
WINDOW_CAP_S = 6 * 3600.0  # window_for gives up beyond this (long silences last up to 90 min)
MIN_QUIET_S = 1.0  # shortest quiet time after a burst (sim_link/world/emission.py MIN_QUIET_S)


def channel_share(sc: Scenario) -> float:
    """The share of a probe burst's frames sent on the channels the sensor listens to."""
    chans = sc.channel.listen_channel_list
    total = sum(PROBE_CHANNEL_SHARES.values())
    return sum(PROBE_CHANNEL_SHARES.get(c, 0.0) for c in chans) / total


def frames_prior(scenario: Scenario):
    """The frames a phone sends per probe burst, as the scenario's emission keys describe them, for the
    estimator's hearing counts (estimation.evidence.FramesPrior): a phone's median count log-uniform
    between ``frames_per_burst_median_min`` and ``_max``, each burst log-normal about it
    (FRAMES_LOG_SIGMA), at most ``frames_per_burst_max``; every frame on a channel the sensor listens
    to (probe scans sweep 1/6/11, where the sensor has its radios). Deterministic (a fixed sample)."""
    from ..estimation.evidence import FramesPrior

    em = scenario.emission
    rng = np.random.default_rng(0)
    n = 50_000
    lo, hi = math.log(em.frames_per_burst_median_min), math.log(em.frames_per_burst_median_max)
    median = np.exp(rng.uniform(lo, hi, n))
    k = np.clip(np.rint(median * np.exp(FRAMES_LOG_SIGMA * rng.standard_normal(n))), 1, em.frames_per_burst_max)
    counts = np.bincount(k.astype(int), minlength=int(em.frames_per_burst_max) + 1)[1:].astype(float)
    return FramesPrior(counts + 0.5)  # no count impossible


def burst_rates(scenario: Scenario):
    """The burst-rate law of the scenario's phones, for the bursts nobody heard
    (estimation.evidence.Exposure): a phone's median gap log-uniform between
    ``burst_gap_median_min_s`` and ``_max_s``, its gaps log-normal with the 90th percentile the
    scenario gives at either end. The world's rare long silences are left out (about 1 gap in 100)."""
    from ..estimation.evidence import burst_rate_prior

    em = scenario.emission
    z90 = 1.2816
    sigma = (math.log(em.burst_gap_p90_min_s / em.burst_gap_median_min_s) / z90,
             math.log(em.burst_gap_p90_max_s / em.burst_gap_median_max_s) / z90)
    return burst_rate_prior((em.burst_gap_median_min_s, em.burst_gap_median_max_s), sigma, log_uniform=True)
