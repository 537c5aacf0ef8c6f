"""The 95 % radius in the field world from the posterior itself, not its Laplace approximation.

A few bursts heard near the receiver threshold leave a posterior shaped like arcs of rings: the
Laplace Gaussian at a mode reaches far along the arcs' tangents where the posterior has bent
away, so its 95 % circle is several times too large (``bench localize --emission bursts``: the
radius 2-4x what 95 % coverage needs, coverage 1.00). Here the Laplace Gaussians of the candidates,
widened, are a proposal for self-normalised importance sampling of the constant-velocity
posterior (the truncated slots, the censored silences and the bursts nobody heard, the velocity
prior with the speed bound, the transmit-offset prior; the data deflated by the estimator's
inflation factor), and the radius is the weighted 95 % quantile of the distance from the estimate.
An estimated transmit offset is drawn with the state: first from its prior about the fit, then, in
the adaptation rounds, jointly with the position (louder is farther: the two are correlated, and
drawing them apart left the radius 9 % short, tests/uavloc_gcs/estimation/test_field_radius.py).
Fixed standard-normal draws make it a deterministic function of its inputs. Used only under a
receiver threshold.
"""

from __future__ import annotations

import numpy as np
from scipy.special import log_ndtr

from .evidence import burst_count_loglik

SAMPLES = 4096
PROPOSAL_SCALE = 2.0  # the proposal's standard deviations, in those of the Laplace Gaussian
MIN_ESS = 100.0  # below this the samples do not represent the posterior; the Laplace radius stands
ADAPTATIONS = 3  # refits of the proposal at most: the first always, the others below RESCUE_ESS
RESCUE_ESS = 300.0
_JITTER = (4.0, 4.0, 0.01, 0.01)  # added to the proposal's covariance [m^2, m^2, m^2/s^2, m^2/s^2]
_DRAWS = np.random.default_rng(20261125).standard_normal((SAMPLES, 5))
_DRAWS2 = np.random.default_rng(20261126).standard_normal((SAMPLES, 5))


def sampled_posterior(problem, modes: list[tuple[np.ndarray, np.ndarray]], t_ref_s: float, center_xy: np.ndarray,
                      factor: float, beta0: float = 0.0, prob: float = 0.95) -> tuple[float, np.ndarray, float] | None:
    """(radius [m] about ``center_xy`` holding ``prob`` of the posterior at ``t_ref_s``, the 4x4
    covariance of (x, y, vx, vy) there, the effective sample size), or None when the samples are
    too few to say (``MIN_ESS``).

    ``problem``: the estimator's :class:`.fit.Problem` (threshold set); ``modes``: (state (4,)
    at t_ref = position, velocity; covariance 4x4) of the candidates to propose from; ``beta0``
    the fitted transmit offset [nepers] when estimated."""
    moving = problem.moving
    dim = 4 if moving else 2
    parts = []
    for state, cov in modes:
        c = 0.5 * (np.asarray(cov, float) + np.asarray(cov, float).T)[:dim, :dim]
        c = PROPOSAL_SCALE**2 * c + np.diag(_JITTER[:dim])
        if not np.all(np.isfinite(c)):
            return None
        try:
            chol = np.linalg.cholesky(c)
        except np.linalg.LinAlgError:
            return None
        mean = np.asarray(state, float)[:dim]
        if problem.tx:  # the transmit offset drawn with the state, first from its prior about the fit
            mean = np.r_[mean, beta0]
            chol = np.block([[chol, np.zeros((dim, 1))], [np.zeros((1, dim)), np.full((1, 1), problem.tx_sigma_nepers)]])
        parts.append((mean, chol))
    x, w, ess = _weighted(problem, parts, 0, t_ref_s, factor, dim)
    if x is None:
        return None
    # adaptation: each component refitted to the weighted samples nearest it (the posterior's arcs
    # are narrower than the Laplace Gaussians, so the first round's weights are uneven); further
    # rounds only to rescue a posterior the samples still represent poorly (RESCUE_ESS)
    anchors = parts
    for k in range(ADAPTATIONS):
        if k > 0 and ess >= RESCUE_ESS:
            break
        refit = _refit(x, w, anchors, dim, problem.tx)
        if not refit:
            break
        x2, w2, ess2 = _weighted(problem, refit + parts[:1], SAMPLES, t_ref_s, factor, dim)
        if x2 is None or ess2 <= ess:
            break
        x, w, ess, anchors = x2, w2, ess2, refit
    if ess < MIN_ESS:
        return None
    dist = np.hypot(x[:, 0] - center_xy[0], x[:, 1] - center_xy[1])
    order = np.argsort(dist)
    cdf = np.cumsum(w[order])
    radius = float(dist[order][min(int(np.searchsorted(cdf, prob)), len(dist) - 1)])
    full = np.zeros((len(x), 4))
    full[:, :dim] = x[:, :dim]
    mean = w @ full
    dev = full - mean
    cov4 = (dev * w[:, None]).T @ dev
    return radius, cov4, ess


def _refit(x: np.ndarray, w: np.ndarray, anchors, dim: int, tx: bool) -> list:
    """Each anchor component's Gaussian refitted (widened 1.5x) to the weighted samples nearest its mean."""
    near = np.argmin(np.stack([np.linalg.norm(x[:, :2] - m[:2], axis=1) for m, _ in anchors]), axis=0)
    out = []
    for j in range(len(anchors)):
        wj = w * (near == j)
        if wj.sum() < 0.02:
            continue
        mj = wj @ x / wj.sum()
        dj = x - mj
        cj = 1.5**2 * (dj * wj[:, None]).T @ dj / wj.sum() + np.diag(_JITTER[:dim] + (1e-4,) * tx)
        try:
            out.append((mj, np.linalg.cholesky(cj)))
        except np.linalg.LinAlgError:
            pass
    return out


def _weighted(problem, parts, offset: int, t_ref_s: float, factor: float, dim: int):
    """Samples from the mixture of ``parts`` (mean, Cholesky factor; the state's ``dim`` entries,
    then the transmit offset [nepers] when estimated), their normalised importance weights and
    effective sample size; (None, None, 0) when every weight is zero."""
    n = SAMPLES // len(parts)
    width = len(parts[0][0])
    z = _DRAWS[: n * len(parts)] if offset == 0 else _DRAWS2[: n * len(parts)]
    x = np.vstack([m + z[i * n:(i + 1) * n, :width] @ l.T for i, (m, l) in enumerate(parts)])
    lq = np.logaddexp.reduce(np.stack([_mvn_logpdf(x, m, l) for m, l in parts]), axis=0)
    beta = x[:, dim] if problem.tx else np.zeros(len(x))
    lw = _log_posterior(problem, x[:, :dim], beta, t_ref_s, factor) - lq
    if not np.any(np.isfinite(lw)):
        return None, None, 0.0
    w = np.exp(lw - np.max(lw))
    w /= w.sum()
    return x, w, float(1.0 / np.sum(w * w))


def _mvn_logpdf(x: np.ndarray, mean: np.ndarray, chol: np.ndarray) -> np.ndarray:
    zz = np.linalg.solve(chol, (x - mean).T)
    return -0.5 * np.sum(zz * zz, axis=0) - float(np.sum(np.log(np.diag(chol))))


def _log_posterior(problem, x: np.ndarray, beta: np.ndarray, t_ref_s: float, factor: float) -> np.ndarray:
    """-0.5 x the estimator's cost for the pure constant-velocity (or static) model, per sample."""
    d, s, y_s = problem.data, problem.log_range_sigma, problem.threshold_y
    p = x[:, :2]
    v = x[:, 2:4] if x.shape[1] == 4 else np.zeros_like(p)
    tau = d.t_s - t_ref_s
    gx = p[:, :1] + v[:, :1] * tau - d.a_xy[:, 0]
    gy = p[:, 1:2] + v[:, 1:2] * tau - d.a_xy[:, 1]
    t = (0.5 * np.log(gx * gx + gy * gy + d.h_m**2) - beta[:, None] - y_s) / s
    b = np.minimum((d.y - y_s) / s, -1e-2)
    data = -0.5 * ((b - t) ** 2 + 2.0 * log_ndtr(-t)) @ d.n_samples
    c = problem.censored
    if c is not None and len(c):
        ctau = c.t_s - t_ref_s
        cx = p[:, :1] + v[:, :1] * ctau - c.a_xy[:, 0]
        cy = p[:, 1:2] + v[:, 1:2] * ctau - c.a_xy[:, 1]
        tc = (0.5 * np.log(cx * cx + cy * cy + c.h_m**2) - beta[:, None] - y_s) / s
        if c.log_p is not None:
            data = data + burst_count_loglik(tc, c.heard, c.burst, c.n_bursts, c.log_p)[0].sum(axis=1)
        else:
            data = data + log_ndtr(tc) @ c.frames
        e = c.exposure
        if e is not None:  # the bursts nobody heard (evidence.Exposure)
            etau = e.t_s - t_ref_s
            ex = p[:, :1] + v[:, :1] * etau - e.a_xy[:, 0]
            ey = p[:, 1:2] + v[:, 1:2] * etau - e.a_xy[:, 1]
            te = (0.5 * np.log(ex * ex + ey * ey + e.h_m**2) - beta[:, None] - y_s) / s
            data = data + e.source.loglik(te, gradient=False)[0]
    lp = data / factor
    if x.shape[1] == 4:
        lp = lp - 0.5 * np.sum(v * v, axis=1) / problem.sigma_v**2
        lp = np.where(np.hypot(v[:, 0], v[:, 1]) <= problem.max_speed_m_s, lp, -np.inf)
    if problem.tx:
        lp = lp - 0.5 * (beta / problem.tx_sigma_nepers) ** 2
    return lp
