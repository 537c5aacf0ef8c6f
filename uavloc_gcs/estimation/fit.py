"""The numerical core: the MAP fit of one emitter's slots.

Its data made ready are :mod:`.prepared`'s, where it starts :mod:`.starts`'.

Objective (negative log posterior x 2) over theta = (x, y[, vx, vy][, beta]) at time t_c:

    sum_i w_i (y_i - ln d_i(theta) + beta)^2           data, w_i = n_i / s^2
  + |v|^2 / sigma_v^2                                   velocity prior, sigma_v = 0.6 v_max per axis
  + ((|v| - v_max)+ / 0.05 m/s)^2                       the speed bound (overshoot ~<= 0.05 m/s)
  + (beta / sigma_beta)^2                               transmit-offset prior (when estimated)
  + |p - c|^2 / (10 km)^2                               a vague position prior: keeps degenerate
                                                        geometry (a hovering vehicle) finite

Under a receiver threshold (the field world: ``ChannelModel.sensitivity_dbm``; y_S its log-range
form, z_i = (ln d_i - beta - y_S) / s) the heard frames are a normal truncated at the threshold,
and vehicles that listened while the phone sent and heard nothing are censored observations:

  - sum_i 2 n_i (-ln Phi(-z_i))                         truncation: each heard frame's density is
                                                        phi / P(heard), P(heard) = Phi(-z_i)
  + sum_j 2 k_j (-ln Phi(z_j))                          censoring: P(none of k_j frames heard)

With a frames prior the censored rows become every listening vehicle's hearing counts per burst
(``evidence.burst_count_loglik``), and with a burst-rate prior the bursts nobody heard add
  + 2 (ln F(0) - ln F(A))                               exposure: F(A) = E_lam[lam^N exp(-lam A)],
                                                        A = the time a burst would have been heard
(``evidence.exposure_loglik``; one residual, its square that, and in the Laplace covariance its
curvature by differences, which may widen it: ``modes.EXPOSURE_FLOOR``).

The truncation lowers the cost where hearing is unlikely, so it cannot be a residual of its own:
per slot it joins the Gaussian term into one convex function of z_i written as a signed root
(``model.truncated_slot_residual``); each censored row is sqrt(-2 k_j ln Phi(z_j))
(``model.log_probability_residual``); both with analytic Jacobians.

sigma_v = 0.6 v_max per axis is a measured compromise. The second moment of a velocity uniform over
the disk |v| <= v_max gives 0.5 v_max, but that Gaussian shrinks fast walkers too much (the disk has
most of its mass near the rim): coverage of the 95 % radius for two parallel legs was 0.91 in
``uavloc bench localize``. 1/sqrt(2) (E|v|^2 = v_max^2) gave 0.94 but lets a static person's
velocity wander, so follow-up looks converge more slowly (a 3-person mission of
tests/sim_link/experiments/test_missionsim.py no longer located everyone). 0.6 gives 0.93-0.95 and keeps that.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import leastsq

from .evidence import Bounds, burst_count_loglik
from .maneuver import Passes, offset_jacobian
from .model import (
    censored_curvature,
    log_probability_residual,
    log_range_jacobian,
    mills_ratio,
    truncated_information_factor,
    truncated_mle,
    truncated_slot_residual,
)
from .prepared import CensoredRows, Prepared

SPEED_BOUND_SOFTNESS_M_S = 0.05
VELOCITY_PRIOR_FRACTION = 0.6  # sigma_v / v_max per axis (see the module docstring)
POSITION_PRIOR_SIGMA_M = 1.0e4


@dataclass(frozen=True)
class Problem:
    data: Prepared
    moving: bool
    tx: bool
    max_speed_m_s: float
    tx_sigma_nepers: float
    passes: Passes | None = None  # maneuver offsets per old pass (see .maneuver); None = pure CV
    bounds: Bounds | None = None  # where the phone was heard / not heard (see .evidence); None = unused
    offset_tail: float | None = None  # the offsets' prior is multivariate t with these dof; None = Gaussian
    # One turn at this time [s] (None: none): before it the person walked with velocity v - u; the
    # velocity change u (ux, uy) follows the pass offsets, with a Gaussian prior of turn_sigma_m_s
    # per axis (see estimate.TURN_JUMP).
    turn_at_s: float | None = None
    turn_sigma_m_s: float = 1.0
    # The receiver threshold in log-range form (ChannelModel.threshold_log_range; None: the paper's
    # exact gate, no truncation), the per-sample log-range sigma s it is measured in, and the
    # censored observations (silences within heard bursts; they need the threshold).
    threshold_y: float | None = None
    log_range_sigma: float = 1.0
    censored: CensoredRows | None = None

    @property
    def base_size(self) -> int:
        """Size of (x, y[, vx, vy][, beta]); the pass offsets (dx_1, dy_1, ...) follow."""
        return 2 + 2 * self.moving + self.tx

    @property
    def offsets_end(self) -> int:
        """End of the pass offsets in theta; the turn's velocity change (when any) follows."""
        return self.base_size + (2 * self.passes.count if self.passes is not None else 0)

    @property
    def size(self) -> int:
        return self.offsets_end + (2 if self.turn_at_s is not None else 0)

    def turn_lead(self, t_s: np.ndarray) -> np.ndarray:
        """How long before the turn each time is (0 after it): the turn's shift there is lead * u."""
        return np.maximum(self.turn_at_s - np.asarray(t_s, float), 0.0)

    @property
    def beta_index(self) -> int:
        return self.base_size - 1

    @property
    def sigma_v(self) -> float:
        return max(self.max_speed_m_s, 1e-3) * VELOCITY_PRIOR_FRACTION

    def _geometry(self, theta: np.ndarray):
        """Offsets g (N, 2) person - vehicle and squared 3-D distances (N,); the last evaluation is
        cached (MINPACK asks for the residuals and the Jacobian at the same point). Over terrain
        (``data.ground``) g is half the gradient of d^2 with respect to the person's position,
        which is all the Jacobian uses it for."""
        key = theta.tobytes()
        cache = self.__dict__.get("_cache")
        if cache is not None and cache[0] == key:
            return cache[1], cache[2]
        d = self.data
        pos = np.outer(d.tau_s, theta[2:4]) + theta[:2] if self.moving else np.broadcast_to(theta[:2], d.a_xy.shape)
        if self.passes is not None:  # index -1 (no offset) picks the appended zero row
            off = np.vstack([theta[self.base_size:self.offsets_end].reshape(-1, 2), np.zeros((1, 2))])
            pos = pos + off[self.passes.index]
        if self.turn_at_s is not None:
            pos = pos + np.outer(self.turn_lead(d.t_s), theta[self.offsets_end:])
        g = pos - d.a_xy
        if d.ground is None:
            d2 = g[:, 0] * g[:, 0] + g[:, 1] * g[:, 1] + d.h_m * d.h_m
        else:  # the person on the ground where they are: d(d^2)/d(position) = 2 (g - h grad)
            rise, grad = d.ground(d.t_s, pos)
            h = d.h_m - rise
            d2 = g[:, 0] * g[:, 0] + g[:, 1] * g[:, 1] + h * h
            g = g - h[:, None] * grad  # what the Jacobian takes as the offset
        object.__setattr__(self, "_cache", (key, g, d2))
        return g, d2

    def _data_jacobian(self, theta: np.ndarray) -> np.ndarray:
        d = self.data
        g, d2 = self._geometry(theta)
        return self._rows_jacobian(g, d2, d.tau_s, d.t_s, self.passes.index if self.passes is not None else None)

    def _rows_jacobian(self, g, d2, tau_s, t_s, pass_index) -> np.ndarray:
        """d(ln d - beta)/d theta (N, P) of rows at offsets g, squared distances d2, times t_s."""
        jac = log_range_jacobian(g, d2, tau_s, self.moving, self.tx)
        if self.passes is not None:
            jac = np.hstack([jac, offset_jacobian(g, d2, replace(self.passes, index=pass_index))])
        if self.turn_at_s is not None:
            lead = self.turn_lead(t_s) / d2
            jac = np.hstack([jac, np.column_stack([g[:, 0] * lead, g[:, 1] * lead])])
        return jac

    def _censored_geometry(self, theta: np.ndarray, rows=None):
        """Offsets (K, 2) and squared 3-D distances (K,) of the censored rows (or of ``rows``, the
        exposure's)."""
        c = self.censored if rows is None else rows
        pos = np.outer(c.tau_s, theta[2:4]) + theta[:2] if self.moving else np.broadcast_to(theta[:2], c.a_xy.shape)
        if self.passes is not None:
            off = np.vstack([theta[self.base_size:self.offsets_end].reshape(-1, 2), np.zeros((1, 2))])
            pos = pos + off[c.pass_index]
        if self.turn_at_s is not None:
            pos = pos + np.outer(self.turn_lead(c.t_s), theta[self.offsets_end:])
        g = pos - c.a_xy
        return g, g[:, 0] * g[:, 0] + g[:, 1] * g[:, 1] + c.h_m * c.h_m

    def _z(self, d2: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """(S - mu) / sigma = (ln d - beta - y_S) / s of rows with squared distances d2."""
        beta = theta[self.beta_index] if self.tx else 0.0
        return (0.5 * np.log(d2) - beta - self.threshold_y) / self.log_range_sigma

    @property
    def data_rows(self) -> int:
        """Residual rows of the data: one per slot, then the censored observations."""
        return len(self.data.t_s) + (self.censored.residual_rows if self.censored is not None else 0)

    def _truncation(self) -> tuple[np.ndarray, np.ndarray]:
        """Per slot the standardized heard mean b and its ML t* (``model.truncated_mle``), cached."""
        cache = self.__dict__.get("_trunc")
        if cache is None:
            b = (self.data.y - self.threshold_y) / self.log_range_sigma
            cache = (b, truncated_mle(b))
            object.__setattr__(self, "_trunc", cache)
        return cache

    def _slot_residuals(self, theta: np.ndarray) -> np.ndarray:
        d = self.data
        _, d2 = self._geometry(theta)
        if self.threshold_y is None:
            beta = theta[self.beta_index] if self.tx else 0.0
            return np.sqrt(d.w) * (d.y - 0.5 * np.log(d2) + beta)
        return self._truncated(theta)[0]

    def _counts(self, theta: np.ndarray):
        """The hearing counts' ln P_b and d ln P_b / dz at theta (the last evaluation cached: MINPACK
        asks for the residuals and the Jacobian at the same point)."""
        key = theta.tobytes()
        cache = self.__dict__.get("_counts_cache")
        if cache is not None and cache[0] == key:
            return cache[1]
        c = self.censored
        _, d2c = self._censored_geometry(theta)
        out = burst_count_loglik(self._z(d2c, theta), c.heard, c.burst, c.n_bursts, c.log_p)
        object.__setattr__(self, "_counts_cache", (key, out))
        return out

    def _exposure(self, theta: np.ndarray):
        """The exposure's ln F, d ln F / dz per row and ln F(0) at theta (the last evaluation cached)."""
        key = theta.tobytes()
        cache = self.__dict__.get("_exposure_cache")
        if cache is not None and cache[0] == key:
            return cache[1]
        e = self.censored.exposure
        _, d2 = self._censored_geometry(theta, e)
        logf, dz, logf0 = e.source.loglik(self._z(d2, theta))
        out = (float(logf[0]), dz[0], logf0)
        object.__setattr__(self, "_exposure_cache", (key, out))
        return out

    def _exposure_gradient(self, theta: np.ndarray) -> np.ndarray:
        """d ln F / d theta (P,)."""
        e = self.censored.exposure
        g, d2 = self._censored_geometry(theta, e)
        _, dz, _ = self._exposure(theta)
        return (dz / self.log_range_sigma) @ self._rows_jacobian(g, d2, e.tau_s, e.t_s, e.pass_index)

    def exposure_information(self, theta: np.ndarray) -> np.ndarray:
        """The exposure term's curvature -d2 ln F / d theta2 (P, P), by central differences of its
        gradient. Not positive definite in general: away from where the vehicles listened most the
        term widens the posterior, which is the point."""
        p = self.size
        step = np.full(p, 0.5)
        if self.moving:
            step[2:4] = 0.005
        if self.tx:
            step[self.beta_index] = 0.005
        h = np.zeros((p, p))
        for i in range(p):
            d = np.zeros(p)
            d[i] = step[i]
            h[i] = (self._exposure_gradient(theta + d) - self._exposure_gradient(theta - d)) / (2.0 * step[i])
        return -0.5 * (h + h.T)

    def _truncated(self, theta: np.ndarray):
        """The slots' signed roots and their derivatives at theta (the last evaluation cached)."""
        key = theta.tobytes()
        cache = self.__dict__.get("_trunc_cache")
        if cache is not None and cache[0] == key:
            return cache[1]
        _, d2 = self._geometry(theta)
        b, t_star = self._truncation()
        out = truncated_slot_residual(self._z(d2, theta), b, t_star, self.data.n_samples)
        object.__setattr__(self, "_trunc_cache", (key, out))
        return out

    def _censored_residuals(self, theta: np.ndarray) -> list:
        c = self.censored
        if c is None:
            return []
        if c.log_p is not None:
            logp, _ = self._counts(theta)
            out = [np.sqrt(np.maximum(-2.0 * logp[0], 0.0))]
            if c.exposure is not None:
                logf, _, logf0 = self._exposure(theta)
                out.append([math.sqrt(max(2.0 * (logf0 - logf), 0.0))])
            return out
        _, d2c = self._censored_geometry(theta)
        return [log_probability_residual(self._z(d2c, theta), c.frames)[0]]

    def _slot_jacobian(self, theta: np.ndarray) -> np.ndarray:
        d = self.data
        if self.threshold_y is None:
            return -np.sqrt(d.w)[:, None] * self._data_jacobian(theta)
        _, dr = self._truncated(theta)
        return (dr / self.log_range_sigma)[:, None] * self._data_jacobian(theta)

    def _censored_jacobian(self, theta: np.ndarray) -> list:
        out = []
        s = self.log_range_sigma
        if self.censored is not None and self.censored.log_p is not None:
            c = self.censored
            g, d2c = self._censored_geometry(theta)
            logp, dz = self._counts(theta)
            r = np.sqrt(np.maximum(-2.0 * logp[0], 0.0))
            grad = (dz[0] / s)[:, None] * self._rows_jacobian(g, d2c, c.tau_s, c.t_s, c.pass_index)
            per_burst = np.zeros((c.n_bursts, grad.shape[1]))
            np.add.at(per_burst, c.burst, grad)
            out.append(-per_burst / np.maximum(r, 1e-12)[:, None])
            if c.exposure is not None:
                logf, _, logf0 = self._exposure(theta)
                re = math.sqrt(max(2.0 * (logf0 - logf), 0.0))
                out.append(-self._exposure_gradient(theta)[None, :] / max(re, 1e-12))
        elif self.censored is not None:
            c = self.censored
            g, d2c = self._censored_geometry(theta)
            _, dr = log_probability_residual(self._z(d2c, theta), c.frames)
            out.append((dr / s)[:, None] * self._rows_jacobian(g, d2c, c.tau_s, c.t_s, c.pass_index))
        return out

    def residuals(self, theta: np.ndarray) -> np.ndarray:
        beta = theta[self.beta_index] if self.tx else 0.0
        parts = [self._slot_residuals(theta)] + self._censored_residuals(theta)
        if self.moving:
            v = theta[2:4]
            speed = math.hypot(v[0], v[1])
            parts += [v / self.sigma_v, [max(speed - self.max_speed_m_s, 0.0) / SPEED_BOUND_SOFTNESS_M_S]]
        if self.tx:
            parts.append([beta / self.tx_sigma_nepers])
        parts.append((theta[:2] - self.data.center) / POSITION_PRIOR_SIGMA_M)
        if self.passes is not None:
            e = self._whitened_offsets(theta)
            parts.append(e * self._tail(float(e @ e))[0] if self.offset_tail is not None else e)
        if self.turn_at_s is not None:
            parts.append(theta[self.offsets_end:] / self.turn_sigma_m_s)
        if self.bounds is not None:
            parts.append(self.bounds.residuals(theta[:2], theta[2:4] if self.moving else None, self._bound_shift(theta)))
        return np.concatenate([np.asarray(p, float).ravel() for p in parts])

    def jacobian(self, theta: np.ndarray) -> np.ndarray:
        d = self.data
        rows = [self._slot_jacobian(theta)] + self._censored_jacobian(theta)
        p = self.size
        if self.moving:
            prior = np.zeros((3, p))
            prior[0, 2] = prior[1, 3] = 1.0 / self.sigma_v
            v = theta[2:4]
            speed = math.hypot(v[0], v[1])
            if speed > self.max_speed_m_s:
                prior[2, 2:4] = v / speed / SPEED_BOUND_SOFTNESS_M_S
            rows.append(prior)
        if self.tx:
            row = np.zeros((1, p))
            row[0, self.beta_index] = 1.0 / self.tx_sigma_nepers
            rows.append(row)
        pos = np.zeros((2, p))
        pos[0, 0] = pos[1, 1] = 1.0 / POSITION_PRIOR_SIGMA_M
        rows.append(pos)
        if self.passes is not None:
            m, b = self.passes.count, self.base_size
            off = np.zeros((2 * m, p))
            off[:m, b:self.offsets_end:2] = self.passes.whiten
            off[m:, b + 1:self.offsets_end:2] = self.passes.whiten
            if self.offset_tail is not None:  # d(f(s) e) = f de + 2 f'(s) e e^T de
                e = self._whitened_offsets(theta)
                f, df = self._tail(float(e @ e))
                off = f * off + 2.0 * df * np.outer(e, e @ off)
            rows.append(off)
        if self.turn_at_s is not None:
            turn = np.zeros((2, p))
            turn[0, self.offsets_end] = turn[1, self.offsets_end + 1] = 1.0 / self.turn_sigma_m_s
            rows.append(turn)
        if self.bounds is not None:
            jb = self.bounds.jacobian(theta[:2], theta[2:4] if self.moving else None, self._bound_shift(theta))
            row = np.zeros((len(self.bounds), p))
            row[:, :2] = jb[:, :2]
            if self.moving:
                row[:, 2:4] = jb[:, 2:4]
            if self.passes is not None:
                k = np.flatnonzero(self.bounds.pass_index >= 0)
                col = self.base_size + 2 * self.bounds.pass_index[k]
                row[k, col], row[k, col + 1] = jb[k, 0], jb[k, 1]
            if self.turn_at_s is not None:
                lead = self._bound_lead()
                row[:, self.offsets_end] = jb[:, 0] * lead
                row[:, self.offsets_end + 1] = jb[:, 1] * lead
            rows.append(row)
        return np.vstack(rows)

    def _bound_shift(self, theta: np.ndarray) -> np.ndarray | None:
        """The pass offsets (and the turn's shift) of the bound rows (K, 2); None without maneuver passes."""
        if self.passes is None:
            return None
        off = np.vstack([theta[self.base_size:self.offsets_end].reshape(-1, 2), np.zeros((1, 2))])
        shift = off[self.bounds.pass_index]
        if self.turn_at_s is not None:
            shift = shift + np.outer(self._bound_lead(), theta[self.offsets_end:])
        return shift

    def _bound_lead(self) -> np.ndarray:
        return self.turn_lead(self.bounds.tau_s + self.data.t_c)

    def _whitened_offsets(self, theta: np.ndarray) -> np.ndarray:
        """The pass offsets whitened by their Gaussian prior, x axis then y axis (2m,)."""
        off = theta[self.base_size:self.offsets_end].reshape(-1, 2)
        return np.concatenate([self.passes.whiten @ off[:, 0], self.passes.whiten @ off[:, 1]])

    def _tail_c(self) -> float:
        return self.offset_tail + 2.0 * self.passes.count

    def _tail(self, s: float) -> tuple[float, float]:
        """f(s) and f'(s) with f(s)^2 s = c ln(1 + s / c), c = dof + 2m: the multivariate t's
        -2 ln density of the whitened offsets e (s = |e|^2), scaled to the Gaussian's curvature
        at e = 0, as a residual f(s) e for least squares."""
        c = self._tail_c()
        if s < 1e-9 * c:
            return 1.0 - s / (4.0 * c), -1.0 / (4.0 * c)
        rho = c * math.log1p(s / c)
        f = math.sqrt(rho / s)
        dg = (c / (c + s) * s - rho) / (s * s)
        return f, dg / (2.0 * f)

    def offset_prior_cost(self, theta: np.ndarray) -> float:
        """-2 ln prior density of the pass offsets (without its normalisation)."""
        e = self._whitened_offsets(theta)
        s = float(e @ e)
        if self.offset_tail is None:
            return s
        c = self._tail_c()
        return c * math.log1p(s / c)

    def prior_information(self, theta: np.ndarray | None = None) -> np.ndarray:
        """The priors' information; with a t-distributed offset prior its Gaussian information
        scaled by the weight c / (c + s) at ``theta`` (the scale mixture's expected precision
        given the offsets: positive where the t's own curvature is not, far in its tail)."""
        j = np.zeros((self.size, self.size))
        j[0, 0] = j[1, 1] = POSITION_PRIOR_SIGMA_M**-2
        if self.moving:
            j[2, 2] = j[3, 3] = self.sigma_v**-2
        if self.tx:
            j[self.beta_index, self.beta_index] = self.tx_sigma_nepers**-2
        if self.passes is not None:
            b = self.base_size
            ww = self.passes.whiten.T @ self.passes.whiten
            if self.offset_tail is not None and theta is not None:
                e = self._whitened_offsets(theta)
                ww = ww * self._tail_c() / (self._tail_c() + float(e @ e))
            end = self.offsets_end
            j[b:end:2, b:end:2] = ww
            j[b + 1:end:2, b + 1:end:2] = ww
        if self.turn_at_s is not None:
            u = self.offsets_end
            j[u, u] = j[u + 1, u + 1] = self.turn_sigma_m_s**-2
        return j

    def data_information(self, theta: np.ndarray) -> np.ndarray:
        """Fisher information of the data at theta. Under a threshold each heard slot holds the
        truncated normal's information (``model.truncated_information_factor``) and each censored
        observation its curvature (``model.censored_curvature``, per frame sent)."""
        jac = self._data_jacobian(theta)
        if self.threshold_y is None:
            return (jac * self.data.w[:, None]).T @ jac
        _, d2 = self._geometry(theta)
        w = self.data.w * truncated_information_factor(self._z(d2, theta))
        info = (jac * w[:, None]).T @ jac
        if self.censored is not None:
            c = self.censored
            g, d2c = self._censored_geometry(theta)
            jc = self._rows_jacobian(g, d2c, c.tau_s, c.t_s, c.pass_index)
            zc = self._z(d2c, theta)
            if c.log_p is not None:  # the Binomial counts' Fisher information at E[K | burst]
                k = np.exp(c.log_p)
                k = float(np.arange(1, len(k) + 1) @ k / k.sum())
                wc = k * mills_ratio(zc) * mills_ratio(-zc) / self.log_range_sigma**2
            else:
                wc = c.frames * censored_curvature(zc) / self.log_range_sigma**2
            info = info + (jc * wc[:, None]).T @ jc
        return info

    def data_residuals(self, theta: np.ndarray) -> np.ndarray:
        """The data's residuals (their squares sum to the data's part of the cost): the normalised
        slot residuals (under a threshold their signed roots), then the censored observations."""
        return self.residuals(theta)[: self.data_rows]

    def standardized_residuals(self, theta: np.ndarray) -> np.ndarray:
        """The slots' residuals, zero mean and unit variance under the model, in time order: under
        a threshold the slot mean of n heard frames has mean m - s lambda(-z) and variance
        kappa s^2 / n (``model.truncated_information_factor``)."""
        if self.threshold_y is None:
            return self.residuals(theta)[: len(self.data.t_s)]
        d = self.data
        _, d2 = self._geometry(theta)
        beta = theta[self.beta_index] if self.tx else 0.0
        r = np.sqrt(d.w) * (d.y - 0.5 * np.log(d2) + beta)
        z = self._z(d2, theta)
        kappa = np.maximum(truncated_information_factor(z), 1e-3)
        return (r + np.sqrt(self.data.n_samples) * mills_ratio(-z)) / np.sqrt(kappa)

    def fit(self, theta0: np.ndarray, max_nfev: int = 200) -> tuple[np.ndarray, float]:
        """Local MAP fit from theta0: (theta, 2 x negative log posterior)."""
        # MINPACK's lmder directly (what least_squares(method="lm") runs, without its wrappers'
        # per-call overhead, which dominates at a few hundred residuals)
        x, *_ = leastsq(self.residuals, theta0, Dfun=self.jacobian, xtol=1e-6, ftol=1e-7, maxfev=max_nfev,
                        full_output=True)
        r = self.residuals(x)
        return x, float(r @ r)
