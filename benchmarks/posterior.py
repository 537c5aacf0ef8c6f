"""The least error any estimator of the RSSI alone can reach: the posterior mean, by importance sampling.

The Bayesian (Van Trees) Cramer-Rao bound is a small-error asymptote. Where the slots pin only a
function of the position that is flat at the truth it lies far below what any estimator can
reach: a walker who ends near the track of the last pass is heard at a range that fixes only
the squared lateral offset (SPEC §3.1: right under a track the lateral coordinate is unobservable
to first order), so the posterior stays tens of metres wide along the cross-track direction while
the information at the truth, a few metres off the track, says a few metres.

The posterior mean under the model that made the data is, by definition, the estimator of least
mean-square error. :func:`rssi_posterior_mean` computes it for a constant-velocity person: the
log-normal ranging likelihood of every slot heard (slot means, as the estimator sees them), the
family's own velocity prior (uniform over the disk |v| <= v_max, how ``bench localize`` draws
walkers) and a flat position prior. It uses no hearing evidence (where the phone was and was
not heard), as the bound uses none. The RMSE of these means over a family's runs is the attainable
floor beside the bound: an estimator of the RSSI alone at 1.0x it is as good as any can be.

Adaptive importance sampling: a mixture proposal of Gaussians about the estimator's candidates,
their mirror images across every straight leg, then two rounds refitted to the weighted samples;
the effective sample size is returned so a run whose weights collapsed can be seen.
"""

from __future__ import annotations

import math

import numpy as np

from uavloc_gcs.estimation.prepared import Prepared
from uavloc_gcs.estimation.starts import leg_lines, mirror_point

CHUNK = 2000


def log_posterior(x: np.ndarray, data: Prepared, t_ref: float, max_speed_m_s: float) -> np.ndarray:
    """Unnormalised log posterior of states x (K, 4) = (position at t_ref, velocity)."""
    tau = data.t_s - t_ref
    out = np.empty(len(x))
    for i in range(0, len(x), CHUNK):
        p, v = x[i:i + CHUNK, :2], x[i:i + CHUNK, 2:]
        gx = p[:, :1] + v[:, :1] * tau - data.a_xy[:, 0]
        gy = p[:, 1:2] + v[:, 1:2] * tau - data.a_xy[:, 1]
        r = data.y - 0.5 * np.log(gx * gx + gy * gy + data.h_m**2)
        lp = -0.5 * (r * r) @ data.w
        out[i:i + CHUNK] = np.where(np.hypot(v[:, 0], v[:, 1]) <= max_speed_m_s, lp, -np.inf)
    return out


def _reflect(state: np.ndarray, t_ref: float, center, direction, t_leg: float) -> np.ndarray:
    """A state (position at t_ref, velocity) mirrored across a leg at the leg's time."""
    p, v = state[:2], state[2:]
    v_m = mirror_point(v, np.zeros(2), direction)
    p_m = mirror_point(p + v * (t_leg - t_ref), center, direction) - v_m * (t_leg - t_ref)
    return np.concatenate([p_m, v_m])


def _mvn_logpdf(x: np.ndarray, mean: np.ndarray, chol: np.ndarray) -> np.ndarray:
    z = np.linalg.solve(chol, (x - mean).T)
    return -0.5 * np.sum(z * z, axis=0) - float(np.sum(np.log(np.diag(chol))))


def estimate_candidates(est) -> list[tuple[np.ndarray, np.ndarray]]:
    """An estimate's best mode and its mirror (when any) as (state (4,), covariance (4, 4)) at its
    reference time: where :func:`rssi_posterior_mean` starts its proposal."""
    out = [(np.concatenate([est.position_xy_m, est.velocity_m_s]), est.covariance)]
    if est.mirror is not None:
        m = est.mirror
        out.append((np.concatenate([m.position_xy_m, m.velocity_m_s]), m.covariance))
    return out


def rssi_posterior_mean(data: Prepared, t_ref: float, candidates: list[tuple[np.ndarray, np.ndarray]],
                        max_speed_m_s: float, rng: np.random.Generator, samples: int = 20_000,
                        rounds: int = 3) -> tuple[np.ndarray, float]:
    """Posterior mean of the position at ``t_ref`` and the effective sample size of the last round.

    ``candidates``: (state (4,), covariance (4, 4)) at t_ref to start the proposal from (the
    estimator's best mode and its mirror); their mirrors across every leg are added.
    """
    floor = np.diag([1.0, 1.0, 0.01, 0.01])
    widen = np.diag([100.0, 100.0, 0.25, 0.25])
    centers = []
    legs = leg_lines(data)
    for state, cov in candidates:
        centers.append((state, cov))
        for c, d, t_leg in legs:
            centers.append((_reflect(state, t_ref, c, d, t_leg), cov))
    wide = [(m, 9.0 * (0.5 * (c + c.T) + floor) + widen) for m, c in centers]
    return _population_mc(lambda x: log_posterior(x, data, t_ref, max_speed_m_s), wide, wide[:2],
                          candidates[0][0][:2], floor, samples=samples, rounds=rounds, rng=rng)



def _population_mc(log_post, wide, keep, start_mean, floor, *, samples: int, rounds: int, rng):
    """Adaptive importance sampling (population Monte Carlo) of a posterior from the Gaussian
    components ``wide`` [(mean, cov)]: each round samples the mixture, weighs by ``log_post`` and
    refits one component per current one to the samples nearest it, beside the components ``keep``
    (so a mode once found is never dropped). Returns the weighted mean position and the ESS."""
    comps, ess, mean = wide, 0.0, start_mean
    dim = len(wide[0][0])
    for _ in range(rounds):
        chols = []
        for m, c in comps:
            try:
                chols.append((m, np.linalg.cholesky(c)))
            except np.linalg.LinAlgError:
                chols.append((m, np.diag(np.sqrt(np.abs(np.diag(c))) + 1e-3)))
        n = max(samples // len(chols), 1)
        x = np.vstack([m + rng.standard_normal((n, dim)) @ l.T for m, l in chols])
        lq = np.logaddexp.reduce(np.stack([_mvn_logpdf(x, m, l) for m, l in chols]), axis=0)
        lw = log_post(x) - lq
        if not np.any(np.isfinite(lw)):
            break
        w = np.exp(lw - np.max(lw))
        w /= w.sum()
        ess = float(1.0 / np.sum(w * w))
        mean = w @ x[:, :2]
        near = np.argmin(np.stack([np.linalg.norm(x[:, :2] - m[:2], axis=1) for m, _ in comps]), axis=0)
        refit = []
        for j in range(len(comps)):
            wj = w * (near == j)
            if wj.sum() < 1e-6:
                continue
            mj = wj @ x / wj.sum()
            dj = x - mj
            refit.append((mj, 2.0 * (dj * wj[:, None]).T @ dj / wj.sum() + floor))
        comps = keep + refit
    return mean, ess

def mmse_floor(errors_m: np.ndarray) -> float:
    """RMSE of the posterior means over a family's runs."""
    e = np.asarray(errors_m, float)
    return float(math.sqrt(np.mean(e * e))) if len(e) else math.nan


# ---------------------------------------------------------------------------------------------
# The field world (bench localize --emission bursts): the same posterior mean under the receiver
# threshold, with the truncated likelihood of the frames heard and the censored silences within
# heard bursts, exactly the estimator's likelihood (uavloc_gcs.estimation.fit), and the family's
# priors (static: the velocity is zero; walkers: uniform over the disk). A wide component over
# the whole hearing region joins the proposal: a few bursts leave rings, not ellipses.


def burst_log_posterior(x: np.ndarray, data: Prepared, t_ref: float, max_speed_m_s: float, channel,
                        censored=None) -> np.ndarray:
    """Unnormalised log posterior of states x (K, 2) (static) or (K, 4) (position at t_ref, velocity)."""
    from scipy.special import log_ndtr

    s, y_s = channel.log_range_sigma, channel.threshold_log_range
    b = np.minimum((data.y - y_s) / s, -1e-2)
    n = data.n_samples
    tau = data.t_s - t_ref
    out = np.empty(len(x))
    for i in range(0, len(x), CHUNK):
        p = x[i:i + CHUNK, :2]
        v = x[i:i + CHUNK, 2:4] if x.shape[1] == 4 else np.zeros_like(p)
        gx = p[:, :1] + v[:, :1] * tau - data.a_xy[:, 0]
        gy = p[:, 1:2] + v[:, 1:2] * tau - data.a_xy[:, 1]
        t = (0.5 * np.log(gx * gx + gy * gy + data.h_m**2) - y_s) / s
        lp = -0.5 * ((b - t) ** 2 + 2.0 * log_ndtr(-t)) @ n
        if censored is not None and len(censored):
            cx = p[:, :1] + v[:, :1] * censored.tau_s - censored.a_xy[:, 0]
            cy = p[:, 1:2] + v[:, 1:2] * censored.tau_s - censored.a_xy[:, 1]
            tc = (0.5 * np.log(cx * cx + cy * cy + censored.h_m**2) - y_s) / s
            if censored.log_p is not None:
                from uavloc_gcs.estimation.evidence import burst_count_loglik

                lp = lp + burst_count_loglik(tc, censored.heard, censored.burst, censored.n_bursts,
                                             censored.log_p)[0].sum(axis=1)
            else:
                lp = lp + log_ndtr(tc) @ censored.frames
            e = censored.exposure
            if e is not None:  # the bursts nobody heard (evidence.Exposure)
                ex = p[:, :1] + v[:, :1] * e.tau_s - e.a_xy[:, 0]
                ey = p[:, 1:2] + v[:, 1:2] * e.tau_s - e.a_xy[:, 1]
                te = (0.5 * np.log(ex * ex + ey * ey + e.h_m**2) - y_s) / s
                lp = lp + e.source.loglik(te, gradient=False)[0]
        if x.shape[1] == 4:
            lp = np.where(np.hypot(v[:, 0], v[:, 1]) <= max_speed_m_s, lp, -np.inf)
        out[i:i + CHUNK] = lp
    return out


def burst_posterior_mean(data: Prepared, t_ref: float, candidates: list[tuple[np.ndarray, np.ndarray]],
                         max_speed_m_s: float, channel, censored, rng: np.random.Generator,
                         samples: int = 20_000, rounds: int = 3) -> tuple[np.ndarray, float]:
    """Posterior mean of the position at ``t_ref`` under the threshold (``max_speed_m_s`` 0: a
    static person, the state is the position alone) and the effective sample size of the last round.
    ``censored``: the estimator's :class:`uavloc_gcs.estimation.prepared.CensoredRows` (or None); the
    rows' ``tau_s`` must be relative to ``data.t_c`` as built, so they are shifted to ``t_ref`` here."""
    from uavloc_gcs.estimation.starts import principal_line

    dim = 4 if max_speed_m_s > 0 else 2
    if censored is not None:
        from dataclasses import replace

        censored = replace(censored, tau_s=censored.t_s - t_ref)
        if censored.exposure is not None:
            censored = replace(censored, exposure=replace(censored.exposure, tau_s=censored.exposure.t_s - t_ref))
    floor = np.diag([1.0, 1.0, 0.01, 0.01])[:dim, :dim]
    widen = np.diag([100.0, 100.0, 0.25, 0.25])[:dim, :dim]
    lines = [(c, d, t) for c, d, t in leg_lines(data)]
    center, direction, _ = principal_line(data)
    lines.append((center, direction, data.t_c))
    centers = []
    for state, cov in candidates:
        st, cv = np.asarray(state, float)[:dim], np.asarray(cov, float)[:dim, :dim]
        cv = np.where(np.isfinite(cv), cv, 0.0)
        centers.append((st, cv))
        for c, d, t_leg in lines:
            full = np.concatenate([state[:2], state[2:4] if dim == 4 else np.zeros(2)])
            centers.append((_reflect(full, t_ref, c, d, t_leg)[:dim], cv))
    wide = [(m, np.minimum(9.0 * (0.5 * (c + c.T) + floor) + widen, 1e6 * np.eye(dim) + 0 * c)) for m, c in centers]
    broad = np.diag([250.0**2, 250.0**2, max_speed_m_s**2, max_speed_m_s**2])[:dim, :dim]
    wide.append((np.concatenate([data.center, np.zeros(2)])[:dim], broad))
    return _population_mc(lambda x: burst_log_posterior(x, data, t_ref, max_speed_m_s, channel, censored), wide,
                          wide[:2] + [wide[-1]], np.asarray(candidates[0][0], float)[:2], floor, samples=samples,
                          rounds=rounds, rng=rng)
