"""The local optima of one emitter's fit and their Gaussians (the search half of :mod:`.estimate`).

From the starts :mod:`.estimate` gives, the distinct modes of the MAP fit (:func:`_distinct_modes`),
each mode's mirror across the legs that heard it -- on the ground plane, and on the slant for a
single pass (:func:`_mirror_starts`, :func:`_slant_mirrors`, :func:`_mirror_one_pass`) -- the modes
refitted inside the hearing constraints (:func:`_refit_bounded`), the power test against a phone
louder than any (:func:`_power_contradicted`), and each mode's Laplace covariance with the
constraints' information capped and a floor on what the exposure adds (:func:`_laplace`). The
module switches below are read at call time: ``uavloc bench looks`` variants set them.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..errors import EstimationError
from .fit import Problem
from .starts import leg_lines, mirror_point, principal_line

PROBE_NFEV = 6
POWER_TEST_CHI2 = 10.83  # chi^2_1 quantile at 0.999
PROBE_MERGE_M = 3.0
# Whether binding hearing constraints add (deflated) information to the Laplace covariance.
# Measured (bench localize --evidence all, 60-200 runs): with them the radius follows the smaller
# error of CV people (two parallel / crossing r95/RMSE 1.8, coverage 0.98-1.00) but random-waypoint
# people who turned lose coverage in the isolated benchmark (small area, lanes + look: 0.81-0.83;
# 0.88 without them). In missions (the policy's silences, paper scenario, 20 walkers, 12 runs)
# with them: 236/240 located, 95.8 % inside their radius, 172 s; without them the small-scenario
# mission test no longer located a static person and runs were slower (4 runs: 189 vs 175 s).
BOUNDS_IN_COVARIANCE = True
# At most this factor of shrinkage, in any direction, of a candidate's standard deviation by the
# hearing constraints (see _capped); None: no cap. bench looks variant "bound-cap" (1.5): missions
# 3.5 s slower, 0.983 inside instead of 0.968 (docs/measurements/paper-comparison.md), so off.
BOUND_SHRINK_MAX: float | None = None
# Whether a mode the hearing constraints moved gets its own mirror starts (bench looks variant
# "no-bounded-mirror" switches it off; measured in docs/measurements/paper-comparison.md).
MIRROR_AFTER_BOUNDS = True
MIRROR_PRIOR_SKIP = 12.0  # extra maneuver-prior cost (chi^2 units) beyond which a one-pass mirror is not tried


def _distinct_modes(problem: Problem, starts: list[np.ndarray], mirrors: bool = True) -> list[tuple[np.ndarray, float]]:
    """Local optima from all starts, best first, duplicates (< 1 m apart) removed.

    The solution from the first start is also mirrored across every straight leg (person and
    velocity reflected at the leg's time): a person close to one leg of several has a local
    mirror there that the global mirror start does not reach, and a person near a single track
    has one just across it (``mirrors=False``: not; a turn model started from the main model's
    modes has those mirrors among its starts already). Later starts first get a few
    iterations; one that is by then next to a known optimum is dropped (it was converging there).
    """
    modes = [problem.fit(starts[0])]
    _fit_more(problem, modes, list(starts[1:]) + (_mirror_starts(problem, modes[0][0]) if mirrors else []))
    out = _merged(modes)
    if not out:
        raise EstimationError("the fit diverged from every start point")
    return out


def _mirror_starts(problem: Problem, theta: np.ndarray) -> list[np.ndarray]:
    """``theta`` mirrored across every straight leg (or the slots' principal line) and, with the
    maneuver model, one pass alone mirrored where that needs no many-sigma maneuver."""
    legs = leg_lines(problem.data)
    if not legs:
        center, direction, _ = principal_line(problem.data)
        legs = [(center, direction, problem.data.t_c)]
    out = [_mirror_state(problem, theta, c, d, t - problem.data.t_c) for c, d, t in legs]
    if problem.data.ground is not None:  # over terrain the mirror's ground differs: see _slant_mirrors
        out += [m for c, d, t in legs for m in _slant_mirrors(problem, theta, c, d, t - problem.data.t_c)]
    if problem.passes is not None:  # maneuver model: also mirror one pass alone, the others kept in place
        base = problem.offset_prior_cost(theta)
        for c, d, t in legs:
            s = _mirror_one_pass(problem, theta, c, d, t)
            # a mirror that needs a many-sigma maneuver cannot hold posterior mass: not worth a fit
            if problem.offset_prior_cost(s) - base < MIRROR_PRIOR_SKIP:
                out.append(s)
    return out


def _fit_more(problem: Problem, modes: list[tuple[np.ndarray, float]], starts: list[np.ndarray]) -> None:
    """Fit each start a few iterations; one that is by then next to a known mode is dropped (it
    was converging there), the others are fitted to the end and appended to ``modes``."""
    for s in starts:
        theta, cost = problem.fit(s, max_nfev=PROBE_NFEV)
        if any(np.linalg.norm(theta[:2] - m[0][:2]) < PROBE_MERGE_M for m in modes):
            continue
        modes.append(problem.fit(theta))


def _merged(modes: list[tuple[np.ndarray, float]]) -> list[tuple[np.ndarray, float]]:
    """Finite modes, best first, duplicates (< 1 m apart) removed."""
    out: list[tuple[np.ndarray, float]] = []
    for theta, cost in sorted(modes, key=lambda f: f[1]):
        if np.all(np.isfinite(theta)) and all(np.linalg.norm(theta[:2] - m[0][:2]) > 1.0 for m in out):
            out.append((theta, cost))
    return out


def _refit_bounded(problem: Problem, modes: list[tuple[np.ndarray, float]]) -> list[tuple[np.ndarray, float]]:
    """The modes refitted where the hearing constraints bind (a mode that needs the person out of
    reach of a slot heard, or within reach of a silence, moves or loses its posterior mass), best
    first, duplicates (< 1 m apart) merged."""
    out = []
    moved = False
    for theta, _ in modes:
        r = problem.residuals(theta)
        if np.any(r[len(r) - len(problem.bounds):] > 0):
            out.append(problem.fit(theta))
            moved = True
        else:
            out.append((theta, float(r @ r)))
    # a mode the constraints moved (e.g. off the track, where an unconstrained fit of an edge
    # pass can sit) has a mirror of its own that no unconstrained start reached
    if moved and MIRROR_AFTER_BOUNDS:
        _fit_more(problem, out, _mirror_starts(problem, min(out, key=lambda f: f[1])[0]))
    return _merged(out) or sorted(out, key=lambda f: f[1])[:1]


def _power_contradicted(problem: Problem, best: tuple[np.ndarray, float], factor: float) -> bool:
    """Likelihood-ratio test of the nominal transmit power: refit with the offset free (its prior
    included) and compare; the (deflated) statistic against chi^2_1 at 1e-3."""
    free = replace(problem, tx=True)
    _, cost = free.fit(np.insert(best[0], problem.base_size, 0.0))
    return (best[1] - cost) / factor > POWER_TEST_CHI2


def _mirror_state(problem: Problem, theta: np.ndarray, center, direction, tau: float) -> np.ndarray:
    out = theta.copy()
    v = theta[2:4] if problem.moving else np.zeros(2)
    p_leg = mirror_point(theta[:2] + v * tau, center, direction)
    v_m = mirror_point(v, np.zeros(2), direction)
    out[:2] = p_leg - v_m * tau
    if problem.moving:
        out[2:4] = v_m
    b = problem.base_size
    for k in range(b, problem.size, 2):  # the pass offsets are vectors: reflect them too
        out[k: k + 2] = mirror_point(theta[k: k + 2], np.zeros(2), direction)
    return out


def _slant_mirrors(problem: Problem, theta: np.ndarray, center, direction, tau: float) -> list[np.ndarray]:
    """Over terrain: the mirror across a leg where the ground there puts the person at the same
    slant range from the leg as ``theta`` does (the plain reflection keeps the horizontal offset,
    and on a slope its ground is tens of metres higher or lower). Along the perpendicular on the
    mirror side, every crossing of that slant range (at most two, nearest first) gives a start:
    a fit from the plain reflection can descend the wrong way, as the slant range along a slope
    first falls and then rises (the mountains demo located a walker 114 m from the truth, the
    truth's side never fitted)."""
    d = problem.data
    v = theta[2:4] if problem.moving else np.zeros(2)
    q = theta[:2] + v * tau
    normal = np.array([-direction[1], direction[0]])
    lateral = float(np.dot(q - center, normal))
    foot = q - lateral * normal
    k = int(np.argmin(np.abs(d.tau_s - tau)))
    t_k = d.t_s[k: k + 1]
    rise_q, _ = d.ground(t_k, q[None, :])
    target = float(np.sum((q - d.a_xy[k]) ** 2) + (d.h_m[k] - rise_q[0]) ** 2)
    side = -1.0 if lateral > 0 else 1.0
    offsets = side * np.arange(1.0, math.sqrt(target) + 2.0, 2.0)
    pts = foot + offsets[:, None] * normal
    rise, _ = d.ground(np.full(len(pts), t_k[0]), pts)
    excess = np.sum((pts - d.a_xy[k]) ** 2, axis=1) + (d.h_m[k] - rise) ** 2 - target
    cross = np.flatnonzero(np.sign(excess[1:]) != np.sign(excess[:-1]))[:2]
    plain = _mirror_state(problem, theta, center, direction, tau)
    p_plain = mirror_point(q, center, direction)
    out = []
    for i in cross:
        f = excess[i] / (excess[i] - excess[i + 1])
        at = pts[i] + f * (pts[i + 1] - pts[i])
        start = plain.copy()
        start[:2] = plain[:2] + (at - p_plain)
        out.append(start)
    return out


def _mirror_one_pass(problem: Problem, theta: np.ndarray, center, direction, t_leg_s: float) -> np.ndarray:
    """Mirror only the pass flown at t_leg_s across its leg; where the other passes put the person
    stays put (their offsets absorb the change). With maneuver offsets the old passes are loosely
    tied to the current pass, so the current pass's own mirror is a separate local optimum."""
    d, ps, b = problem.data, problem.passes, problem.base_size
    p, v = theta[:2], theta[2:4]
    e = problem.offsets_end
    off = theta[b:e].reshape(-1, 2)
    tau = np.array([np.mean(d.tau_s[ps.index == j]) for j in range(ps.count)])
    # the turn's shift at each offset pass (kept as it is)
    shift = np.outer(problem.turn_lead(tau + d.t_c), theta[e:]) if problem.turn_at_s is not None else 0.0 * off
    where = p + np.outer(tau, v) + off + shift  # the person at each offset pass
    j = int(ps.index[int(np.argmin(np.abs(d.t_s - t_leg_s)))])
    out = theta.copy()
    if j >= 0:
        out[b + 2 * j: b + 2 * j + 2] = mirror_point(where[j], center, direction) - p - v * tau[j] - shift[j]
        return out
    # the current pass: its position reflected, the velocity kept (the older passes, through their
    # offsets, say where the person came from, not which way the mirror image walks)
    tau_leg = t_leg_s - d.t_c
    out[:2] = mirror_point(p + v * tau_leg, center, direction) - v * tau_leg
    out[b:e] = (where - out[:2] - np.outer(tau, out[2:4]) - shift).ravel()
    return out


def _laplace(problem: Problem, theta: np.ndarray, cost: float, factor: float) -> tuple[np.ndarray, float]:
    """Posterior covariance (deflated data information) and log mass of a mode."""
    info = problem.data_information(theta) / factor + problem.prior_information(theta)
    if problem.bounds is not None and BOUNDS_IN_COVARIANCE:
        jb = problem.jacobian(theta)[-len(problem.bounds):]
        extra = jb.T @ jb / factor  # the same deflation: a misfit state makes them binding
        if BOUND_SHRINK_MAX is not None:
            extra = _capped(info, extra, BOUND_SHRINK_MAX)
        info = info + extra
    if problem.censored is not None and problem.censored.exposure is not None:
        info = _with_exposure(info, problem.exposure_information(theta) / factor)
    cov = _inverse(info)
    data_cost = float(np.sum(problem.data_residuals(theta) ** 2))
    prior_cost = cost - data_cost
    sign, logdet = np.linalg.slogdet(cov)
    return cov, -0.5 * (data_cost / factor + prior_cost) + 0.5 * (logdet if sign > 0 else -np.inf)


def _capped(info: np.ndarray, extra: np.ndarray, shrink: float) -> np.ndarray:
    """``extra`` information limited so that, in every direction, it shrinks the standard
    deviation given by ``info`` by at most the factor ``shrink``: the binding rows are hundreds
    of near-copies of one one-sided constraint, and a one-sided constraint truncates the
    posterior, it does not make it as narrow as their count would say."""
    w, v = np.linalg.eigh(0.5 * (info + info.T))
    if np.min(w) <= 0:
        return extra
    half = v @ np.diag(1.0 / np.sqrt(w)) @ v.T  # info^(-1/2)
    d, u = np.linalg.eigh(half @ extra @ half)
    d = np.clip(d, 0.0, shrink**2 - 1.0)
    root = v @ np.diag(np.sqrt(w)) @ v.T
    return root @ (u @ np.diag(d) @ u.T) @ root


# The exposure's curvature may widen the posterior (it is not positive definite), but by at most
# this factor of the information in any direction (the standard deviation at most doubles).
EXPOSURE_FLOOR = 0.25


def _with_exposure(info: np.ndarray, h: np.ndarray, floor: float = EXPOSURE_FLOOR) -> np.ndarray:
    """info + h with h (symmetric, indefinite) limited so the sum stays >= ``floor`` x info."""
    w, v = np.linalg.eigh(0.5 * (info + info.T))
    w = np.maximum(w, 1e-12 * max(float(w.max()), 1e-300))
    white = v / np.sqrt(w)  # white.T @ info @ white = I
    m = white.T @ (0.5 * (h + h.T)) @ white
    mw, mv = np.linalg.eigh(0.5 * (m + m.T))
    root = v * np.sqrt(w)  # info = root @ root.T
    return root @ (np.eye(len(w)) + (mv * np.maximum(mw, floor - 1.0)) @ mv.T) @ root.T


def _inverse(info: np.ndarray) -> np.ndarray:
    info = 0.5 * (info + info.T)
    try:
        return np.linalg.inv(info)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(info)


