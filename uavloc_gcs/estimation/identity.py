"""Linking the addresses heard into people (SPEC §1.1 "Identity").

A real sensor hears 802.11 source addresses, not people: most phones send every probe burst under
a new random (locally administered) address, phones of one model share a content fingerprint, and
some keep one address for ever. :func:`link` groups the addresses into people from what the ground
knows, and relabels the slots so that ``emitter_id`` is a person:

- **address**: one address is one device, so every burst under an address heard before belongs to
  that address's person (a stable address links its own bursts, for sure);
- **fingerprint**: different nonzero fingerprints are never one person, and an address with an
  unknown fingerprint (0: old logs, the paper's world) is never linked to another one -- without a
  fingerprint nothing says two addresses are one phone; nor is a globally unique (universally
  administered, U/L bit clear) address: a phone probing under its hardware address does not
  randomise;
- **where and when**: a slot heard at vehicle position ``a`` [m] with mean RSSI ``r`` over ``n``
  frames puts the phone within the ground annulus about ``a`` whose radii are the ranges at which
  ``r`` would be exceeded (inner) or not reached (outer) with probability :data:`BOUND_PROBABILITY`
  under the channel model (log-range std ``s / sqrt(n)``, n at most MAX_INDEPENDENT_FRAMES; under
  a receiver sensitivity the outer range of a reading given that it was heard; plus a
  transmit-power margin when phones differ; capped at ``channel.gate_m``, the paper world's sure
  range). Two bursts can be one person only when their annuli, grown by ``max_speed_m_s * dt``,
  intersect. A person is a candidate for a new burst only when every burst of theirs passes it;
- **streams**: a phone sends one probe burst at a time, each at most a few seconds long, and
  answers an on-board access point under the one address it uses for that network, so two bursts
  under different addresses heard at once for more than :data:`CONCURRENT_S`, or both longer than
  that, are two phones.

Among the candidates (and "a new person") the most likely is chosen: each linkable person carries
a particle belief of where they are (moved uniformly within ``max_speed_m_s * dt`` between bursts,
weighed by each burst's likelihood, the heard frames' density truncated at the receiver's
sensitivity); a candidate is scored by the burst's likelihood averaged over their moved particles,
a new person by its likelihood integrated over the plane divided by the area (``area_m2``) times
the prior odds :data:`LOG_NEW_PERSON_ODDS`; a candidate whose last burst ended within
:data:`CONTINUATION_S` gets :data:`CONTINUATION_LOG_ODDS` (one burst sent under several
addresses). When the runner-up scores at least :data:`UNCERTAIN_RATIO` of the best, the link is
kept but marked uncertain with a reason naming the alternative. Fingerprints alone never merge two
people: two same-fingerprint phones heard 300 m apart at once are two.

Stable ids: bursts are decided in time order from what was heard up to them, and a person's id is
the first address heard of them, so appending later bursts never relabels earlier ones (the daemon
re-links on every update and keeps its per-person state). Slots that arrive late with earlier
times, or the rest of a burst whose first slots were already linked, can change the decision.
``link(..., previous=)`` resumes from the last update's decisions when they still hold. With every
address stable, or every fingerprint 0, linking is the identity: person = address.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field

import numpy as np

from ..observations import SlotBatch
from .model import ChannelModel

# Probability with which one slot's range bound may be wrong (each side).
BOUND_PROBABILITY = 1e-3
_Z_BOUND = 3.090232306167813  # ndtri(1 - BOUND_PROBABILITY)
# Slots of one address more than this apart [s] are separate bursts (a burst lasts ~1-2 s, phones
# send one every 20-270 s; a continuous emitter's passes are its "bursts").
BURST_GAP_S = 5.0
# A runner-up scoring at least this fraction of the chosen hypothesis makes the link uncertain.
UNCERTAIN_RATIO = 0.2
# The area a new person could be anywhere in, when the caller does not say (the paper's 1120 x 640 m).
DEFAULT_AREA_M2 = 1120.0 * 640.0
# How much louder or quieter than nominal a phone may transmit [dB] when nothing says (real phones
# differ by several dB, SPEC 1; twice the simulated field world's 3 dB spread; the estimator's
# TX_PRIOR_SIGMA_DB). ``uavloc localize`` links with it.
UNKNOWN_TX_MARGIN_DB = 6.0
# Reasons kept per person (the first ones; later ones are counted).
MAX_REASONS = 3
# Slots of a burst used in its likelihood (its tightest ones) and particles per person.
MAX_ROWS = 4
PARTICLES = 64
# A slot's mean RSSI counts as at most this many independent frames: a burst's frames share most
# of their shadowing, and the mean of the frames above a threshold is biased loud.
MAX_INDEPENDENT_FRAMES = 4
# Prior log odds of "a new person" against each known candidate of the same fingerprint. Measured
# on bench identity's own worlds (10-50 people, 2-11 models): 0 reports 4-10x the people heard, -2
# about as many as heard; the share of bursts on the wrong person rises from ~16 % to ~40 % with it
# (few bursts tell same-model people apart; splitting is the other error).
LOG_NEW_PERSON_ODDS = -2.0
# A new address within this many seconds of a person's last burst is, a priori, e^3 times likelier
# theirs (one burst under several addresses; sim_link's fast-rotating models do it). Measured on
# sim_link's field world (4 worlds, 10-50 people): splits + merges 264 instead of 385, wrong bursts
# 47.9 % instead of 48.1 %.
CONTINUATION_S = 2.0
CONTINUATION_LOG_ODDS = 3.0
# Two bursts under different addresses heard at the same time for longer than this [s] are two
# phones, and so are two bursts under different addresses that both last longer. A probe burst
# lasts at most about 3 s (80 frames 40 ms apart, sim_link's fitted maximum), and a phone sends one
# at a time; what is heard longer is a phone answering an on-board access point
# (``emission.elicitation_rate_hz``) under the one address it uses for that network. Without
# this, same-model phones answering at once were linked into one person: `uavloc demo` of the field
# world with a 2 Hz access point merged 7 of 10 phones into 3 "people" and located none.
CONCURRENT_S = 4.0
_SEED = 0x1D
_RADIAL_NODES = 128
_HALF_LN_2PI = 0.5 * math.log(2.0 * math.pi)


def format_address(address: int) -> str:
    """'aa:bb:cc:dd:ee:ff' of a 48-bit address given as an integer."""
    a = int(address) & 0xFFFF_FFFF_FFFF
    return ":".join(f"{(a >> s) & 0xFF:02x}" for s in range(40, -8, -8))


def parse_address(text: str) -> int:
    """The integer of 'aa:bb:cc:dd:ee:ff' (or '-' separated); ValueError when malformed."""
    parts = text.strip().replace("-", ":").split(":")
    if len(parts) != 6 or not all(len(p) == 2 for p in parts):
        raise ValueError(f"not a MAC address: {text!r}")
    return int("".join(parts), 16)


def is_locally_administered(address: int) -> bool:
    """Whether the address has the U/L bit set (random addresses are locally administered)."""
    return bool((int(address) >> 40) & 0x02)


def person_name(person: int) -> str:
    """How a person is named in logs: the first address heard of them as a MAC when it is one (the
    field world's ids are 48-bit addresses), else the plain emitter id (the paper's world, old logs)."""
    p = int(person)
    return format_address(p) if p >= 1 << 32 else str(p)


def format_addresses(addresses, sep: str = ";") -> str:
    """The addresses as MACs joined by ``sep`` (e.g. a CSV cell)."""
    return sep.join(format_address(a) for a in addresses)


@dataclass(frozen=True)
class Linking:
    """The result of :func:`link`. ``slots`` are the input slots (same order) with ``emitter_id``
    the person; ``burst_index`` (N,) numbers each slot's burst (bursts in time order)."""

    slots: SlotBatch
    burst_index: np.ndarray
    _addresses: dict = field(repr=False)  # person -> tuple of addresses, in the order first heard
    _reasons: dict = field(repr=False)  # person -> list of reasons its links are uncertain
    _state: "_Linker | None" = field(default=None, repr=False, compare=False)  # to resume from

    def people(self) -> list[int]:
        """Person ids, ascending."""
        return sorted(self._addresses)

    def addresses(self, person: int) -> list[int]:
        """The addresses a person was heard under, in the order first heard (the first is the id)."""
        return list(self._addresses.get(int(person), ()))

    def uncertain(self, person: int) -> str | None:
        """Why one of this person's links is uncertain, or None when every link is sure."""
        reasons = self._reasons.get(int(person))
        if not reasons:
            return None
        text = "; ".join(reasons[:MAX_REASONS])
        return text + (f" (and {len(reasons) - MAX_REASONS} more)" if len(reasons) > MAX_REASONS else "")

    def link_state(self, person: int) -> str:
        """'uncertain' or 'sure' (for the output files)."""
        return "uncertain" if self.uncertain(person) else "sure"

    @property
    def n_bursts(self) -> int:
        return int(self.burst_index.max()) + 1 if len(self.burst_index) else 0


def identity_linking(slots: SlotBatch) -> Linking:
    """Every address its own person (what :func:`link` gives when no fingerprint is known)."""
    burst = burst_index(slots)
    addrs = {int(a): (int(a),) for a in np.unique(slots.address)}
    return Linking(slots.with_emitter_ids(slots.address), burst, addrs, {})


def link(slots: SlotBatch, channel: ChannelModel, *, max_speed_m_s: float, area_m2: float | None = None,
         tx_margin_db: float = 0.0, previous: Linking | None = None) -> Linking:
    """Link the addresses in ``slots`` into people (see the module docstring).

    ``max_speed_m_s``: the people's speed bound [m/s]; ``area_m2``: the search area [m²] (where a
    person not heard yet could be; default :data:`DEFAULT_AREA_M2`); ``tx_margin_db``: how much
    louder or quieter than ``channel.reference_power_dbm`` a phone may transmit [dB] (widens every
    range bound). ``previous``: the linking of an earlier state of the same data (the daemon's last
    update); when its bursts are unchanged at the head of these, only the new bursts are decided
    (the result is the same as without it). Pure and deterministic.
    """
    if max_speed_m_s < 0 or not math.isfinite(max_speed_m_s):
        raise ValueError(f"max_speed_m_s must be finite and >= 0, got {max_speed_m_s}")
    if len(slots) == 0 or not np.any(slots.fingerprint != 0):
        return identity_linking(slots)
    area = DEFAULT_AREA_M2 if area_m2 is None else float(area_m2)
    if not area > 0:
        raise ValueError(f"area_m2 must be positive, got {area_m2}")
    burst = burst_index(slots)
    b = _burst_table(slots, burst, channel, tx_margin_db, math.sqrt(area))
    params = (channel, float(max_speed_m_s), area, float(tx_margin_db))
    old = previous._state if previous is not None else None
    linker = old.resumed(b, params) if old is not None else None
    if linker is None:
        linker = _Linker(b, params)
    linker.run()
    pid = np.asarray(linker.pid, dtype=np.int64)
    addresses: dict[int, list[int]] = {}
    for k in range(len(pid)):  # bursts in time order: addresses in the order first heard
        lst = addresses.setdefault(int(pid[k]), [])
        if int(b.address[k]) not in lst:
            lst.append(int(b.address[k]))
    linked = slots.with_emitter_ids(pid[burst])
    reasons = {p: list(r) for p, r in linker.reasons.items()}
    return Linking(linked, burst, {p: tuple(a) for p, a in addresses.items()}, reasons, linker)


# ---------------------------------------------------------------------------------------------


def burst_index(slots: SlotBatch) -> np.ndarray:
    """(N,) burst number of every slot: slots of one address no more than BURST_GAP_S apart form a
    burst; bursts are numbered by their first slot's time (then address)."""
    n = len(slots)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    order = np.lexsort((slots.t_s, slots.address))
    a, t = slots.address[order], slots.t_s[order]
    new = np.ones(n, dtype=bool)
    new[1:] = (a[1:] != a[:-1]) | (np.diff(t) > BURST_GAP_S)
    raw = np.cumsum(new) - 1  # per sorted slot
    starts = np.flatnonzero(new)
    rank = np.lexsort((a[starts], t[starts]))  # bursts by first time, then address
    number = np.empty(len(starts), dtype=np.int64)
    number[rank] = np.arange(len(starts))
    out = np.empty(n, dtype=np.int64)
    out[order] = number[raw]
    return out


@dataclass(frozen=True)
class _Bursts:
    """Per burst (time order): first/last time [s], address, fingerprint, the ground annulus of its
    tightest slot (centre (2,), inner and outer radius [m]) for the gate, and up to MAX_ROWS of its
    tightest slots for the likelihood: vehicle ground position (B, R, 2), height (B, R), observed
    ln range (B, R) and its std (B, R); unused rows have ``row_used`` False (row 0 always used)."""

    t0: np.ndarray
    t1: np.ndarray
    n_slots: np.ndarray
    address: np.ndarray
    fingerprint: np.ndarray
    xy: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    row_xy: np.ndarray
    row_h: np.ndarray
    row_y: np.ndarray
    row_s: np.ndarray
    row_n: np.ndarray
    row_used: np.ndarray
    y_sens: float  # ln of the range at which the median RSSI is the receiver's sensitivity (inf: none)
    s_frame: float  # std of one frame's ln range
    max_ground_m: float  # farthest ground range a new phone is looked for at (the area's side)
    gate_m: float  # the channel's sure 3-D range (inf: none)


def ground_bounds(slots: SlotBatch, channel: ChannelModel, tx_margin_db: float = 0.0, *, threshold: bool = True):
    """Per slot, the ground ranges [m] (inner, outer) within which the phone is unless the slot's
    RSSI is a ``BOUND_PROBABILITY`` accident on either side. Each slot counts as
    MAX_INDEPENDENT_FRAMES frames at most (frames of one burst share most of their shadowing).
    Under a receiver sensitivity the outer range is that of the reading given that it was heard:
    ``P(ln r <= y | u, heard) = Phi((y - u)/s) / Phi((y_S - u)/s) = BOUND_PROBABILITY`` (a phone far
    out is heard only when loud), infinite for a reading at the threshold (``threshold=False``:
    as if there were none)."""
    from scipy.special import log_ndtr

    s_eff = channel.log_range_sigma / np.sqrt(_n_eff(slots.n_samples))
    ln_d = channel.log_range(slots.rssi_dbm)
    margin = abs(tx_margin_db) * channel.nepers_per_db
    ln_hi = ln_d + _Z_BOUND * s_eff
    y_sens = channel.threshold_log_range if threshold else None
    if y_sens is not None:
        s1 = channel.log_range_sigma
        target = math.log(BOUND_PROBABILITY)
        lo_u, hi_u = ln_hi.copy(), ln_d + 40.0 * s1
        for _ in range(40):  # bisection: the ratio falls as the true range u grows
            mid = 0.5 * (lo_u + hi_u)
            f = log_ndtr((ln_d - mid) / s_eff) - _n_eff(slots.n_samples) * log_ndtr((y_sens - mid) / s1)
            below = f < target
            hi_u = np.where(below, mid, hi_u)
            lo_u = np.where(below, lo_u, mid)
        ln_hi = np.where(ln_d >= y_sens, np.inf, hi_u)
    with np.errstate(over="ignore"):
        d_hi = np.minimum(np.exp(ln_hi + margin), channel.gate_m)
    d_lo = np.minimum(np.exp(ln_d - _Z_BOUND * s_eff - margin), d_hi)
    h2 = slots.xyz_m[:, 2] ** 2
    return np.sqrt(np.maximum(d_lo * d_lo - h2, 0.0)), np.sqrt(np.maximum(d_hi * d_hi - h2, 0.0))


def _burst_table(slots: SlotBatch, burst: np.ndarray, channel: ChannelModel, tx_margin_db: float,
                 max_ground_m: float) -> _Bursts:
    # rank a burst's slots by their outer bound without the threshold (cheap), then bound the
    # tightest one properly
    _, hi = ground_bounds(slots, channel, tx_margin_db, threshold=False)
    nb = int(burst.max()) + 1
    # every burst's slots, tightest first: sort by (burst, outer radius)
    order = np.lexsort((hi, burst))
    sb = burst[order]
    first = np.ones(len(order), dtype=bool)
    first[1:] = sb[1:] != sb[:-1]
    starts = np.flatnonzero(first)
    rank = np.arange(len(order)) - np.repeat(starts, np.diff(np.append(starts, len(order))))
    keep = rank < MAX_ROWS
    rows, where = order[keep], (sb[keep], rank[keep])
    rep = order[first]
    lo_rep, hi_rep = ground_bounds(slots.take(rep), channel, tx_margin_db)
    t0 = np.full(nb, np.inf)
    np.minimum.at(t0, burst, slots.t_s)
    t1 = np.full(nb, -np.inf)
    np.maximum.at(t1, burst, slots.t_s)
    row_xy = np.zeros((nb, MAX_ROWS, 2))
    row_h = np.full((nb, MAX_ROWS), 1.0)
    row_y = np.zeros((nb, MAX_ROWS))
    row_s = np.ones((nb, MAX_ROWS))
    used = np.zeros((nb, MAX_ROWS), dtype=bool)
    row_xy[where] = slots.xyz_m[rows, :2]
    row_h[where] = np.maximum(np.abs(slots.xyz_m[rows, 2]), 1.0)
    row_y[where] = channel.log_range(slots.rssi_dbm[rows])
    tx_s = abs(tx_margin_db) * channel.nepers_per_db / 2.0  # the margin as two standard deviations
    s_frame = math.sqrt(channel.log_range_sigma ** 2 + tx_s ** 2)
    row_n = np.ones((nb, MAX_ROWS))
    row_n[where] = _n_eff(slots.n_samples[rows])
    row_s[where] = s_frame / np.sqrt(row_n[where])
    used[where] = True
    y_sens = math.inf if channel.threshold_log_range is None else channel.threshold_log_range
    return _Bursts(t0, t1, np.bincount(burst, minlength=nb), slots.address[rep], slots.fingerprint[rep],
                   slots.xyz_m[rep, :2], lo_rep, hi_rep,
                   row_xy, row_h, row_y, row_s, row_n, used, y_sens, s_frame, max_ground_m,
                   channel.gate_m)


def _n_eff(n_samples: np.ndarray) -> np.ndarray:
    """Independent samples a slot's mean RSSI is worth: its frames, at most MAX_INDEPENDENT_FRAMES."""
    return np.clip(n_samples, 1, MAX_INDEPENDENT_FRAMES).astype(float)


@dataclass
class _Belief:
    """Where a linkable person may be: PARTICLES weighted positions [m] at time ``t_s``."""

    xy: np.ndarray  # (K, 2)
    logw: np.ndarray  # (K,) normalised log weights
    t_s: float


class _Linker:
    """The decisions burst by burst, in time order, and what they need to go on (so that a later
    update resumes where the last one stopped). A linkable person's belief (particles) is built only
    when they are first a candidate for a new address, from their bursts so far. Randomness comes
    from one generator with a fixed seed drawn in time order, so the decision on a burst depends
    only on the bursts before it."""

    def __init__(self, b: _Bursts, params: tuple):
        self.b, self.params = b, params
        self.v, self.log_area = params[1], math.log(params[2])
        self.rng = np.random.default_rng(_SEED)
        self.pid: list[int] = []
        self.person_of_address: dict[int, int] = {}
        self.by_fingerprint: dict[int, list[int]] = {}
        self.beliefs: dict[int, _Belief | None] = {}  # linkable people only
        self.pending: dict[int, list[int]] = {}  # their bursts not yet in the belief
        self.reasons: dict[int, list[str]] = {}

    def resumed(self, b: _Bursts, params: tuple) -> "_Linker | None":
        """A copy to go on with over ``b``, or None when ``b`` does not begin with the bursts decided
        here, unchanged, or the parameters differ."""
        n, old = len(self.pid), self.b
        if params != self.params or len(b.t0) < n:
            return None
        same = (np.array_equal(b.address[:n], old.address[:n]) and np.array_equal(b.t0[:n], old.t0[:n])
                and np.array_equal(b.t1[:n], old.t1[:n]) and np.array_equal(b.n_slots[:n], old.n_slots[:n]))
        if not same:
            return None
        new = copy.copy(self)
        new.b = b
        new.rng = copy.deepcopy(self.rng)
        new.pid = list(self.pid)
        new.person_of_address = dict(self.person_of_address)
        new.by_fingerprint = {k: list(v) for k, v in self.by_fingerprint.items()}
        new.beliefs = dict(self.beliefs)  # beliefs are replaced, never changed in place
        new.pending = {k: list(v) for k, v in self.pending.items()}
        new.reasons = {k: list(v) for k, v in self.reasons.items()}
        return new

    def run(self) -> None:
        self._pid = np.zeros(len(self.b.t0), dtype=np.int64)
        self._pid[:len(self.pid)] = self.pid
        for k in range(len(self.pid), len(self.b.t0)):
            self.pid.append(self._decide(k))
            self._pid[k] = self.pid[-1]
            fp = int(self.b.fingerprint[k])
            if fp != 0:
                self.by_fingerprint.setdefault(fp, []).append(k)

    def _belief(self, p: int) -> _Belief:
        b, todo, bel = self.b, self.pending.pop(p, []), self.beliefs[p]
        if bel is None:
            _, xy, logw = _new_person(b, todo[0], self.rng)
            bel, todo = _updated(xy, logw, float(b.t1[todo[0]]), self.rng), todo[1:]
        for j in todo:
            _, moved, logw = _candidates_likelihood(b, j, [bel], self.v, self.rng)
            bel = _updated(moved[0], logw[0], float(b.t1[j]), self.rng)
        self.beliefs[p] = bel
        return bel

    def _decide(self, k: int) -> int:
        """The person of burst k."""
        b = self.b
        addr, fp = int(b.address[k]), int(b.fingerprint[k])
        known = self.person_of_address.get(addr)
        if known is not None:  # one address is one device
            if known in self.beliefs:
                self.pending.setdefault(known, []).append(k)
            return known
        if fp == 0 or not is_locally_administered(addr):
            # nothing to link by, or a globally unique (hardware) address: a device that uses it
            # does not randomise, so it is a person of its own
            self.person_of_address[addr] = addr
            return addr
        prior = self.by_fingerprint.get(fp)
        cands = _feasible(b, k, np.asarray(prior), self._pid, self.v) if prior else []
        if not cands:  # nobody it could be: a new person, no need to score
            self.person_of_address[addr] = addr
            self.beliefs[addr], self.pending[addr] = None, [k]
            return addr
        new_ll, new_xy, new_logw = _new_person(b, k, self.rng)
        hyps = [(new_ll - self.log_area + LOG_NEW_PERSON_ODDS, None)]
        ll, moved, logw = _candidates_likelihood(b, k, [self._belief(p) for p in cands], self.v, self.rng)
        ll = ll + _continuation_log_prior(b.t0[k] - np.array([self.beliefs[p].t_s for p in cands]))
        hyps += [(float(ll[i]), p) for i, p in enumerate(cands)]
        hyps.sort(key=lambda h: (-h[0], -1 if h[1] is None else h[1]))
        best = hyps[0][1]
        if best is None:
            person = addr
            self.beliefs[addr] = _updated(new_xy, new_logw, float(b.t1[k]), self.rng)
        else:
            person = best
            i = cands.index(best)
            self.beliefs[best] = _updated(moved[i], logw[i], float(b.t1[k]), self.rng)
        self.person_of_address[addr] = person
        if hyps[1][0] - hyps[0][0] >= math.log(UNCERTAIN_RATIO):
            alt = "a new person" if hyps[1][1] is None else f"person {format_address(hyps[1][1])}"
            odds = math.exp(hyps[1][0] - hyps[0][0])
            self.reasons.setdefault(person, []).append(
                f"{format_address(addr)} at t={b.t0[k]:.0f} s could be {alt} ({odds:.2f} times as likely)")
        return person


def _continuation_log_prior(dt_s: np.ndarray) -> np.ndarray:
    """ln prior odds that a new address starting ``dt_s`` after a person's last burst ended is that
    person: CONTINUATION_LOG_ODDS within CONTINUATION_S (phones that change address every few
    frames send one burst under several addresses, back to back, never overlapping), else 0."""
    dt = np.asarray(dt_s)
    return np.where((dt >= 0.0) & (dt <= CONTINUATION_S), CONTINUATION_LOG_ODDS, 0.0)


def _feasible(b: _Bursts, k: int, prior: np.ndarray, pid: np.ndarray, v: float) -> list[int]:
    """The people (ids, ascending) of whom every burst in ``prior`` is within reach of burst k: the
    annuli grown by ``v dt`` intersect. People under a hardware address never change address."""
    dt = np.maximum(b.t0[k] - b.t1[prior], 0.0)
    grow = v * dt
    dist = np.hypot(b.xy[prior, 0] - b.xy[k, 0], b.xy[prior, 1] - b.xy[k, 1])
    ok = ((dist <= b.hi[k] + b.hi[prior] + grow) & (dist >= b.lo[k] - b.hi[prior] - grow)
          & (dist >= b.lo[prior] - b.hi[k] - grow))
    # two streams heard at once under two addresses are two phones, and a phone answers an access
    # point under one address: two long streams under two addresses are two phones
    other = b.address[prior] != b.address[k]
    overlap = np.minimum(b.t1[prior], b.t1[k]) - np.maximum(b.t0[prior], b.t0[k])
    ok &= ~other | (overlap <= CONCURRENT_S)
    if b.t1[k] - b.t0[k] > CONCURRENT_S:
        ok &= ~other | (b.t1[prior] - b.t0[prior] <= CONCURRENT_S)
    owners = pid[prior]
    out = set(owners.tolist()) - set(owners[~ok].tolist())
    return sorted(p for p in out if is_locally_administered(p))


def _row_loglik(b: _Bursts, k: int, xy: np.ndarray, start: int = 0) -> np.ndarray:
    """Sum over burst k's rows (from ``start``) of ln p(observed ln range | phone at xy), xy (..., 2)."""
    n_rows = int(np.count_nonzero(b.row_used[k]))
    if start >= n_rows:
        return np.zeros(xy.shape[:-1])
    rows = slice(start, n_rows)
    g = xy[..., None, :] - b.row_xy[k, rows]  # (..., R, 2)
    ln_d = 0.5 * np.log(g[..., 0] ** 2 + g[..., 1] ** 2 + b.row_h[k, rows] ** 2)
    return np.sum(_loglik_ln_range(b, k, rows, ln_d), axis=-1)


def _loglik_ln_range(b: _Bursts, k: int, rows, ln_d):
    """ln p(the rows' mean RSSI | heard, 3-D range e^ln_d) (``rows`` an index or slice into burst
    k's rows, broadcast against ln_d's last axis): the frames' normal density given that each was
    heard (truncated at the sensitivity, so that a phone far out heard loud by luck is not taken for
    a near one), in nepers."""
    from scipy.special import log_ndtr

    s = b.row_s[k, rows]
    z = (ln_d - b.row_y[k, rows]) / s
    out = -0.5 * z * z - np.log(s) - _HALF_LN_2PI
    if math.isfinite(b.y_sens):
        out = out - b.row_n[k, rows] * log_ndtr((b.y_sens - ln_d) / b.s_frame)
    return out


def _new_person(b: _Bursts, k: int, rng: np.random.Generator):
    """ln of the integral over the plane (to ``max_ground_m``) of burst k's likelihood (the evidence
    for a new person, before dividing by the area), and PARTICLES positions with log weights drawn
    from it: the first row's radial integral ``2 pi int L(u) e^{2u} du`` (u = ln d) on a grid,
    positions drawn by its inverse CDF at uniform angles, weighed by the other rows."""
    h = b.row_h[k, 0]
    u_hi = max(math.log(min(b.gate_m, math.hypot(b.max_ground_m, h))), math.log(h) + 1e-6)
    u = np.linspace(math.log(h), u_hi, _RADIAL_NODES)
    f = _loglik_ln_range(b, k, 0, u) + 2.0 * u
    m = float(np.max(f))
    g = np.exp(f - m)
    cell = 0.5 * (g[1:] + g[:-1]) * np.diff(u)
    total = float(np.sum(cell))
    log_z = math.log(2.0 * math.pi) + m + math.log(total)
    cdf = np.concatenate([[0.0], np.cumsum(cell)]) / total
    u01 = rng.random((2, PARTICLES))
    uu = np.interp(u01[0], cdf, u)
    rho = np.sqrt(np.maximum(np.exp(2.0 * uu) - h * h, 0.0))
    ang = 2 * math.pi * u01[1]
    xy = b.row_xy[k, 0] + rho[:, None] * np.column_stack([np.cos(ang), np.sin(ang)])
    logw = _row_loglik(b, k, xy, start=1)
    lse = _logsumexp(logw)
    return log_z + lse - math.log(PARTICLES), xy, logw - lse


def _candidates_likelihood(b: _Bursts, k: int, beliefs: list[_Belief], v: float, rng: np.random.Generator):
    """Per candidate belief: ln p(burst k | that person), the particles moved to the burst's time
    (uniformly within ``v dt``) and their posterior log weights (normalised)."""
    xy = np.stack([q.xy for q in beliefs])  # (C, K, 2)
    logw = np.stack([q.logw for q in beliefs])
    reach = v * np.maximum(b.t0[k] - np.array([q.t_s for q in beliefs]), 0.0)
    u = rng.random((2,) + xy.shape[:2])
    r = reach[:, None] * np.sqrt(u[0])
    moved = xy + np.stack([r * np.cos(2 * math.pi * u[1]), r * np.sin(2 * math.pi * u[1])], axis=-1)
    post = logw + _row_loglik(b, k, moved)
    m = np.max(post, axis=1)
    ll = m + np.log(np.sum(np.exp(post - m[:, None]), axis=1))
    return ll, moved, post - ll[:, None]


def _updated(xy: np.ndarray, logw: np.ndarray, t_s: float, rng: np.random.Generator) -> _Belief:
    """The belief, resampled (systematic) when its effective sample size falls below half."""
    w = np.exp(logw)
    if 1.0 / float(np.sum(w * w)) < 0.5 * len(w):
        c = np.cumsum(w)
        idx = np.searchsorted(c / c[-1], (rng.random() + np.arange(len(w))) / len(w)).clip(0, len(w) - 1)
        xy, logw = xy[idx], np.full(len(w), -math.log(len(w)))
    return _Belief(xy, logw, t_s)


def _logsumexp(x: np.ndarray) -> float:
    m = float(np.max(x))
    return m + math.log(float(np.sum(np.exp(x - m)))) if math.isfinite(m) else m
