"""Estimate one emitter (a phone) from its RSSI slots: position, velocity and honest radii.

:func:`estimate_emitter` is a pure function of the slots (any vehicles, any legs). It fits the
constant-velocity model by MAP (see :mod:`.fit`) from several starts, including the mirror image
across the slots' principal line, keeps the distinct local optima as candidates, and reports:

- ``radius95_m``: the radius of the circle about the estimate holding 95 % of the posterior
  (Laplace approximation, information deflated when the residuals show correlated shadowing or a
  misfit). When a mirror candidate holds more than 5 % of the posterior mass the radius takes it
  in, because a 95 % circle must: if it lies outside the best candidate's own circle the estimate
  is ``ambiguous`` (a look has to tell them apart) and the radius reaches over its whole circle;
  a near twin inside it is covered by the 95 % circle of the two candidates' mixture.
  ``mode_radius95_m`` is the radius of the best candidate alone.
- ``annulus_bound_m``: the paper's annulus-intersection bound (:mod:`.annulus`).

With ``silence=`` (opt-in) where the phone was heard and where vehicles listened without hearing
it constrain every candidate's track (:mod:`.evidence`): mirrors on the silent side lose out.

Why not trust one pass: a constant-velocity person seen from one straight leg is unobservable
(SPEC §3.1); only the speed prior bounds the error, and the radius says so.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import EstimationError
from ..observations import SlotBatch
from .annulus import annulus_bound_m, reach_bound_m
from .evidence import Censored, Silence, build_bounds
from .field_radius import sampled_posterior
from .fit import Problem
from .maneuver import MANEUVER_TIME_S, find_passes, intensity_m2_s3, state_noise
from .model import ChannelModel, mixture_radius, radius_of_probability
from .modes import PROBE_MERGE_M, _distinct_modes, _laplace, _power_contradicted, _refit_bounded
from .prepared import censored_rows, prepare
from .starts import inflation_factor, start_points

log = logging.getLogger(__name__)

MIN_SLOTS = 3
AMBIGUITY_MASS = 0.05
TX_PRIOR_SIGMA_DB = 6.0
# Whether a second motion model joins the estimate: that the person turned since the oldest data
# (prior probability 1 - exp(-lag / maneuver time)), in which the old passes tie the present state
# only through the speed bound (q = 3 v_max^2 / lag: a deviation of v_max * lag after the lag).
# The Gaussian maneuver noise alone has light tails: a person who turned 100 s ago is several of
# its sigmas off the line, and the mirror the turn leads to loses all its mass. Measured (bench
# localize --runs 100 --family "lanes + look" [--switch turn-mixture]; docs/measurements/paper-comparison.md):
# small area 0.83 -> 0.91 covered with the median radius 18.6 -> 28.9 m, two lanes + look 0.93 ->
# 0.92, the solve 2.5-3x slower, and after two looks at a known turn radii 17-28 m instead of
# 11-14 m (test_maneuver.py); short of 93 % in the small area, so off.
TURN_MIXTURE = False
# The pass offsets' prior: multivariate t with this many degrees of freedom (None: Gaussian). A
# scale mixture of the Gaussian maneuver prior over the intensity q: a person who turned is far in
# the Gaussian's tail, in the t's only a logarithm away. Measured (bench localize --runs 200
# --switch tail-4 [--switch turn-mixture]; docs/measurements/paper-comparison.md): small area + look 0.81 ->
# 0.88 covered (0.93 with the mixture, every random-waypoint family then >= 0.93), but the look
# families' radii about double and correlated shadowing's RMSE / bound goes 0.45 -> 0.8 for two
# parallel legs (the offsets absorb the shadowing), so off.
MANEUVER_TAIL_DOF: float | None = None
# Whether models in which the person turned once join the estimate: at each of the longest gaps
# in the data (``TURN_GAPS``, the turn's time unknown within them) the velocity before it was
# v - u, with u ~ N(0, (TURN_SIGMA_FRACTION v_max)^2) per axis, beside the Gaussian maneuver
# noise. The prior probability of a turn since the oldest data, 1 - exp(-lag / TURN_TIME_S),
# is shared among the gaps by the time each stands for. A turn is one change of velocity: two
# parameters that correlated shadowing cannot use the way it uses free offsets per pass
# (MANEUVER_TAIL_DOF). Without it the Gaussian maneuver noise has light tails and, after a turn,
# the look families' radii are 1.7-2.6x too small at the 95th percentile. Measured with
# TWINS_ACROSS_MODELS_ONLY = False, TURN_TIME_S = 200 and MIXTURE_RADIUS (bench localize --runs
# 100, the "need" column; docs/measurements/paper-comparison.md): every random-waypoint family covered
# 0.93-0.98 with radii 0.85-1.11 of what 95 % needs (without: small area + look 0.83, need 2.61);
# correlated shadowing's RMSE / bound 0.46 (0.43-0.44 without); 1,000 slots in 8 ms instead of
# 6.4 ms; in missions (bench looks --runs 20, variant "no-turns" is the main model alone) 0.6 s
# longer, 0.973 inside instead of 0.963, on the SITL suite's scenario 0.4 s.
TURN_JUMP = True
TURN_GAPS = 3
TURN_GAP_MIN_S = 5.0
TURN_SIGMA_FRACTION = 1.0
# The mean time between turns in TURN_JUMP's prior; None: the maneuver time. The random-waypoint
# walkers of a 250 m square turn about every two minutes, those of the paper's area about every
# eight; 200 s covers the small area at 0.94 instead of 0.92 (bench looks variant "turn-600" is the
# maneuver time).
TURN_TIME_S: float | None = 200.0
# Whether only modes of different motion models are merged when they meet at t_ref (closer than
# PROBE_MERGE_M). Two modes of one model are told apart at the fit's reference time; with
# different velocities they can meet at t_ref, and the second then takes the mirror's place as a
# twin of the estimate, hiding a real alternative further down (seen in the small-area family with
# TURN_JUMP: "mirrors" 0.2-3.7 m from the estimate holding 30-77 % of the mass, the truth 50 m
# away). False merges those too (bench looks variant "split-twins" is True); measured in
# docs/measurements/paper-comparison.md: with TURN_JUMP it lifts the small area + look family 0.90 -> 0.92.
TWINS_ACROSS_MODELS_ONLY = False
# Whether TURN_JUMP's turn models start from the main model's modes (the turn's velocity change
# zero; the main model's mirrors among them) instead of the start grid, the CV fit and their own
# mirror starts (TURN_MIRRORS). Measured (docs/measurements/paper-comparison.md): the same coverage, and the
# solve for 1,000 slots 7.5 ms instead of 13 ms (the main model alone 6.8 ms).
TURN_STARTS_FROM_MAIN = True
TURN_MIRRORS = False
# How the 95 % radius takes in a second mode holding more than AMBIGUITY_MASS inside the estimate's
# own circle (a near twin; an ambiguous mirror further off is always covered whole): True, the
# radius of the circle about the estimate holding 95 % of the two modes' mixture (each a Gaussian
# with its own 95 % radius, weighed by its mass); False, the circle reaching over the twin's whole
# 95 % circle (distance + its radius), as if the twin held all the mass. Measured in
# docs/measurements/paper-comparison.md (bench looks variant "cover-mirror" is False).
MIXTURE_RADIUS = True
# Whether, under a receiver threshold (the field world), the 95 % radius and the covariance come
# from importance sampling of the posterior (.field_radius) instead of the Laplace Gaussian. Measured
# in docs/science/estimator.md (bench localize --emission bursts).
FIELD_SAMPLED_RADIUS = True


@dataclass(frozen=True)
class Candidate:
    """An alternative solution (the mirror image) at the estimate's reference time."""

    position_xy_m: np.ndarray
    velocity_m_s: np.ndarray
    relative_likelihood: float  # posterior mass relative to the estimate (Laplace)
    radius95_m: float
    covariance: np.ndarray = field(repr=False)  # 4x4 (x, y, vx, vy)

    @property
    def holds_mass(self) -> bool:
        """Whether it holds more than AMBIGUITY_MASS of the two candidates' posterior mass (then
        the 95 % circle must reach over it)."""
        return self.relative_likelihood / (1 + self.relative_likelihood) > AMBIGUITY_MASS


@dataclass(frozen=True)
class Estimate:
    emitter_id: int
    status: str  # "ok" | "not_enough_data"
    t_ref_s: float
    position_xy_m: np.ndarray  # (2,) local ENU at t_ref_s [m]
    velocity_m_s: np.ndarray  # (2,) [m/s]
    covariance: np.ndarray = field(repr=False)  # 4x4 over (x, y, vx, vy) at t_ref_s
    radius95_m: float = math.inf  # calibrated, includes the mirror when ambiguous [m]
    annulus_bound_m: float = math.inf  # the paper's bound [m]; NaN when the rings do not intersect
    ambiguous: bool = False
    mirror: Candidate | None = None
    n_slots: int = 0
    last_slot_t_s: float = math.nan
    tx_offset_db: float = 0.0
    mode_radius95_m: float = math.inf
    max_speed_m_s: float = 0.0
    model_motion: bool = True
    inflation: float = 1.0  # information deflation applied (1 = i.i.d. model held)
    process_noise_m2_s3: float = 0.0  # maneuver intensity q per axis (see .maneuver); 0 = pure CV
    log_mass: float = math.nan  # the estimate's mode: Laplace log posterior mass (model prior included)

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def predict(self, t_s: float) -> tuple[np.ndarray, float]:
        """Predicted position (2,) and 95 % radius [m] at time t_s.

        Moving model: the constant-velocity extrapolation with its covariance plus the maneuver
        process noise (turns, stops: ``process_noise_m2_s3``, see :mod:`.maneuver`), and with the
        maneuver model at least the current radius + v_max |dt| (every stop, and every turn that
        leaves the person within v_max |dt| of the CV prediction, is covered whatever its timing),
        but never more than the reach of the speed bound (the current radius + (|v| + v_max) |dt|),
        which holds whatever the person does. Static model: the radius grows by v_max |dt|.
        """
        q = self.process_noise_m2_s3
        pos, r, cov2 = _predict_mode(self.position_xy_m, self.velocity_m_s, self.covariance, self.mode_radius95_m,
                                     t_s - self.t_ref_s, self.max_speed_m_s, self.model_motion, q)
        m = self.mirror
        if m is not None and (self.ambiguous or m.holds_mass):
            mpos, mr, mcov2 = _predict_mode(m.position_xy_m, m.velocity_m_s, m.covariance, m.radius95_m,
                                            t_s - self.t_ref_s, self.max_speed_m_s, self.model_motion, q)
            r = _pair_radius(pos, cov2, r, mpos, mcov2, mr, m.relative_likelihood, self.ambiguous)
        return pos, r


def _pair_radius(pos, cov, r, mpos, mcov, mr, rel: float, ambiguous: bool) -> float:
    """The 95 % radius about ``pos`` of the estimate's mode (covariance ``cov``, own radius ``r``)
    and a second mode holding ``rel`` times its mass (see MIXTURE_RADIUS). Each mode's Gaussian is
    scaled to its own radius, which carries what the covariance does not (a static person's walk
    since the data, the floors of a prediction). An ``ambiguous`` pair (the second mode outside the
    estimate's own circle) is always covered whole: how the mass splits between two sides of a
    pass rests on what the motion model says of turns, the least certain part of the estimate."""
    apart = float(np.linalg.norm(np.asarray(mpos) - np.asarray(pos)))
    if ambiguous or not MIXTURE_RADIUS or not (math.isfinite(r) and math.isfinite(mr)):
        return max(r, apart + mr)
    w = rel / (1.0 + rel)
    return mixture_radius(pos, [(1.0 - w, pos, _scaled(cov, r)), (w, mpos, _scaled(mcov, mr))])


def _scaled(cov2: np.ndarray, r: float) -> np.ndarray:
    """``cov2`` scaled so that its centred 95 % circle has radius ``r``."""
    g = radius_of_probability(cov2)
    if not (math.isfinite(g) and g > 0):
        return np.eye(2) * (r / math.sqrt(-2.0 * math.log(0.05))) ** 2
    return np.asarray(cov2, float) * (r / g) ** 2


def _predict_mode(p, v, cov, r0, dt, vmax, moving, q=0.0) -> tuple[np.ndarray, float, np.ndarray]:
    """One mode dt later: position, 95 % radius and the 2x2 position covariance (its shape, for
    _pair_radius; the radius carries the floors and caps below)."""
    if not math.isfinite(r0):
        return p + v * dt, math.inf, cov[:2, :2]
    if not moving:
        return p.copy(), r0 + vmax * abs(dt), cov[:2, :2]
    a = np.eye(4)
    a[0, 2] = a[1, 3] = dt
    c = a @ cov @ a.T + state_noise(q, dt)
    r = radius_of_probability(c[:2, :2])
    if q > 0:  # a stop or a turn at any moment moves the person off the CV prediction
        r = max(r, r0 + vmax * abs(dt))
    r = min(r, r0 + (float(np.hypot(*v)) + vmax) * abs(dt))
    return p + v * dt, max(r, r0 if dt == 0 else 0.0), c[:2, :2]


def estimate_emitter(
    slots: SlotBatch,
    channel: ChannelModel,
    *,
    max_speed_m_s: float,
    t_ref_s: float | None = None,
    model_motion: bool = True,
    estimate_tx_power: bool = False,
    previous: "Estimate | None" = None,
    maneuver_time_s: float = MANEUVER_TIME_S,
    silence: Silence | None = None,
    censored: Censored | None = None,
    ground=None,
) -> Estimate:
    """Estimate one emitter from its slots (all rows must carry the same emitter id).

    ``t_ref_s`` defaults to the last slot's time. ``model_motion=False`` is the paper's NM variant
    (static person). ``previous`` (the last estimate of this emitter) only adds a start point.
    Too few slots (fewer than 3, or fewer than 3 observations once slots of one vehicle within
    0.1 s are merged) give ``status="not_enough_data"``, not an exception.

    ``maneuver_time_s`` sets the maneuver process noise q = v_max^2 / maneuver_time_s (people turn
    and stop; see :mod:`.maneuver`): slots far in time from ``t_ref_s`` may have left the
    constant-velocity line and are down-weighted accordingly. ``math.inf`` is the pure CV model.

    ``silence`` (opt-in; ``Silence.empty()`` for none recorded) makes the hearing itself evidence
    (:mod:`.evidence`), with a finite ``channel.comm_range_m``: every slot heard puts the person
    within range of the vehicle then, every silence outside it; the candidates are refitted under
    these soft constraints. Off (``None``) by default: measured, it also lets a sharp turn pick the
    wrong mirror of a single look pass more often (test_maneuver.py). Under a receiver threshold
    (``channel.sensitivity_dbm`` set: the field world) there is no sure range and ``silence`` is
    not used; ``censored`` takes its place.

    Under a receiver threshold the heard slots' likelihood is that of frames heard above it (a
    truncated normal, see :mod:`.fit`), and ``censored`` (from :func:`.evidence.censored_silence`:
    vehicles that listened while the phone sent a burst another vehicle heard, and heard nothing)
    adds the probability of hearing none of the frames sent. ``censored`` needs the threshold.

    ``ground`` (over terrain, from :mod:`.terrain_fit`): ``ground(t_s, xy)`` gives how much higher
    the ground is at positions xy (N, 2) at times t_s than where the slots' heights above the
    person were taken, and its gradient there (N, 2): the fit keeps the person on the ground
    wherever it moves them (the heard slots; censored rows and silences keep their heights).
    """
    if max_speed_m_s < 0 or not math.isfinite(max_speed_m_s):
        raise EstimationError(f"max_speed_m_s must be a finite non-negative number, got {max_speed_m_s}")
    if censored is not None and len(censored) and channel.sensitivity_dbm is None:
        raise EstimationError("censored silences need a receiver threshold (ChannelModel.sensitivity_dbm)")
    ids = np.unique(slots.emitter_id)
    if len(ids) > 1:
        raise EstimationError(f"estimate_emitter got slots of {len(ids)} emitters; use estimate_all")
    good = np.isfinite(slots.rssi_dbm) & np.isfinite(slots.t_s) & np.all(np.isfinite(slots.xyz_m), axis=1)
    slots = slots.take(good)
    emitter = int(ids[0]) if len(ids) else -1
    last = float(slots.t_s.max()) if len(slots) else math.nan
    t_ref = last if t_ref_s is None else float(t_ref_s)
    moving = bool(model_motion) and max_speed_m_s > 0
    if len(slots) < MIN_SLOTS:
        return _not_enough(emitter, slots, t_ref, last, max_speed_m_s, moving)
    data = prepare(slots, channel, height_floor=ground is None)
    if len(data.t_s) < MIN_SLOTS:  # e.g. three slots within 0.1 s are one observation
        return _not_enough(emitter, slots, t_ref, last, max_speed_m_s, moving)
    if ground is not None:
        data = replace(data, ground=ground)
    q = intensity_m2_s3(max_speed_m_s, maneuver_time_s) if moving else 0.0
    t_anchor = min(max(t_ref, float(data.t_s.min())), float(data.t_s.max()))
    main = _solve(data, channel, q, t_anchor, moving, bool(estimate_tx_power), float(max_speed_m_s),
                  previous, silence, censored=censored)
    if not main.problem.tx and _power_contradicted(main.problem, main.modes[0], main.factor):
        log.info("emitter %d: the data contradict the nominal transmit power; estimating it", emitter)
        return estimate_emitter(slots, channel, max_speed_m_s=max_speed_m_s, t_ref_s=t_ref_s,
                                model_motion=model_motion, estimate_tx_power=True, previous=previous,
                                maneuver_time_s=maneuver_time_s, silence=silence, censored=censored,
                                ground=ground)
    solutions = [(main, 0.0)]
    lag = t_anchor - float(data.t_s.min())
    if TURN_MIXTURE and main.problem.passes is not None and lag > 0 and math.isfinite(maneuver_time_s):
        # the person may have turned since the oldest data: a second model in which the old
        # passes tie the present state only through the speed bound (see TURN_MIXTURE)
        no_turn, a_turn = _turn_log_prior(lag, maneuver_time_s)
        q_turn = 3.0 * max_speed_m_s**2 / lag
        if q_turn > q:
            turned = _solve(data, channel, q_turn, t_anchor, moving, main.problem.tx,
                            float(max_speed_m_s), previous, silence, censored=censored)
            solutions = [(main, no_turn), (turned, a_turn)]
    # the two models of a turn are alternatives, not parts of one prior: with both switches on,
    # the turn mixture is used
    elif TURN_JUMP and main.problem.passes is not None and lag > 0 and math.isfinite(maneuver_time_s):
        solutions = _with_turns(main, data, channel, t_anchor, moving, float(max_speed_m_s), previous, silence,
                                lag, maneuver_time_s, censored)
    entries = _candidates(solutions, moving, t_ref - data.t_c)
    top = entries[0]
    sol, theta, pos, vel, cov, logmass = top.solution, top.theta, top.pos, top.vel, top.cov, top.logmass
    problem, factor = sol.problem, sol.factor
    # beyond the data (t_ref outside their span) the person may have maneuvered since the anchor
    extra = state_noise(sol.q, t_ref - t_anchor)
    cov = cov + extra
    q = sol.q
    beta = theta[problem.beta_index] if problem.tx else 0.0
    mode_r = _mode_radius(cov, moving, max_speed_m_s, t_ref - data.t_c)
    # where the phone was heard at all bounds everything, e.g. the lateral error right under a track
    # (over terrain the ground under the person changes each slot's disc wherever they are: the
    # discs are taken at their widest, the person as high as the vehicle, which still bounds)
    reach = reach_bound_m(pos, t_ref, data.t_s, data.a_xy, data.h_m if data.ground is None else 0.0 * data.h_m,
                          channel.gate_m, max_speed_m_s)
    mirror = None
    if len(entries) > 1:
        other = entries[1]
        m_cov = other.cov + state_noise(other.solution.q, t_ref - t_anchor)
        rel = float(math.exp(min(other.logmass - logmass, 0.0)))
        mirror = Candidate(other.pos, other.vel, rel, _mode_radius(m_cov, moving, max_speed_m_s, t_ref - data.t_c),
                           m_cov)
    # a second mode holding more than AMBIGUITY_MASS must be inside the 95 % circle; it is an
    # alternative a look has to rule out (``ambiguous``) only when it lies outside the estimate's
    # own circle: the hearing constraints can split one mode into near twins a few metres apart
    radius = mode_r
    ambiguous = False
    if mirror is not None and mirror.holds_mass:
        apart = float(np.linalg.norm(mirror.position_xy_m - pos))
        ambiguous = apart > mode_r
        radius = _pair_radius(pos, cov[:2, :2], mode_r, mirror.position_xy_m, m_cov[:2, :2], mirror.radius95_m, rel,
                              ambiguous)
    if math.isfinite(reach):
        radius, mode_r = min(radius, reach), min(mode_r, reach)
    if channel.sensitivity_dbm is not None and FIELD_SAMPLED_RADIUS:
        # a few bursts near the threshold: the posterior bends along rings, the Laplace circle is
        # far too large (see .field_radius); the radius and covariance from the posterior itself
        modes = [(np.concatenate([pos, vel]), cov)]
        if mirror is not None:
            modes.append((np.concatenate([mirror.position_xy_m, mirror.velocity_m_s]), m_cov))
        sampled = sampled_posterior(problem, modes, t_ref, pos, factor, beta)
        if sampled is not None:
            radius, cov, _ = sampled
            mode_r = radius
    bound = annulus_bound_m(pos, t_ref, data.t_s, data.a_xy, data.h_m, data.y + beta, data.n_samples,
                            channel.log_range_sigma, max_speed_m_s)
    return Estimate(
        emitter, "ok", t_ref, pos, vel, cov, radius, bound, ambiguous, mirror, len(slots), last,
        beta / channel.nepers_per_db, mode_r, float(max_speed_m_s), moving, factor, q, float(logmass),
    )


@dataclass
class _Solution:
    """The modes of one motion model: its problem (hearing bounds included), modes best first by
    Laplace mass, their (covariance, log mass), and the model's maneuver intensity q."""

    problem: Problem
    modes: list
    laplace: list
    factor: float
    q: float


@dataclass
class _Entry:
    """One mode of one motion model moved to t_ref, with its mass under the model's prior."""

    solution: _Solution
    theta: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    cov: np.ndarray  # 4x4 at t_ref, before the maneuver noise beyond the data
    logmass: float


def _with_turns(main: "_Solution", data, channel: ChannelModel, t_anchor: float, moving: bool, vmax: float,
                previous: "Estimate | None", silence: Silence | None, lag: float,
                maneuver_time_s: float, censored: Censored | None = None) -> list[tuple["_Solution", float]]:
    """The main model and one model per turn time (see TURN_JUMP), with their log prior masses."""
    t = data.t_s[data.t_s <= t_anchor]
    gaps = np.diff(t)
    big = np.flatnonzero(gaps > TURN_GAP_MIN_S)
    if len(big) == 0:
        return [(main, 0.0)]
    big = np.sort(big[np.argsort(-gaps[big])][:TURN_GAPS])
    times = 0.5 * (t[big] + t[big + 1])
    # each turn time stands for the turns nearer to it than to another (between the oldest data and the anchor)
    edges = np.concatenate([[t[0]], 0.5 * (times[1:] + times[:-1]), [t_anchor]])
    share = np.diff(edges) / lag
    no_turn, a_turn = _turn_log_prior(lag, TURN_TIME_S or maneuver_time_s)
    out = [(main, no_turn)]
    for t_k, w in zip(times, share):
        if w <= 0:
            continue
        seeds = [np.concatenate([theta, np.zeros(2)]) for theta, _ in main.modes] if TURN_STARTS_FROM_MAIN else None
        turned = _solve(data, channel, main.q, t_anchor, moving, main.problem.tx, vmax, previous, silence,
                        turn_at_s=float(t_k), starts=seeds, censored=censored)
        out.append((turned, a_turn + math.log(w)))
    return out


def _turn_log_prior(lag_s: float, turn_time_s: float) -> tuple[float, float]:
    """ln P(no turn) and ln P(a turn) within ``lag_s`` for turns every ``turn_time_s`` on average
    (a Poisson process), without forming 1 - exp(-lag / T): that rounds to 1 beyond about 37 T
    (two hours of data at T = 200 s), and ln(1 - 1) ended a whole search with a math domain
    error (tests/test_e2e_vehicle_faults.py, 7,600 s of one person's slots)."""
    x = lag_s / turn_time_s
    return -x, math.log(-math.expm1(-x))


def _solve(data, channel: ChannelModel, q: float, t_anchor: float, moving: bool, tx: bool, vmax: float,
           previous: "Estimate | None", silence: Silence | None, turn_at_s: float | None = None,
           starts: list[np.ndarray] | None = None, censored: Censored | None = None) -> _Solution:
    """Every mode of the data under the maneuver intensity q (and a turn at ``turn_at_s``, see
    TURN_JUMP), refitted under the hearing bounds. ``starts`` (best first) replace the start
    grid, the constant-velocity start and ``previous``: a turn model starts from the main model's
    modes (see TURN_STARTS_FROM_MAIN)."""
    passes = find_passes(data.t_s, t_anchor, q)
    problem = Problem(data, moving, tx, vmax, TX_PRIOR_SIGMA_DB * channel.nepers_per_db,
                      passes, offset_tail=MANEUVER_TAIL_DOF,
                      turn_at_s=turn_at_s if passes is not None and moving else None,
                      turn_sigma_m_s=max(TURN_SIGMA_FRACTION * vmax, 1e-3),
                      threshold_y=channel.threshold_log_range, log_range_sigma=channel.log_range_sigma,
                      censored=censored_rows(censored, data, passes) if channel.sensitivity_dbm is not None else None)
    if starts is not None and len(starts) and len(starts[0]) == problem.size:
        modes = _distinct_modes(problem, list(starts), mirrors=TURN_MIRRORS)
    else:
        modes = _distinct_modes(problem, _fresh_starts(problem, data, channel, moving, previous))
    heard_xyz = np.column_stack([data.a_xy, data.h_m])
    heard_pass = problem.passes.index if problem.passes is not None else np.full(len(data.t_s), -1)
    heard_mid = np.where(heard_pass >= 0, t_anchor + (problem.passes.lags_s[heard_pass] if problem.passes is not None
                                                     else 0.0), data.t_s)
    bounds = build_bounds(data.t_c, t_anchor, data.t_s, heard_xyz, heard_pass, heard_mid, silence,
                          channel.gate_m, q,
                          np.array([m[0][:2] for m in modes]), vmax, moving, ground=data.ground)
    if bounds is not None and silence is not None:
        problem = replace(problem, bounds=bounds)
        modes = _refit_bounded(problem, modes)
    factor = inflation_factor(problem, modes[0][0])
    laplace = [_laplace(problem, theta, cost, factor) for theta, cost in modes]
    order = np.argsort([-lm for _, lm in laplace])
    return _Solution(problem, [modes[i] for i in order], [laplace[i] for i in order], factor, q)


def _fresh_starts(problem: Problem, data, channel: ChannelModel, moving: bool,
                  previous: "Estimate | None") -> list[np.ndarray]:
    """Start points of a model fitted from scratch, best first: ``previous`` (warm), the
    constant-velocity fit from the best grid start (with the maneuver model), the grid."""
    starts = start_points(problem)
    if problem.passes is not None:
        # the CV fit from the best start first: with free pass offsets the maneuver fit has more
        # local optima, and the straight-line solution is the natural place to begin
        cv = replace(problem, passes=None, offset_tail=None, turn_at_s=None, bounds=None)
        first = np.zeros(problem.size)
        first[: problem.base_size] = cv.fit(starts[0][: problem.base_size])[0]
        starts.insert(0, first)
    if previous is not None and previous.ok:
        warm = np.zeros(problem.size)
        warm[:2] = previous.position_xy_m + previous.velocity_m_s * (data.t_c - previous.t_ref_s)
        if moving:
            warm[2:4] = previous.velocity_m_s
        if problem.tx:
            warm[problem.beta_index] = previous.tx_offset_db * channel.nepers_per_db
        starts.insert(0, warm)
    return starts


def _offset_prior_norm(problem: Problem) -> float:
    """Log normalisation of the pass offsets' Gaussian prior (both axes), without the 2 pi terms,
    which cancel against the Laplace volume's: what makes the log masses of two motion models
    with different offset priors comparable."""
    if problem.passes is None:
        return 0.0
    norm = 2.0 * float(np.sum(np.log(np.abs(np.diag(problem.passes.whiten)))))
    if problem.turn_at_s is not None:  # the turn's velocity change, Gaussian on both axes
        norm -= 2.0 * math.log(problem.turn_sigma_m_s)
    if problem.offset_tail is not None:  # the t's normalisation beyond the Gaussian's, d = 2m, c = dof + d
        nu, d = problem.offset_tail, 2.0 * problem.passes.count
        norm += math.lgamma(0.5 * (nu + d)) - math.lgamma(0.5 * nu) - 0.5 * d * math.log(0.5 * (nu + d))
    return norm


def _candidates(solutions: list[tuple[_Solution, float]], moving: bool, dt: float) -> list[_Entry]:
    """The modes of all motion models at t_ref, by posterior mass (model prior included), best
    first; modes of different models closer than ``PROBE_MERGE_M`` are one candidate with the
    mixture's mean covariance (the heavier's state)."""
    entries = []
    for sol, log_prior in solutions:
        norm = _offset_prior_norm(sol.problem) if len(solutions) > 1 else 0.0
        for (theta, _), (cov_c, logmass) in zip(sol.modes, sol.laplace):
            pos, vel, cov = _at(theta, cov_c, moving, dt)
            entries.append(_Entry(sol, theta, pos, vel, cov, logmass + norm + log_prior))
    entries.sort(key=lambda e: -e.logmass)
    out: list[_Entry] = []
    for e in entries:
        twin = next((o for o in out if (not TWINS_ACROSS_MODELS_ONLY or o.solution is not e.solution)
                     and float(np.linalg.norm(o.pos - e.pos)) < PROBE_MERGE_M), None)
        if twin is None:
            out.append(e)
            continue
        w = 1.0 / (1.0 + math.exp(min(twin.logmass - e.logmass, 700.0)))  # e's share of the pair
        d = np.concatenate([e.pos - twin.pos, e.vel - twin.vel])  # a static model's velocity is zero
        twin.cov = (1 - w) * twin.cov + w * e.cov + w * (1 - w) * np.outer(d, d)
        twin.logmass = float(np.logaddexp(twin.logmass, e.logmass))
    out.sort(key=lambda e: -e.logmass)
    return out


def estimate_all(slots: SlotBatch, channel: ChannelModel, *, max_speed_m_s: float,
                 previous: "dict[int, Estimate] | None" = None,
                 censored: "dict[int, Censored] | None" = None, **options) -> dict[int, Estimate]:
    """:func:`estimate_emitter` for every emitter id in ``slots``, keyed by id; ``censored``: each
    emitter's censored observations by id (see :func:`.evidence.censored_silence`), none for an id
    it lacks."""
    previous = previous or {}
    censored = censored or {}
    out = {}
    for e in slots.emitters():
        out[int(e)] = estimate_emitter(slots.for_emitter(e), channel, max_speed_m_s=max_speed_m_s,
                                       previous=previous.get(int(e)), censored=censored.get(int(e)), **options)
    return out


def _at(theta, cov_c, moving: bool, dt: float):
    """State and 4x4 covariance moved from the fit's reference time by dt."""
    cov = np.zeros((4, 4))
    if moving:
        a = np.eye(4)
        a[0, 2] = a[1, 3] = dt
        pos = theta[:2] + theta[2:4] * dt
        cov = a @ cov_c[:4, :4] @ a.T
        return pos, theta[2:4].copy(), cov
    cov[:2, :2] = cov_c[:2, :2]
    return theta[:2].copy(), np.zeros(2), cov


def _mode_radius(cov: np.ndarray, moving: bool, vmax: float, dt: float) -> float:
    r = radius_of_probability(cov[:2, :2])
    # static model: the person may have walked since the data's centre time
    return r if moving else r + vmax * abs(dt)


def _not_enough(emitter, slots, t_ref, last, vmax, moving) -> Estimate:
    pos = np.mean(slots.xyz_m[:, :2], axis=0) if len(slots) else np.full(2, np.nan)
    return Estimate(emitter, "not_enough_data", t_ref, pos, np.zeros(2), np.full((4, 4), np.nan),
                    math.inf, math.inf, False, None, len(slots), last, 0.0, math.inf, float(vmax), moving)
