"""From the search policy's beliefs to what the operator gets: person results and one statement."""

from __future__ import annotations

import dataclasses
import logging
import math
import re
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..errors import UavlocError
from ..geo import LocalFrame
from .results import PersonResult
from .store import EstimateRow

log = logging.getLogger(__name__)


def _f(value, default: float = math.nan) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        return default
    return v if math.isfinite(v) else default


def _vec(value) -> tuple[float, float]:
    if value is None:
        return math.nan, math.nan
    arr = np.asarray(value, dtype=float).reshape(-1)
    return (float(arr[0]), float(arr[1])) if arr.size >= 2 else (math.nan, math.nan)


def person_result(status, frame: LocalFrame, *, epoch_t_s: float = 0.0) -> PersonResult:
    """A :class:`PersonResult` from a ``search.policy.PersonStatus`` (estimate duck-typed).

    ``epoch_t_s`` is subtracted from the fix time so it reads as seconds since the search began.
    """
    est = status.estimate
    # Position, velocity, time and radius all of the policy's believed candidate (the fix's when
    # located). The estimate's own position_xy_m / radius95_m must not be used: when the estimator
    # reports a mirror ambiguity that the area resolved, they are the other candidate's position
    # and a radius reaching over both.
    if status.xy_m is not None:
        (e, n), t_ref_abs = status.xy_m, _f(status.t_ref_s)
        r95 = _f(getattr(status, "radius95_m", None))
    else:
        (e, n), t_ref_abs = (math.nan, math.nan), math.nan
        r95 = math.nan
    vel = getattr(status, "velocity_m_s", None)
    ve, vn = _vec(vel if vel is not None else getattr(est, "velocity_m_s", None))
    bound = _f(getattr(est, "annulus_bound_m", getattr(est, "bound_m", None)))
    if math.isfinite(e) and math.isfinite(n):
        lat, lon = frame.to_wgs84(e, n)
        lat, lon = float(lat), float(lon)
    else:
        lat = lon = math.nan
    fix = _f(status.fix_t_s) - epoch_t_s if status.fix_t_s is not None else math.nan
    located = bool(status.located) and math.isfinite(r95) and math.isfinite(e)
    ambiguous = bool(getattr(est, "ambiguous", False)) and not located  # a fix is unambiguous
    reason = "" if located else (status.reason or "no position")
    t_ref = t_ref_abs - epoch_t_s
    return PersonResult(int(status.emitter_id), lat, lon, float(e), float(n), ve, vn, r95, bound, fix,
                        located, not ambiguous, reason, t_ref)


def final_results(statuses, slots, scenario, frame: LocalFrame, linking=None, *, refit: bool = True) -> list[PersonResult]:
    """Each person re-estimated at the end from the slots of their last FINAL_WINDOW_S seconds of
    being heard. The policy freezes a person's estimate when it first meets the accuracy; later
    passes usually sharpen it. A person counts as located if the policy located them or the
    refit's 95 % circle (over both mirror candidates if ambiguous) is within the required accuracy.
    A located person keeps their fix unless the refit also meets the accuracy and agrees with it;
    a refit that meets the accuracy but puts the person where the fix, grown by walking since, says
    they cannot be, unmakes the fix: two confident answers that disagree locate no one. The
    reported position is always the one the reported radius is about.

    Never a fit over all of a person's data: a constant-velocity fit over a whole search is
    confidently wrong for a walker who turned (issue 42: on a busy machine a paper demo lasted
    1,700 s and such a fit reported a walker 145 m from the truth with an 8.2 m radius, as located).

    ``linking`` (the policy's ``estimation.identity.Linking``, when a sensor reported fingerprints):
    the people are the linked addresses, so their slots are the linked ones, and each result names
    the addresses it was heard under and why their link is uncertain. ``refit=False`` reports the
    policy's beliefs as they are (a stopped search: its results must not wait for fits)."""
    from ..estimation import ChannelModel, airborne_slots  # noqa: PLC0415
    from ..heights import airborne_floor_m  # noqa: PLC0415

    channel = ChannelModel.from_scenario(scenario)
    if linking is not None:
        slots = linking.slots  # already the survey slots, relabelled by person
        out = final_results(statuses, slots, scenario, frame, refit=refit)
        return [dataclasses.replace(r, addresses=tuple(linking.addresses(r.emitter_id)),
                                    link_reason=linking.uncertain(r.emitter_id) or "") for r in out]
    slots = airborne_slots(slots, airborne_floor_m(scenario), scenario.dem)  # what the policy estimated from
    required = scenario.people.required_accuracy_m
    vmax = scenario.people.max_speed_m_s
    out = []
    for st in statuses:
        base = person_result(st, frame)
        part = slots.for_emitter(st.emitter_id).sorted_by_time() if refit else slots.take(np.zeros(0, int))
        recent = part.take(part.t_s >= (part.t_s.max() - FINAL_WINDOW_S if len(part) else 0.0))
        est = _fit(recent, channel, vmax, scenario.dem)
        if est is None or not (est.radius95_m <= required or not (base.located or est.ambiguous)):
            # nothing better: never trade a located fix for a looser refit, nor the policy's
            # area-resolved belief for an ambiguous refit that does not meet the accuracy either way
            out.append(base)
            continue
        e, n = (float(v) for v in est.position_xy_m)
        if base.located and math.isfinite(base.t_ref_s):
            apart = math.hypot(e - base.east_m, n - base.north_m)
            reach = base.radius95_m + float(est.radius95_m) + vmax * abs(float(est.t_ref_s) - base.t_ref_s)
            if apart > reach:
                log.warning("person %d: the refit is %.0f m from the fix, which with both radii and walking "
                            "allows %.0f m: not counted as located", base.emitter_id, apart, reach)
                out.append(dataclasses.replace(
                    base, located=False, reason=f"two fixes disagree: the last {FINAL_WINDOW_S:g} s of data put "
                    f"them {apart:.0f} m from where they were located, more than both 95 % radii and walking "
                    f"since allow ({reach:.0f} m)"))
                continue
        lat, lon = (float(v) for v in frame.to_wgs84(e, n))
        located = base.located or est.radius95_m <= required  # est radius <= required if base located
        resolved = located or not est.ambiguous
        r95 = float(est.radius95_m)
        out.append(PersonResult(base.emitter_id, lat, lon, e, n, float(est.velocity_m_s[0]),
                                float(est.velocity_m_s[1]), r95, _f(est.annulus_bound_m), base.fix_time_s,
                                located, resolved, "" if located else reason_with_radius(base.reason, r95, required),
                                float(est.t_ref_s)))
    return [_never_located_beyond(_with_radio(r, slots), required) for r in out]


def _with_radio(r: PersonResult, slots) -> PersonResult:
    """``r`` with the radio its slots were heard by (uavloc_gcs.radios; Wi-Fi when unknown)."""
    from ..radios import radio_of  # noqa: PLC0415

    part = slots.for_emitter(r.emitter_id)
    return dataclasses.replace(r, radio=radio_of(part)) if len(part) else r


_RADIUS_TEXT = re.compile(r"95 % radius (?:[-+]?\d+(?:\.\d*)?|inf|nan) m")


def reason_with_radius(reason: str, radius95_m: float, required_m: float) -> str:
    """``reason`` about the radius that is reported. The policy words its reasons with the radius
    of its own belief; the final refit reports another one, and the operator must not read two
    radii for one person (the table said 99.2 m while the reason said 56.8 m). A reason with a
    radius gets the reported one; a reason without one gets it appended when it exceeds the
    required accuracy."""
    text = f"95 % radius {radius95_m:.1f} m"
    if _RADIUS_TEXT.search(reason):
        return _RADIUS_TEXT.sub(text, reason)
    if math.isfinite(radius95_m) and radius95_m > required_m and "radius" not in reason:
        return f"{reason}; {text} > {required_m:g} m" if reason else f"{text} > {required_m:g} m"
    return reason


def _never_located_beyond(r: PersonResult, required_m: float) -> PersonResult:
    """A person whose reported radius exceeds the required accuracy is never reported located."""
    if not r.located or r.radius95_m <= required_m:
        return r
    log.warning("person %d: reported radius %.1f m > required %.1f m; not counted as located",
                r.emitter_id, r.radius95_m, required_m)
    return dataclasses.replace(r, located=False, reason=f"95 % radius {r.radius95_m:.1f} m > {required_m:g} m")


def _fit(data, channel, max_speed_m_s: float, dem=None):
    """A valid estimate from ``data`` (its radius covering a mirror image if ambiguous), or None.
    Over terrain (``dem``) the person stands on its ground, as in the policy's fits: a flat-ground
    refit misreads the slant ranges by the ground's rise, and at the end of a mountains demo it
    reported a walker 142 m from the truth with a 0.35 m radius."""
    from ..estimation.terrain_fit import fit_for  # noqa: PLC0415

    if len(data) == 0:
        return None
    try:
        est = fit_for(dem)(data, channel, max_speed_m_s=max_speed_m_s, model_motion=True)
    except UavlocError:
        return None
    # An ambiguous estimate's radius95_m is centred on its primary and reaches over the mirror,
    # so position and radius still belong together; it is located only if that circle is small.
    if not est.ok or not math.isfinite(est.radius95_m):
        return None
    return est


def estimate_row(status, t_s: float) -> EstimateRow:
    r = person_result(status, _NO_FRAME)
    return EstimateRow(t_s, r.emitter_id, r.east_m, r.north_m, r.vel_east_m_s, r.vel_north_m_s,
                       r.radius95_m, r.annulus_bound_m, r.located, not r.ambiguity_resolved,
                       "" if r.located else status.reason)


class _NoFrame:
    """Stands in for a frame when only local coordinates are needed (no lat/lon conversion)."""

    def to_wgs84(self, e, n):
        return math.nan, math.nan


_NO_FRAME = _NoFrame()


FINAL_WINDOW_S = 60.0  # on two paper demos 60 s beat 30 s, 120 s and the whole search (docs/guide/daemon.md)


@dataclass(frozen=True)
class SearchOutcome:
    """How a search ended. ``statement`` is one or two sentences for the operator."""

    people: tuple[PersonResult, ...]
    all_located: bool
    statement: str
    elapsed_s: float
    replans: int
    vehicles_home: tuple[int, ...]
    vehicles_lost: tuple[int, ...]
    vehicles_returning: tuple[int, ...] = ()  # return home acknowledged, landing not seen yet
    # per vehicle: (id, replans that changed its looks, missions uploaded incl. the scan, new plans not
    # uploaded because not worth a restarted leg)
    uploads: tuple[tuple[int, int, int, int], ...] = ()
    # why the results are partial (the search was stopped before its end); "" when it ended
    partial: str = ""
    # what was searched (search.coverage.CoverageSummary), set once the results are written
    coverage: object = None
    # part of the area went unsearched because a vehicle was lost (or its scan never started) and
    # nobody could take it over: the daemon's exit code says so (EXIT_UNSEARCHED)
    unsearched_after_loss: bool = False
    # vehicles lost while not on the ground and disarmed, and not heard again (service.lost.LastHeard):
    # said first everywhere, and the daemon's exit code (service.lost.EXIT_VEHICLE_LOST)
    lost_in_air: tuple = ()


EXIT_UNSEARCHED = 4  # `uavloc daemon`'s exit code when part of the area was left unsearched (see above)


def coverage_statement(summary, lost: Sequence[int] = (), not_started: Sequence[int] = (),
                       stopped: bool = False) -> tuple[str, bool]:
    """What was searched, for the end of the statement, and whether part of the area went
    unsearched because vehicles ``lost`` (or whose scans were ``not_started``) left it and
    nobody took it over. A search ``stopped`` before its end says that instead (its exit code is
    the signal's)."""
    if summary is None:
        return "", False
    text = summary.sentence()
    if stopped:
        if summary.unsearched_m2 > 0:
            text += f" The search was stopped before {summary.unsearched_m2 / 1e6:.3f} km² of the area were searched."
        return text, False
    gone = sorted({*lost, *not_started})
    left = bool(gone) and summary.unsearched_m2 > 0 and not summary.nothing_flown
    if left:
        text += (f" Part of the area ({summary.unsearched_m2 / 1e6:.3f} km²) was not searched: vehicle(s) "
                 f"{', '.join(map(str, gone))} could not fly it and "
                 f"{getattr(summary, 'passes_end', '') or 'no other vehicle took it over'}.")
    elif gone and summary.nothing_flown:
        left = True
    return text, left


def radio_note(people: Sequence[PersonResult]) -> str:
    """A sentence when some people were heard by BLE beacons (issue 39): they are identities, not
    phones; "" otherwise."""
    n_ble = sum(getattr(p, "radio", "wifi") == "ble" for p in people)
    if not n_ble:
        return ""
    return (f" {n_ble} of these {len(people)} were heard by Bluetooth LE beacons alone: each is one beacon key, "
            "so one phone can be counted once for its Wi-Fi and once for each 15-minute key it was heard under "
            "(nothing in the frames links them).")


def statement_for(people: Sequence[PersonResult], required_m: float, lost: Sequence[int],
                  not_home: Sequence[int], returning: Sequence[int] = (), coverage=None, *,
                  lost_in_air: Sequence = (), fleet: bool = True) -> str:
    """One clear statement: everyone located, or who is not and why; and where the fleet is.
    ``coverage`` (search.coverage.CoverageSummary): "no phone heard" is said with the POD reached,
    or as "nothing flew" when no vehicle flew over the area at survey altitude. ``lost_in_air``
    (service.lost.LastHeard): vehicles whose own sentences come before this statement (the caller
    puts them first); they are not named again here. ``fleet=False``: nothing about the fleet (a
    stopped search, whose stop report says what each vehicle does, once)."""
    missing = [p for p in sorted(people, key=lambda p: p.emitter_id) if not p.located]
    if not people and coverage is not None and coverage.nothing_flown:
        text = "No phone was heard: nothing flew over the search area at survey altitude."
    elif not people and coverage is not None:
        text = (f"No phone was heard where the vehicles flew (achieved POD {coverage.overall1:.2f} over the area, "
                f"target {coverage.target:.2f}).")
    elif not people:
        text = "No phone was heard."
    elif not missing:
        text = f"All {len(people)} people heard were located within {required_m:g} m (95 %)."
    else:
        why = "; ".join(f"{p.name if p.label else f'person {p.emitter_id}'}: {p.reason or 'not located'}"
                        for p in missing)
        text = (f"{len(people) - len(missing)} of {len(people)} people heard located within {required_m:g} m; "
                f"not located: {why}.")
    text += radio_note(people)
    if not fleet:
        return text
    said = {x.vehicle for x in lost_in_air}
    lost = [v for v in lost if v not in said]
    if lost:
        text += f" Lost contact with vehicle(s) {', '.join(map(str, lost))}."
    if returning:
        text += f" Vehicle(s) {', '.join(map(str, returning))} returning home (RTL), not landed yet."
    if not_home:
        text += f" Vehicle(s) {', '.join(map(str, not_home))} not confirmed returning home."
    if not returning and not not_home and not lost and not said:
        text += " All vehicles are home."
    return text
