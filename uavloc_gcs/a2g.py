"""The air-to-ground channel from a phone on the ground to a vehicle above it (SPEC 1.1, issue 41).

Whether the path is blocked depends on the elevation angle, so altitude has a price: lower looks
hear a phone more loudly (shorter range, better ranging) but lose the phones at low angles. One
frame of a phone with transmit offset ``tx`` at 3-D distance d and elevation theta arrives at

    RSSI = P0 + tx - 10 eta log10(d / d0) - excess[s] + X + F        [dBm]

- ``s`` is the path's state, line of sight (LoS) with probability ``P_LoS(theta)`` of Al-Hourani,
  Kandeepan, Lardner, "Optimal LAP altitude for maximum coverage", IEEE WCL 3(6):569-572, 2014:
  ``P_LoS = 1 / (1 + a exp(-b (theta_deg - a)))``; one state per burst of one vehicle;
- ``excess[s]`` the mean excess loss over the log-distance law in that state (the same paper's
  eta_LoS / eta_NLoS at 2 GHz, the frequency of its table nearest 2.4 GHz);
- ``X ~ N(0, shadow[s]^2)`` the large-scale shadowing, shared by every frame of one burst from one
  vehicle (a burst is sent within a second from one place); the simulator correlates it between
  bursts over the distance moved (:attr:`Environment.decorrelation_m`), so bursts far apart are
  independent;
- ``F`` the small-scale fading, independent frame to frame (frames 40 ms apart hop over channels
  1/6/11, 25 MHz apart, while the vehicle moves several wavelengths): 10 log10 |h|^2 of Rician
  fading with K = 9 dB in LoS, Rayleigh in NLoS, drawn and integrated exactly
  (:mod:`uavloc_gcs.a2g_fading`; a Gaussian in dB would make edge frames too easy to hear).

A frame is heard when its RSSI exceeds the receiver's sensitivity S. Sources of every number are in
:data:`ENVIRONMENTS` and docs/science/world.md ("The air-to-ground channel"). The calibration: with
free-space spreading (eta = 2) the link budget P0 - S puts a LoS frame's 50 % hearing distance in
open terrain (no excess loss; the 4 dB shadowing and the fading integrated) at Wi2SAR's measured
298.8 m (:func:`wi2sar_reference_power_dbm`).

Everything here is pure numpy over arrays that broadcast (horizontal distance, height, transmit
offset); the simulator (sim_link/world), the estimator and the POD model use the same functions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from .a2g_fading import FadingLaw, fading_law

LOS, NLOS = 0, 1
GH_NODES = 48  # Gauss-Hermite nodes over the shared shadowing (within 5e-4 of quadrature: tests)
# ... and over its posterior given a burst's heard frames, in the likelihood (narrower, smoother:
# within 2e-3 in log-likelihood of quadrature, tests/uavloc_gcs/test_a2g.py)
GH_NODES_LIKELIHOOD = 24
_PROPOSAL_WIDEN = 1.5  # the importance proposal's spread over the Gaussian-fading posterior's
_MIN_P = 1e-300  # floor of probabilities before a logarithm
HEARING_COARSE_STEPS = 10  # hearing_distance_m: the crossing is bracketed on every 10th point first

# Wi2SAR ("Take Me Home, Wi-Fi Drone", Hou, Yu, Wu, MobiCom '26, arXiv 2604.09115): the aerial victim
# discovery range at 2.4 GHz without its lens, Fig. 10(c), as published in the artifact
# wi2sar/wi2sar-mobicom26-ae, data/fig10_ll_effectiveness/fig10_vdm_working_range.csv.
WI2SAR_LOS_RANGE_M = 298.8461142
WI2SAR_NLOS_RANGE_M = 147.4143819


@dataclass(frozen=True)
class Environment:
    """One built-up environment of the elevation-angle model (see :data:`ENVIRONMENTS`)."""

    name: str
    los_a: float  # Al-Hourani's a [-]
    los_b_per_deg: float  # Al-Hourani's b [1/deg]
    excess_los_db: float  # mean excess loss over the log-distance law, LoS [dB]
    excess_nlos_db: float  # the same, NLoS [dB]
    # ITU-R P.1410 built-up parameters the (a, b) were fitted to: ratio of built-up land,
    # buildings per km^2, scale of the Rayleigh law of building heights [m] (documentation)
    built_up_fraction: float
    buildings_per_km2: float
    building_height_scale_m: float
    shadow_los_db: float  # std of the burst-shared large-scale shadowing, LoS [dB]
    shadow_nlos_db: float  # the same, NLoS [dB]
    rician_k_los_db: float  # small-scale fading in LoS; NLoS is Rayleigh
    decorrelation_m: float  # the shadowing (and LoS state) decorrelate over this distance moved [m]


# (a, b, eta_LoS, eta_NLoS): Al-Hourani, Kandeepan, Lardner, IEEE WCL 2014, table of the four
# environments at 2 GHz (the same numbers in zhangxiaochen95/uav_bs_ctrl envs/common.py, whose
# arctan feeds radians where the model takes degrees -- a trap this module avoids).
# (alpha, beta, gamma): ITU-R P.1410 standard environments, as tabulated in Saboor et al., "A
# geometry-based modelling approach for the LoS probability in UAV communications", IEEE OJ-COMS 5,
# 2024, Table 2 (the recommendation itself does not tabulate the four tuples).
# Shadowing, LoS: 4 dB -- 3GPP TR 38.811 V15.0.0 Table 6.7.2-3a (urban LoS, S band, SF 4 dB); the
# low-altitude UAV campaigns summarised by Khawaja et al., IEEE COMST 21(3), 2019 (Table 2.2 of its
# book version) measured 2.2-5.3 dB (Matolak & Sun suburban 2.6-3.2, Khawaja et al. suburban/open
# 2.79-5.3, Sun & Matolak mountains 2.2-3.9, Newhall et al. 5.24): 4 dB for every environment.
# Shadowing, NLoS: TR 38.811 S band at 30 deg elevation -- suburban 8.78 dB (Table 6.7.2-6a),
# urban 6 dB (6.7.2-4a), dense urban 12.4 dB (6.7.2-2a); high-rise has no 38.811 scenario and takes
# dense urban's. K factor in LoS: 9 dB, TR 38.811 urban LoS (Table 6.7.2-3a), the lowest of its
# S-band LoS tables; NLoS: no dominant path (38.811 NLoS K = -100 dB), Rayleigh.
# Decorrelation: TR 38.811 SF decorrelation distance 37 m (LoS) and 50 m (NLoS); 50 m is taken for
# both (more correlated bursts inform less). The tables above were read in fraunhoferhhi/QuaDRiGa,
# quadriga_src/config/3GPP_38.881_*.conf, which transcribe TR 38.811.
ENVIRONMENTS: dict[str, Environment] = {
    e.name: e for e in (
        Environment("suburban", 4.88, 0.43, 0.1, 21.0, 0.1, 750.0, 8.0, 4.0, 8.78, 9.0, 50.0),
        Environment("urban", 9.61, 0.16, 1.0, 20.0, 0.3, 500.0, 15.0, 4.0, 6.0, 9.0, 50.0),
        Environment("dense-urban", 12.08, 0.11, 1.6, 23.0, 0.5, 300.0, 20.0, 4.0, 12.4, 9.0, 50.0),
        Environment("high-rise", 27.23, 0.08, 2.3, 34.0, 0.5, 300.0, 50.0, 4.0, 12.4, 9.0, 50.0),
    )
}


def elevation_deg(horizontal_m, height_m) -> np.ndarray:
    """Elevation angle [deg] of the vehicle seen from the phone (height = vehicle above the phone)."""
    return np.degrees(np.arctan2(np.asarray(height_m, float), np.asarray(horizontal_m, float)))


def los_probability(env: Environment, elevation_deg_) -> np.ndarray:
    """Al-Hourani's P_LoS at elevation angles [deg] (not radians)."""
    th = np.asarray(elevation_deg_, float)
    return 1.0 / (1.0 + env.los_a * np.exp(-env.los_b_per_deg * (th - env.los_a)))


def p1410_los_probability(env: Environment, horizontal_m: float, height_m: float) -> float:
    """The geometric LoS probability of ITU-R P.1410 (the model Al-Hourani's curve was fitted to) for
    a terminal on the ground and one ``height_m`` above it: floor(r sqrt(alpha beta) / 1000)
    buildings, Rayleigh heights of scale gamma, each below the ray where it crosses. For comparison
    (docs/science/world.md): it depends on the distance as well as the elevation."""
    n = int(math.floor(horizontal_m * math.sqrt(env.built_up_fraction * env.buildings_per_km2) / 1000.0))
    if n == 0:
        return 1.0
    ray = height_m * (1.0 - (np.arange(n) + 0.5) / n)  # the ray's height over building i
    return float(np.prod(1.0 - np.exp(-ray ** 2 / (2.0 * env.building_height_scale_m ** 2))))


def fading_db_moments(k_factor_db: float | None) -> tuple[float, float]:
    """Mean and standard deviation [dB] of the fading F (Rician with ``k_factor_db``, or Rayleigh:
    -2.507 dB and 5.570 dB, Euler's gamma and pi / sqrt(6) in dB)."""
    law = fading_law(k_factor_db)
    return law.mean_db, law.std_db


@lru_cache(maxsize=16)
def _median_margin_db(shadow_db: float, k_factor_db: float | None) -> float:
    """The margin m [dB] of a frame's local mean power over the sensitivity at which it is heard
    with probability 1/2, shadowing N(0, shadow_db^2) and the fading integrated."""
    law = fading_law(k_factor_db)
    nodes, weights = _gh()
    lo, hi = -40.0, 40.0
    for _ in range(60):
        m = 0.5 * (lo + hi)
        p = float(law.survival(-(m + shadow_db * nodes)) @ weights)
        lo, hi = (lo, m) if p >= 0.5 else (m, hi)
    return 0.5 * (lo + hi)


def wi2sar_reference_power_dbm(sensitivity_dbm: float, path_loss_exponent: float = 2.0,
                               reference_distance_m: float = 1.0, shadow_db: float = 4.0,
                               k_factor_db: float = 9.0) -> float:
    """The RSSI at the reference distance [dBm] that puts the 50 % hearing distance of one LoS frame
    in open terrain (no excess loss; shadowing ``shadow_db``, Rician fading) at Wi2SAR's 298.8 m."""
    spreading = 10.0 * path_loss_exponent * math.log10(WI2SAR_LOS_RANGE_M / reference_distance_m)
    return sensitivity_dbm + spreading + _median_margin_db(shadow_db, k_factor_db)


def wi2sar_blocked_excess_db(reference_power_dbm: float, sensitivity_dbm: float, path_loss_exponent: float = 2.0,
                             reference_distance_m: float = 1.0, shadow_db: float = 4.0) -> float:
    """The excess loss of a blocked path [dB] that puts one blocked (Rayleigh-faded, shadowing
    ``shadow_db``) frame's 50 % hearing distance at Wi2SAR's obstructed 147.4 m under this link
    budget: what Wi2SAR's wilderness occlusion costs, beside the towns' building losses."""
    spreading = 10.0 * path_loss_exponent * math.log10(WI2SAR_NLOS_RANGE_M / reference_distance_m)
    return reference_power_dbm - sensitivity_dbm - spreading - _median_margin_db(shadow_db, None)


def _gh(n: int | None = None):
    return _gh_nodes(GH_NODES if n is None else n)


@lru_cache(maxsize=8)
def _gh_nodes(n: int):
    z, w = np.polynomial.hermite_e.hermegauss(n)
    return z, w / w.sum()


@dataclass(frozen=True)
class A2GChannel:
    """The elevation-angle channel of one environment with the scenario's link budget: frames are
    heard above ``sensitivity_dbm``; ``reference_power_dbm`` is the RSSI at ``reference_distance_m``
    of a phone with no transmit offset before excess loss, shadowing and fading."""

    environment: Environment
    reference_power_dbm: float
    path_loss_exponent: float
    reference_distance_m: float
    sensitivity_dbm: float

    @staticmethod
    def from_scenario(sc) -> "A2GChannel | None":
        """The scenario's channel when ``[channel] environment`` names one; None otherwise (the
        log-distance channel of sim_link/world/channel.py)."""
        ch = sc.channel
        name = getattr(ch, "environment", None)
        if name is None:
            return None
        return A2GChannel(ENVIRONMENTS[name], ch.reference_power_dbm, ch.path_loss_exponent,
                          ch.reference_distance_m, ch.receiver_sensitivity_dbm)

    # -- per-state constants, index LOS / NLOS ------------------------------------------------
    @property
    def excess_db(self) -> np.ndarray:
        return np.array([self.environment.excess_los_db, self.environment.excess_nlos_db])

    @property
    def shadow_db(self) -> np.ndarray:
        return np.array([self.environment.shadow_los_db, self.environment.shadow_nlos_db])

    def fading(self, state: int) -> FadingLaw:
        """The small-scale fading law of a frame in ``state`` (Rician in LoS, Rayleigh in NLoS)."""
        return fading_law(self.environment.rician_k_los_db if state == LOS else None)

    @property
    def fast_mean_db(self) -> np.ndarray:
        """Mean of the fading in dB per state."""
        return np.array([self.fading(LOS).mean_db, self.fading(NLOS).mean_db])

    @property
    def fast_db(self) -> np.ndarray:
        """Standard deviation of the fading in dB per state."""
        return np.array([self.fading(LOS).std_db, self.fading(NLOS).std_db])

    def los_probability(self, horizontal_m, height_m) -> np.ndarray:
        return los_probability(self.environment, elevation_deg(horizontal_m, height_m))

    def spreading_dbm(self, d3_m, tx_offset_db=0.0) -> np.ndarray:
        """RSSI [dBm] at 3-D distance ``d3_m`` by the log-distance law alone (no excess loss,
        shadowing or fading)."""
        d = np.maximum(np.asarray(d3_m, float), 1e-3)
        return (self.reference_power_dbm + np.asarray(tx_offset_db, float)
                - 10.0 * self.path_loss_exponent * np.log10(d / self.reference_distance_m))

    def mean_power_dbm(self, d3_m, state: int, tx_offset_db=0.0) -> np.ndarray:
        """Local mean power [dBm] of a frame in ``state`` with no shadowing: spreading and excess loss
        (a frame's RSSI is this plus the shadowing and the fading F, E[10^(F/10)] = 1)."""
        return self.spreading_dbm(d3_m, tx_offset_db) - self.excess_db[state]

    def frame_mean_dbm(self, d3_m, state: int, tx_offset_db=0.0) -> np.ndarray:
        """Mean RSSI [dBm] of a frame in ``state`` with no shadowing (the fading's mean in dB added)."""
        return self.mean_power_dbm(d3_m, state, tx_offset_db) + self.fast_mean_db[state]

    def state_range_m(self, state: int, tx_offset_db: float = 0.0) -> float:
        """3-D distance [m] at which one frame in ``state`` is heard with probability 1/2 (the state's
        shadowing and fading integrated)."""
        m = _median_margin_db(float(self.shadow_db[state]), self.fading(state).k_factor_db)
        margin = float(self.mean_power_dbm(self.reference_distance_m, state, tx_offset_db)) - self.sensitivity_dbm - m
        return self.reference_distance_m * 10.0 ** (margin / (10.0 * self.path_loss_exponent))

    # -- hearing --------------------------------------------------------------------------------
    def _per_frame_q(self, d3, s, tx_offset_db, x_db):
        """P(a frame is above the sensitivity | state s, shared shadowing x_db)."""
        return self.fading(s).survival(self.sensitivity_dbm - self.mean_power_dbm(d3, s, tx_offset_db) - x_db)

    def frame_heard_probability(self, horizontal_m, height_m, tx_offset_db=0.0) -> np.ndarray:
        """P(one frame sent at this geometry is heard), the LoS state, the shadowing (Gauss-Hermite)
        and the fading integrated out."""
        h, z = np.asarray(horizontal_m, float), np.asarray(height_m, float)
        d3 = np.hypot(h, z)[..., None]
        p_los = self.los_probability(h, z)
        nodes, weights = _gh()
        tx = np.asarray(tx_offset_db, float)[..., None]
        out = 0.0
        for s, w in ((LOS, p_los), (NLOS, 1.0 - p_los)):
            out = out + w * (self._per_frame_q(d3, s, tx, self.shadow_db[s] * nodes) @ weights)
        return np.asarray(out)

    def heard_count_pmf(self, horizontal_m, height_m, frames_sent: int, *, channel_share: float = 1.0,
                        tx_offset_db=0.0) -> np.ndarray:
        """P(n of a burst's ``frames_sent`` frames are heard), n = 0..frames_sent, shape (..., K+1):
        each frame reaches a listened channel with ``channel_share`` and is heard above the
        sensitivity; frames share the burst's state and shadowing (Gauss-Hermite over it)."""
        from scipy.special import comb

        k = int(frames_sent)
        h, z = np.asarray(horizontal_m, float), np.asarray(height_m, float)
        d3 = np.hypot(h, z)[..., None]
        p_los = self.los_probability(h, z)
        nodes, weights = _gh(2 * GH_NODES)  # a given count of many frames is peaked in the shadowing
        n = np.arange(k + 1)
        out = 0.0
        for s, w in ((LOS, p_los), (NLOS, 1.0 - p_los)):
            q = channel_share * self._per_frame_q(d3, s, np.asarray(tx_offset_db, float)[..., None],
                                                  self.shadow_db[s] * nodes)  # (..., G)
            q = np.clip(q, 0.0, 1.0)[..., None]
            terms = q ** n * (1.0 - q) ** (k - n)  # (..., G, K+1)
            out = out + np.asarray(w)[..., None] * np.tensordot(terms, weights, axes=([-2], [0]))
        return comb(k, n) * out

    def burst_heard_probability(self, horizontal_m, height_m, frames, *, channel_share: float = 1.0,
                                tx_offset_db=0.0) -> np.ndarray:
        """P(at least one frame of a burst is heard). ``frames``: the frames it sends (an int, or an
        array broadcasting with the geometry), or a pmf over 0..Kmax frames given as
        ``("pmf", array)``."""
        h, z = np.asarray(horizontal_m, float), np.asarray(height_m, float)
        d3 = np.hypot(h, z)
        p_los = self.los_probability(h, z)
        nodes, weights = _gh()
        pmf = None
        if isinstance(frames, tuple) and frames and frames[0] == "pmf":
            pmf = np.asarray(frames[1], float)
            pmf = pmf / pmf.sum()
            kk = np.arange(len(pmf))
        out = 0.0
        tx = np.asarray(tx_offset_db, float)
        for s, w in ((LOS, p_los), (NLOS, 1.0 - p_los)):
            q = channel_share * self._per_frame_q(d3[..., None], s, tx[..., None], self.shadow_db[s] * nodes)
            miss = np.clip(1.0 - q, 0.0, 1.0)  # (..., G)
            if pmf is None:
                k = np.asarray(frames, float)[..., None]
                none = (miss ** k) @ weights
            else:
                none = ((miss[..., None] ** kk) @ pmf) @ weights
            out = out + w * (1.0 - none)
        return np.asarray(out)

    def burst_heard_given_margin(self, state: int, margin_db, frames_pmf, *, channel_share: float = 1.0) -> np.ndarray:
        """P(at least one frame of a burst heard | state) against the margin [dB] of a frame's local
        mean power (:meth:`mean_power_dbm`) over the sensitivity; ``frames_pmf[K]`` over K = 0..Kmax
        frames sent. For tables: the geometry and the transmit offset enter only through the margin."""
        nodes, weights = _gh()
        pmf = np.asarray(frames_pmf, float)
        pmf = pmf / pmf.sum()
        kk = np.nonzero(pmf)[0]
        q = channel_share * self.fading(state).survival(
            -(np.asarray(margin_db, float)[..., None] + self.shadow_db[state] * nodes))
        miss = np.clip(1.0 - q, 0.0, 1.0)
        none = ((miss[..., None] ** kk) @ pmf[kk]) @ weights
        return 1.0 - none

    def hearing_distance_m(self, height_m: float, *, frames=None, channel_share: float = 1.0, p: float = 0.5,
                           tx_offset_db: float = 0.0, max_m: float = 3000.0, step_m: float = 0.5) -> float:
        """The horizontal distance [m] beyond which a frame (``frames`` None) or a burst (``frames``
        as for :meth:`burst_heard_probability`) sent by a phone ``height_m`` below the vehicle is heard
        with less than probability ``p`` (the outermost crossing; 0 if never above ``p``)."""
        h = np.arange(0.0, max_m + step_m, step_m)

        def prob(at):
            if frames is None:
                return self.frame_heard_probability(at, height_m, tx_offset_db)
            return self.burst_heard_probability(at, height_m, frames, channel_share=channel_share,
                                                tx_offset_db=tx_offset_db)

        # The crossing is bracketed on every HEARING_COARSE_STEPS-th point, then found on the fine
        # points of that bracket alone (the probability falls smoothly with distance past its
        # peak): a tenth of the evaluations. Without a coarse point above p, every point is tried.
        coarse = np.append(np.arange(0, len(h), HEARING_COARSE_STEPS), len(h) - 1)
        above = np.nonzero(prob(h[coarse]) >= p)[0]
        if above.size:
            lo = int(coarse[above[-1]])
            idx = np.arange(lo, min(lo + HEARING_COARSE_STEPS, len(h) - 1) + 1)
        else:
            idx = np.arange(len(h))
        pr = prob(h[idx])
        above = np.nonzero(pr >= p)[0]
        if above.size == 0:
            return 0.0
        i = int(above[-1])
        at = int(idx[i])
        if at + 1 >= len(h):
            return float(h[-1])
        after = pr[i + 1] if i + 1 < len(pr) else float(prob(h[at + 1:at + 2])[0])
        f = (pr[i] - p) / max(pr[i] - after, 1e-300)
        return float(h[at] + f * step_m)

    # -- the likelihood of one burst ------------------------------------------------------------
    def _log_integrand_nodes(self, rssi, counts, d3, s, tx, n_missed: int | None, channel_share: float):
        """For state s over the positions' shape: the shadowing's importance nodes X (..., G), the log
        of (prior density of X) x (heard values' exact density given X) / (proposal density) + the
        node's log weight, and the log miss probability per frame at the nodes.

        The proposal is the shadowing's posterior under a Gaussian-in-dB stand-in for the fading
        (closed form), widened by :data:`_PROPOSAL_WIDEN` so the exact, skewed law stays covered."""
        return self._log_integrand_at(rssi, counts, self.mean_power_dbm(d3, s, tx), s, channel_share)

    def _log_integrand_at(self, rssi, counts, mp, s, channel_share: float):
        """:meth:`_log_integrand_nodes` at local mean powers ``mp`` [dBm] in state s: everything in a
        burst's likelihood given the state depends on the geometry and offset only through them."""
        law = self.fading(s)
        sf, sx = float(law.std_db), float(self.shadow_db[s])
        mp = np.asarray(mp, float)
        shape = np.shape(mp)
        if rssi.size:
            n_tot = float(counts.sum())
            ybar = float((counts * rssi).sum() / n_tot) - mp - law.mean_db
            prec = 1.0 / (sx * sx) + n_tot / (sf * sf)
            pm = (n_tot * ybar / (sf * sf)) / prec
            psd = np.full(shape, _PROPOSAL_WIDEN / math.sqrt(prec))
        else:
            pm, psd = np.zeros(shape), np.full(shape, sx)
        nodes, weights = _gh(GH_NODES_LIKELIHOOD)
        x = pm[..., None] + psd[..., None] * nodes  # (..., G)
        log_w = (np.log(weights) + 0.5 * nodes ** 2 + np.log(psd[..., None] * math.sqrt(2.0 * math.pi))
                 - 0.5 * (x / sx) ** 2 - math.log(sx * math.sqrt(2.0 * math.pi)))
        base = mp[..., None] + x  # (..., G): each frame's RSSI is base + F
        for r, n in zip(rssi, counts):
            log_w = log_w + law.log_density(r - base, int(round(n)))
        q = channel_share * law.survival(self.sensitivity_dbm - base)
        return log_w, np.log(np.clip(1.0 - q, _MIN_P, 1.0))

    def burst_log_likelihood(self, rssi_dbm, n_missed: int, horizontal_m, height_m, *, counts=None,
                             tx_offset_db=0.0, channel_share: float = 1.0) -> np.ndarray:
        """log p(one burst's heard RSSI and ``n_missed`` frames sent but not heard | geometry), with
        the LoS state and the burst's shared shadowing integrated out; vectorised over positions
        (``horizontal_m``, ``height_m``, ``tx_offset_db`` broadcast; the result has their shape).

        ``rssi_dbm`` (J,): heard values [dBm], each the mean of ``counts[j]`` frames (a sensor's slot;
        default one frame each). Given the state and the shadowing X the frames are independent with
        RSSI = mean power + X + F (F the exact fading law; a slot's mean has the law of the mean of its
        frames' F) and a missed frame has probability 1 - c P(F > S - mean power - X), c =
        ``channel_share`` (1 when ``n_missed`` counts frames on listened channels). X is integrated by
        importance-weighted Gauss-Hermite about its posterior. A slot's frames are not each required
        to lie above S (exact for one frame per slot). Constants that depend on neither the geometry
        nor the counts are kept, so values compare across positions and counts."""
        rssi = np.asarray(rssi_dbm, float).reshape(-1)
        cnt = np.ones(len(rssi)) if counts is None else np.asarray(counts, float).reshape(-1)
        h, z = np.broadcast_arrays(np.asarray(horizontal_m, float), np.asarray(height_m, float))
        tx = np.broadcast_to(np.asarray(tx_offset_db, float), h.shape)
        d3 = np.hypot(h, z)
        p_los = np.clip(self.los_probability(h, z), _MIN_P, 1.0)
        parts = []
        for s, w in ((LOS, p_los), (NLOS, np.clip(1.0 - p_los, _MIN_P, 1.0))):
            log_w, log_miss = self._log_integrand_nodes(rssi, cnt, d3, s, tx, n_missed, channel_share)
            parts.append(np.log(w) + _logsumexp(log_w + int(n_missed) * log_miss, axis=-1))
        return np.logaddexp(parts[0], parts[1])

    def burst_log_likelihood_unknown_sent(self, rssi_dbm, frames_pmf, horizontal_m, height_m, *, counts=None,
                                          tx_offset_db=0.0, channel_share: float = 1.0) -> np.ndarray:
        """As :meth:`burst_log_likelihood` when the number of frames sent is not known: summed over
        K frames sent with ``frames_pmf[K]`` (K = 0..Kmax, every channel), each sent frame reaching a
        listened channel with ``channel_share``: sum_K p(K) C(K, N) E[(1 - c q)^(K - N) ...], N the
        heard frames (a polynomial in 1 - c q at each node)."""
        h, z = np.broadcast_arrays(np.asarray(horizontal_m, float), np.asarray(height_m, float))
        tx = np.broadcast_to(np.asarray(tx_offset_db, float), h.shape)
        d3 = np.hypot(h, z)
        p_los = np.clip(self.los_probability(h, z), _MIN_P, 1.0)
        parts = []
        for s, w in ((LOS, p_los), (NLOS, np.clip(1.0 - p_los, _MIN_P, 1.0))):
            parts.append(np.log(w) + self.state_log_likelihood_unknown_sent(
                rssi_dbm, frames_pmf, self.mean_power_dbm(d3, s, tx), s, counts=counts, channel_share=channel_share))
        return np.logaddexp(parts[0], parts[1])

    def state_log_likelihood_unknown_sent(self, rssi_dbm, frames_pmf, mean_power_dbm, state: int, *, counts=None,
                                          channel_share: float = 1.0) -> np.ndarray:
        """The state-``state`` term of :meth:`burst_log_likelihood_unknown_sent` (before its weight
        P(state)) as a function of the local mean power alone [dBm] (``mean_power_dbm`` any shape):
        a smooth function of one variable, which callers tabulate once per burst."""
        from scipy.special import comb

        rssi = np.asarray(rssi_dbm, float).reshape(-1)
        cnt = np.ones(len(rssi)) if counts is None else np.asarray(counts, float).reshape(-1)
        n_heard = int(round(cnt.sum()))
        pmf = np.asarray(frames_pmf, float)
        pmf = pmf / pmf.sum()
        mp = np.asarray(mean_power_dbm, float)
        kk = np.arange(n_heard, len(pmf))
        if kk.size == 0 or pmf[kk].sum() <= 0:
            return np.full(mp.shape, -np.inf)
        coeffs = pmf[kk] * comb(kk, n_heard)
        log_w, log_miss = self._log_integrand_at(rssi, cnt, mp, state, channel_share)
        poly = np.polynomial.polynomial.polyval(np.exp(log_miss), coeffs)
        return _logsumexp(log_w + np.log(np.maximum(poly, _MIN_P)), axis=-1)


def _logsumexp(a: np.ndarray, axis: int) -> np.ndarray:
    m = np.max(a, axis=axis, keepdims=True)
    m = np.where(np.isfinite(m), m, 0.0)
    return np.squeeze(m, axis=axis) + np.log(np.sum(np.exp(a - m), axis=axis))
