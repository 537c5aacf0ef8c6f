"""How the search policy judges each person (the middle of :class:`~.policy.SearchPolicy`).

After every estimate: is the person located (a sharp estimate, no open mirror, the fix corroborated),
ambiguous, or still pending (``_classify``); after every planned or reported look: did it hear
them, locate them, or was it a miss, and is it time to give them up (``_check_looks``); and the
sentence the policy says about each person (``_reason``). The data these read are
:mod:`.hearing`'s; the plans made from them are :mod:`.policy`'s. The module switches below are read
at call time: ``uavloc bench looks`` variants set them.
"""

from __future__ import annotations

import logging
import math
from dataclasses import replace

import numpy as np

from . import orbit as orb
from . import targets as tg
from .hearing import Hearing, _Person

log = logging.getLogger("uavloc_gcs.search.policy")

# Looks per person before giving up, None for no cap: the energy budget ends the looks. A cap of 4
# gave up people that further looks located: `uavloc bench looks --variants default,cap4`, paper
# scenario, 40 worlds: 800/800 located against 794/800, +6.3 +- 8.4 s; SITL sparse scan, 120
# worlds: 360/360 against 358/360, +0.3 +- 0.4 s.
MAX_LOOKS: int | None = None
# With phones that send probe bursts (the field world, no elicitation), a person is given up after
# this many fly-by looks that did not locate them: each sees a few seconds of a phone that speaks
# every 20-270 s. Without it the daemon flew the field demo's 10 people look after look until the
# batteries were at 9-13 % (3,100 s of mission time, 7 replans, nobody located). None: no cap.
FLYBY_LOOKS_FOR_BURSTS: int | None = 2
MAX_MISSES = 2  # looks that heard nothing before giving up (with a mirror ambiguity: one at each candidate)
MATERIAL_SHIFT_FRACTION = 0.5  # estimate moved > this x required accuracy => replan
LOOK_LATE_S = 180.0  # with look reports: an unreported look is dropped (not a miss) this long after its time
# Once a person has been mirror-ambiguous, the ambiguity counts as settled only when the mirror
# holds less than this share of the posterior (the estimator calls it ambiguous above 5 %). The
# mirror's share from distant data is volatile: measured (same run) 52 %, 26 %, 34 %, 3.7 % on
# consecutive estimates while the vehicle flew away 100 m off; the 3.7 % one was the wrong mirror
# (89 m off, 9 m radius) and was declared located; six seconds later the data gave the right one
# with 0 %. None turns the hysteresis off.
AMBIGUITY_SETTLED_MASS = 0.01


class Judging(Hearing):
    """Located, ambiguous, pending or given up: the judging side of :class:`~.policy.SearchPolicy`
    (which sets the state these methods keep, see its ``__init__``)."""

    def _candidate(self, p: _Person) -> tg.Candidate | None:
        if p.estimate is None:
            return None
        cands = tg.candidates(p.estimate, p.last_slot_t_s)
        if not cands:
            return None
        if len(cands) == 2:
            inside = [tg.inside_area(self.area_xy_m, c.xy_m, margin_m=self.required_m) for c in cands]
            if inside[0] != inside[1]:
                return cands[0] if inside[0] else cands[1]
            if p.flipped:
                return cands[1]
        return cands[0]

    def _ambiguous(self, p: _Person) -> bool:
        cands = tg.candidates(p.estimate, p.last_slot_t_s) if p.estimate is not None else []
        if len(cands) < 2:
            return False
        inside = [tg.inside_area(self.area_xy_m, c.xy_m, margin_m=self.required_m) for c in cands]
        return inside[0] == inside[1]

    def _separation(self, p: _Person) -> float | None:
        if not self._ambiguous(p):
            return None
        a, b = tg.candidates(p.estimate, p.last_slot_t_s)
        return float(np.linalg.norm(a.xy_m - b.xy_m))

    def _unsettled(self, p: _Person, est):
        """``est`` as the policy believes it: still ambiguous (radius over both candidates) when
        this person was ambiguous before and the mirror, outside the estimate's own 95 % circle,
        keeps AMBIGUITY_SETTLED_MASS or more."""
        if getattr(est, "ambiguous", False):
            p.was_ambiguous = True
            return est
        mirror = getattr(est, "mirror", None)
        if (AMBIGUITY_SETTLED_MASS is None or not p.was_ambiguous or mirror is None
                or str(getattr(est, "status", "ok")) != "ok"):
            return est
        rel = float(mirror.relative_likelihood)
        reach = float(np.linalg.norm(np.asarray(mirror.position_xy_m) - np.asarray(est.position_xy_m)))
        if rel / (1.0 + rel) < AMBIGUITY_SETTLED_MASS or reach <= float(getattr(est, "mode_radius95_m", 0.0)):
            return est  # settled, or a second optimum inside the estimate's own circle: no alternative
        return replace(est, ambiguous=True, radius95_m=max(float(est.radius95_m), reach + float(mirror.radius95_m)))

    def _ok(self, p: _Person) -> bool:
        est = p.estimate
        return est is not None and str(getattr(est, "status", "ok")) == "ok" and not p.error

    def _classify(self, p: _Person, t_s: float) -> None:
        if p.fix_t_s is not None or p.gave_up or not self._ok(p):
            return
        r95 = self._radius95(p)
        cand = self._candidate(p)
        if r95 <= self.required_m and not self._ambiguous(p) and cand is not None and not p.contradicted:
            # dated at the estimate's reference (its data's last slot): with fits in a worker,
            # slots may have come since
            t_fix = float(getattr(p.estimate, "t_ref_s", p.last_slot_t_s))
            p.fix_t_s = t_fix if math.isfinite(t_fix) else t_s
            p.fix_estimate = p.estimate
            p.fix_radius95_m = r95
            p.fix_candidate = cand
            self._awaiting.pop(p.emitter_id, None)
            self._flown.pop(p.emitter_id, None)

    def _radius95(self, p: _Person) -> float:
        """Calibrated 95 % radius [m] of the candidate we believe. The estimator's ``radius95_m``
        covers both mirror candidates when ambiguous; once the area rules one out, only the other
        candidate's own radius counts."""
        est = p.estimate
        r95 = float(getattr(est, "radius95_m", math.inf))
        if getattr(est, "ambiguous", False) and getattr(est, "mirror", None) is not None and not self._ambiguous(p):
            primary = tg.candidates(est, p.last_slot_t_s)[0]
            chosen = self._candidate(p)
            if chosen is not None and np.allclose(chosen.xy_m, primary.xy_m):
                r95 = float(getattr(est, "mode_radius95_m", r95))
            else:
                r95 = float(getattr(est.mirror, "radius95_m", r95))
        return r95

    def _signature(self, p: _Person):
        if p.estimate is None:
            return None
        cand = self._candidate(p)
        return (p.fix_t_s is not None, bool(p.gave_up), self._ambiguous(p), p.flipped,
                None if cand is None else cand.xy_m.copy(), self._ok(p))

    def _material(self, a, b) -> bool:
        if a[:4] != b[:4] or a[5] != b[5]:
            return True
        if a[4] is None or b[4] is None:
            return a[4] is not b[4]
        return float(np.linalg.norm(a[4] - b[4])) > MATERIAL_SHIFT_FRACTION * self.required_m

    def _check_looks(self, t_s: float) -> set[int]:
        """Planned looks whose time has passed: count them; a look that heard nothing is a miss
        (flip to the mirror candidate if ambiguous; give up after MAX_MISSES). A look reported
        flown is judged R/V after it was flown; with ``look_reports`` an unreported one only
        LOOK_LATE_S after its (re-based) planned time, otherwise R/V after its planned time."""
        changed = set()
        grace_s = self.range_m / self.speed_m_s
        late_s = LOOK_LATE_S if self.look_reports else 0.0
        due, unheard = [], []
        for eid, t in self._flown.items():
            judge_s = t + grace_s + orb.orbit_dwell_s(self, eid)
            if t_s < judge_s:
                continue
            if self._reported_through(eid, judge_s):
                due.append((eid, t, self._flown))
            elif t_s >= judge_s + LOOK_LATE_S:
                unheard.append(eid)
        for eid in unheard:  # its receiver never reported the look: no evidence either way
            del self._flown[eid]
            p = self._people[eid]
            if p.fix_t_s is None and not p.gave_up:
                log.info("emitter %s: the looking vehicle's receiver has not reported the look %g s after it; "
                         "planned again", eid, LOOK_LATE_S)
                changed.add(eid)
        due += [(eid, t, self._awaiting) for eid, t in self._awaiting.items()
                if t_s >= t + grace_s + late_s + orb.orbit_dwell_s(self, eid) and eid not in self._flown]
        for eid, t_access, book in due:
            del book[eid]
            p = self._people[eid]
            if p.fix_t_s is not None or p.gave_up:
                continue
            if self.look_reports and book is self._awaiting:
                # Never reported flown: no evidence that the phone is gone (issue 26: under load a
                # look's upload stalled for minutes of mission time, the look was judged missed
                # unflown and people were given up "not heard on 2 looks"). It is planned again.
                log.info("emitter %s: look not flown %g s after its time; planned again", eid, LOOK_LATE_S)
                changed.add(eid)
                continue
            p.looks += 1
            heard = p.last_slot_t_s >= t_access - 2.0 * grace_s
            if not heard:
                p.misses += 1
                if self._ambiguous(p):
                    p.flipped = not p.flipped
            orbit_verdict = orb.judge_orbit(self, eid, p, heard)  # None: not an orbit look
            if orbit_verdict is not None:
                p.gave_up = orbit_verdict
                # a look at eid planned while it was orbited is that orbit's rest (orbit_targets),
                # judged now with it: left awaiting, it was judged again later as a fly-by
                self._awaiting.pop(eid, None)
            elif p.misses >= MAX_MISSES and self._bursts:
                # a phone heard in bursts is silent most of the time: a fly-by missing it says
                # little about whether it is still there
                p.gave_up = (f"not heard on {p.misses} fly-by looks where it was predicted; its phone"
                             " sends probe bursts tens of seconds to minutes apart, so a fly-by of a few"
                             " seconds usually misses it (it may well still be there)")
            elif p.misses >= MAX_MISSES:
                p.gave_up = (f"not heard on {p.misses} looks where it was predicted"
                             " (a phone that is off or has gone cannot be located)")
            elif self._bursts and FLYBY_LOOKS_FOR_BURSTS is not None and p.looks >= FLYBY_LOOKS_FOR_BURSTS:
                r95 = self._radius95(p) if p.estimate is not None else math.nan
                p.gave_up = (f"not located after {p.looks} fly-by looks (95 % radius {r95:.0f} m); a fly-by"
                             " of a few seconds rarely catches a phone that bursts tens of seconds to minutes"
                             " apart, so more of them would only spend the batteries")
            elif MAX_LOOKS is not None and p.looks >= MAX_LOOKS:
                r95 = self._radius95(p) if p.estimate is not None else math.nan  # the believed candidate's
                p.gave_up = f"not located after {p.looks} looks (95 % radius {r95:.1f} m)"
            changed.add(eid)
        return changed

    def _reason(self, p: _Person) -> str:
        if p.fix_t_s is not None:
            return f"located: 95 % radius {p.fix_radius95_m:.1f} m <= {self.required_m:g} m"
        if p.gave_up:
            return f"given up: {p.gave_up}"
        if p.error:
            return f"no estimate: {p.error}"
        if p.estimate is None:
            return "not estimated yet"
        if not self._ok(p):
            return f"estimate status {getattr(p.estimate, 'status', '?')}"
        unplanned = "; the last plan had no look for it" if p.emitter_id in self._unplanned else ""
        if p.emitter_id in self._deferred:
            unplanned = "; its look waits for a fresh pack (no pack in the air reaches it)"
        if p.contradicted:
            return f"95 % radius {self._radius95(p):.1f} m, but {p.contradicted}" + unplanned
        if self._ambiguous(p):
            return "mirror ambiguity: needs a look off the flight line" + unplanned
        return f"95 % radius {self._radius95(p):.1f} m > {self.required_m:g} m" + unplanned
