"""Judging a simulated search against the world's truth: which phone each reported person is, how
far off, whether the circle claimed holds them (sim_link.experiments.missionsim's results; the
core never sees the truth)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..world import World


@dataclass(frozen=True)
class PersonResult:
    """One true person at the end of a mission. Errors in metres; NaN where not estimated."""

    emitter_id: int
    heard: bool
    located: bool
    fix_t_s: float  # NaN if never located
    error_m: float  # believed position at its reference time vs truth at that time
    claimed_radius_m: float  # the method's own error claim (95 % radius or annulus bound)
    reason: str = ""  # the policy's statement about this person at the end ("" where it makes none)
    # of the bursts the reported person judged as this one holds, the share another phone sent (NaN
    # where unknown): a fix built from two phones' bursts is not a fix (issue 41 item 4)
    foreign_share: float = math.nan


def _owners(world: World, statuses: list, slots_of=None) -> tuple[np.ndarray, list]:
    """Per reported person, the phone behind them (the first address's, or with ``slots_of`` the one
    that sent most of their bursts) and the share of their bursts another phone sent (NaN unknown)."""
    from uavloc_gcs.estimation.identity import burst_index

    owner = world.person_of([s.emitter_id for s in statuses]) if statuses else np.zeros(0, int)
    foreign = [math.nan] * len(statuses)
    if slots_of is not None:
        for k, s in enumerate(statuses):
            slots = slots_of(s.emitter_id)
            if len(slots) == 0:
                continue
            burst = burst_index(slots)
            _, first = np.unique(burst, return_index=True)  # one address per burst: one phone
            phones, counts = np.unique(world.person_of(slots.address[first]), return_counts=True)
            top = counts == counts.max()
            if not top[phones == owner[k]].any():  # a tie keeps the first address's phone
                owner[k] = int(phones[np.argmax(counts)])
            foreign[k] = 1.0 - float(counts.max()) / float(counts.sum())
    return owner, foreign


def _error_m(world: World, s, i: int, t_end_s: float) -> float:
    """How far reported person ``s`` is from phone ``i`` at their reference time [m]."""
    truth = world.positions(s.t_ref_s if s.t_ref_s is not None else t_end_s)[int(i)]
    return float(np.hypot(s.xy_m[0] - truth[0], s.xy_m[1] - truth[1]))


def judge(world: World, statuses: list, t_end_s: float, slots_of=None) -> tuple[tuple, tuple]:
    """(:func:`person_results`, :func:`circle_claims`) with the phone behind each reported person
    worked out once."""
    owners = _owners(world, statuses, slots_of)
    return _person_results(world, statuses, t_end_s, *owners), _circle_claims(world, statuses, t_end_s, owners[0])


def circle_claims(world: World, statuses: list, t_end_s: float, slots_of=None) -> tuple[tuple[bool, float, bool], ...]:
    """Every circle the policy reports, duplicates of one phone included: (located, 95 % radius [m],
    whether it holds the phone behind it) for each reported person with an estimate."""
    return _circle_claims(world, statuses, t_end_s, _owners(world, statuses, slots_of)[0])


def _circle_claims(world: World, statuses: list, t_end_s: float, owner) -> tuple[tuple[bool, float, bool], ...]:
    return tuple((bool(s.located), float(s.radius95_m), _error_m(world, s, i, t_end_s) <= float(s.radius95_m))
                 for s, i in zip(statuses, owner) if s.xy_m is not None and i >= 0)


def person_results(world: World, statuses: list, t_end_s: float, slots_of=None) -> tuple[PersonResult, ...]:
    """Compare what the policy believes (PersonStatus list) with the truth, one row per true person.

    In the field world the policy reports people under the first address heard of them, and the
    linking may split one phone into several reported people or merge several phones into one.
    With ``slots_of`` (emitter id -> the slots the policy holds as that person's,
    ``SearchPolicy.heard_slots``) a reported person is the phone that sent most of their bursts and
    ``foreign_share`` says how many of them another phone sent; without it, the phone of the first
    address heard. A true person is judged by the one of theirs that is located (the first one if
    several), else the first reported."""
    return _person_results(world, statuses, t_end_s, *_owners(world, statuses, slots_of))


def _person_results(world: World, statuses: list, t_end_s: float, owner, foreign) -> tuple[PersonResult, ...]:
    by_person: dict[int, tuple] = {}
    for k, (s, i) in enumerate(zip(statuses, owner)):
        best = by_person.get(int(i))
        if best is None or (s.located and not best[0].located):
            by_person[int(i)] = (s, foreign[k])
    out = []
    for i, eid in enumerate(world.emitter_ids):
        s, share = by_person.get(i, (None, math.nan))
        if s is None or s.xy_m is None:
            out.append(PersonResult(int(eid), s is not None, False, math.nan, math.nan, math.nan,
                                    "" if s is None else s.reason, share))
            continue
        out.append(PersonResult(int(eid), True, s.located, math.nan if s.fix_t_s is None else s.fix_t_s,
                                _error_m(world, s, i, t_end_s), float(s.radius95_m), s.reason, share))
    return tuple(out)


def max_error_m(world: World, statuses: list) -> float:
    """Largest believed-vs-true error over all true people (NaN while someone is unheard)."""
    res = person_results(world, statuses, 0.0)
    errs = [p.error_m for p in res]
    return float(np.max(errs)) if errs and not any(math.isnan(e) for e in errs) else math.nan
