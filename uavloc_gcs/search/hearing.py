"""What the search policy heard, and what it makes of it (the first half of :class:`~.policy.SearchPolicy`).

Slots come in (``ingest``), from a sensor that reports fingerprints they are linked into people
(``_relink``, estimation.identity), where each vehicle listened is kept (``ingest_track``, or the
slots themselves for the daemon), and each person's data become what the estimator reads: the
grid's bursts and the vehicles that heard none of them (``_bursts_of``), or the silences and
censored intervals of the continuous fits (``_silence``, ``_censored``). The decisions -- who is
located, where to look, when to give up, the plan -- are :mod:`.policy`'s, on the state kept here.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import EstimationError
from ..observations import SlotBatch
from ..radios import BLE, WIFI, ble_view, radio_of
from ..scenario import Scenario
from . import targets as tg
from .phones import burst_rates, channel_share, frames_prior

log = logging.getLogger("uavloc_gcs.search.policy")

TRACK_STEP_SLOTS = 10  # listening tracks are kept every this many slots (0.25 s, 6 m at 25 m/s)
# A caller with no listening track of its own (the daemon: a companion reports only the slots it
# heard) sets ``tracks_from_slots``: every slot heard, of any phone, says where that vehicle
# listened, so the other phones were silent there. A lost RSSI batch (at most 12 entries, 255 ms)
# must not read as silence, so with these tracks a phone counts as silent only where it was not
# heard for this long either side.
SLOT_TRACK_QUIET_S = 0.6
# In the field world (bursts under a receiver threshold) people are estimated on a grid of the ground
# (estimation/burst_grid.py) instead of by the multi-start fits of estimation/estimate.py: a posterior
# bent along rings with several modes is what a few bursts give. The person is in the area within
# GRID_AREA_MARGIN_M (people are searched for inside it).
GRID_ESTIMATE = True
GRID_AREA_MARGIN_M = 50.0


@dataclass
class _Person:
    """Mutable bookkeeping for one emitter (private to the policy)."""

    emitter_id: int
    batches: list = field(default_factory=list)
    n_slots: int = 0
    last_slot_t_s: float = -math.inf
    dirty: bool = False
    estimate: object = None
    error: str = ""
    flipped: bool = False  # look at the mirror candidate instead of the primary
    looks: int = 0
    misses: int = 0
    gave_up: str = ""
    fix_t_s: float | None = None
    fix_estimate: object = None
    fix_radius95_m: float = math.inf
    fix_candidate: tg.Candidate | None = None  # the believed candidate at the fix
    was_ambiguous: bool = False  # some estimate of this person was mirror-ambiguous
    version: int = 0  # counts changes of the person's data: a fit of an older version is stale
    contradicted: str = ""  # why the heard slots alone disagree with the latest sharp estimate
    fitting: bool = False  # a fit of this person is under way (estimation.fitting)


class Hearing:
    """Slots in, people out: the data side of :class:`~.policy.SearchPolicy`, which sets the state
    these methods keep (see its ``__init__``)."""

    def ingest(self, slots: SlotBatch) -> None:
        """Store new slots (any vehicles, any emitters); those heard low (taking off, landing, on
        the ground: below heights.airborne_floor_m, each slot by its own height) are left out."""
        from ..estimation import airborne_slots
        from ..heights import airborne_floor_m

        slots = airborne_slots(slots, airborne_floor_m(self.scenario), self.scenario.dem)
        if len(slots) == 0:
            return
        if self._raw or np.any(slots.fingerprint != 0):
            # a sensor that reports content fingerprints hears addresses, not people: they are
            # linked into people (estimation.identity) before the next estimate, in update
            self._raw.append(slots)
        else:
            self._add_person_slots(slots)
        if self.tracks_from_slots:
            for v in np.unique(slots.vehicle):
                mine = slots.vehicle == v
                t, first = np.unique(slots.t_s[mine], return_index=True)
                self.ingest_track(int(v), t, slots.xyz_m[mine][first])

    def _add_person_slots(self, slots: SlotBatch) -> None:
        for eid in slots.emitters():
            part = slots.for_emitter(int(eid))
            p = self._people.setdefault(int(eid), _Person(int(eid)))
            p.batches.append(part)
            p.n_slots += len(part)
            p.last_slot_t_s = max(p.last_slot_t_s, float(np.max(part.t_s)))
            p.dirty = True
            p.version += 1

    def _relink(self) -> None:
        """Link every address heard so far into people and give each person their slots. Person ids
        are stable as data grow (the first address heard of them), so a person's bookkeeping (looks,
        fix) carries over; a person whose bursts now belong to someone else is dropped."""
        from ..estimation.identity import UNKNOWN_TX_MARGIN_DB, link
        from ..geo import polygon_area_m2

        raw = SlotBatch.concat(self._raw)
        self._raw = [raw]
        sc = self.scenario
        self.linking = link(raw, self.channel, max_speed_m_s=sc.people.max_speed_m_s,
                            area_m2=polygon_area_m2(self.area_xy_m),
                            tx_margin_db=UNKNOWN_TX_MARGIN_DB,
                            previous=self.linking)
        labelled = self.linking.slots
        order = np.argsort(labelled.emitter_id, kind="stable")
        ids, starts = np.unique(labelled.emitter_id[order], return_index=True)
        bounds = list(starts[1:]) + [len(order)]
        seen = set()
        for eid, a, b in zip(ids, starts, bounds):
            eid = int(eid)
            seen.add(eid)
            part = labelled.take(np.sort(order[a:b])).sorted_by_time()
            p = self._people.get(eid)
            if p is None:
                p = self._people[eid] = _Person(eid)
            elif p.n_slots == len(part) and p.batches and np.array_equal(p.batches[0].t_s, part.t_s):
                continue
            p.batches, p.n_slots = [part], len(part)
            p.last_slot_t_s = float(np.max(part.t_s))
            p.dirty = True
            p.version += 1
        for eid in set(self._people) - seen:
            log.info("person %d: their bursts are now linked to someone else", eid)
            del self._people[eid]
            for book in (self._awaiting, self._flown, self._look_vehicle):
                book.pop(eid, None)
            self._unplanned.discard(eid)

    def ingest_track(self, vehicle: int, t_s, xyz_m) -> None:
        """Record where ``vehicle`` listened: slot times (N,) [s] and positions (N, 3) [m, z = height
        above the people]; kept every TRACK_STEP_SLOTS-th slot, each at its own height (those below
        heights.airborne_floor_m, as in ingest, are not). A phone not heard there is evidence
        that it was out of range (estimate_emitter's ``silence``)."""
        from ..heights import airborne, airborne_floor_m

        t = np.asarray(t_s, float).reshape(-1)
        if len(t) == 0:
            return
        xyz = np.asarray(xyz_m, float).reshape(-1, 3)
        # over terrain: the height above the ground under the vehicle
        k = (np.round(t / self.scenario.channel.slot_s).astype(np.int64) % TRACK_STEP_SLOTS == 0) & airborne(
            xyz, airborne_floor_m(self.scenario), self.scenario.dem)
        xyz = xyz[k]
        if not len(xyz):
            return
        self._tracks.setdefault(int(vehicle), []).append((t[k], xyz))
        if not self.hearing_evidence or self.channel.sensitivity_dbm is not None:
            # under a receiver threshold a silence is evidence only during a heard burst (see
            # _censored): new listening after the bursts changes nothing
            return
        for p in self._people.values():  # a silence near a pending candidate may rule it out
            if p.dirty or p.fix_t_s is not None or p.gave_up or not self._ok(p):
                continue
            for c in tg.candidates(p.estimate, p.last_slot_t_s):
                if float(np.min(np.linalg.norm(xyz[:, :2] - c.xy_m, axis=1))) < self.range_m:
                    p.dirty = True
                    p.version += 1
                    break

    def ingest_position(self, vehicle: int, t_s: float, xyz_m) -> None:
        """Record one telemetry position of ``vehicle`` [s; m, z = height above the people], where it
        listened: under a receiver threshold, the censored silences of the bursts it did not hear
        (``_censored``) need where every vehicle was when a burst was heard, which the slots heard
        (sparse: a few bursts a minute) do not say. Kept as they come, at their height, none dropped
        but those below heights.airborne_floor_m (over a DEM, above the ground under the vehicle)."""
        from ..heights import airborne, airborne_floor_m

        xyz = np.asarray(xyz_m, float).reshape(1, 3)
        if not airborne(xyz, airborne_floor_m(self.scenario), self.scenario.dem)[0]:
            return
        self._tracks.setdefault(int(vehicle), []).append((np.array([float(t_s)]), xyz))

    def _silence(self, p: "_Person"):
        """The recorded listening of every vehicle where ``p``'s phone was not heard; None when
        nothing was recorded or the evidence is off."""
        from ..estimation import Silence, silence_from_track

        if not self.hearing_evidence or not self._tracks or self.channel.sensitivity_dbm is not None:
            return None  # under a receiver threshold there is no range gate: see _censored
        heard = p.batches[0]
        ts, xs = [], []
        for v, parts in self._tracks.items():
            if len(parts) > 1:
                self._tracks[v] = parts = [(np.concatenate([a for a, _ in parts]), np.vstack([b for _, b in parts]))]
            t, xyz = parts[0]
            s = silence_from_track(t, xyz, heard.t_s[heard.vehicle == v], slot_s=self.scenario.channel.slot_s,
                                   quiet_s=SLOT_TRACK_QUIET_S if self.tracks_from_slots else None)
            ts.append(s.t_s)
            xs.append(s.xyz_m)
        return Silence(np.concatenate(ts), np.vstack(xs))

    def _censored(self, p: "_Person"):
        """The field world's silences (a receiver threshold, phones that send bursts): the vehicles
        that listened without hearing ``p``'s phone during one of its heard bursts, as censored
        observations (estimation.evidence.censored_silence); None without a threshold or tracks."""
        from ..estimation.evidence import censored_silence

        if not self.hearing_evidence or not self._tracks or self.channel.sensitivity_dbm is None:
            return None
        if self._frames_prior is None and self._bursts:
            self._frames_prior = frames_prior(self.scenario)
            self._burst_rates = burst_rates(self.scenario)
        tracks = []
        for v, parts in self._tracks.items():
            if len(parts) > 1:
                self._tracks[v] = parts = [(np.concatenate([a for a, _ in parts]), np.vstack([b for _, b in parts]))]
            tracks.append((v, parts[0][0], parts[0][1]))
        return censored_silence(tracks, p.batches[0], frames_prior=self._frames_prior or None,
                                exposure_rates=self._burst_rates if self._frames_prior else None)

    def _grid_spec(self, radio: str = WIFI):
        """The field world's grid estimate (estimation.burst_grid) when phones send bursts under a
        receiver threshold and GRID_ESTIMATE is on; None for the fits of estimation.estimate.
        ``radio``: the identity's (uavloc_gcs.radios): a BLE identity's units are single beacons
        under the BLE link budget. With an access point too: its answers are units of their own
        (burst_grid.bursts_from_slots); the continuous fits of estimation.estimate, used for them
        before, claimed 95 % radii of 18-26 m for people 23-32 m away, where the grid's held
        9 of 10 people (a whole search's data, docs/science/estimator.md)."""
        if not (GRID_ESTIMATE and self._probe_bursts and self.channel.sensitivity_dbm is not None):
            return None
        if self._grid is None:
            self._grid = {}
        spec = self._grid.get(radio)
        if spec is None:
            from ..estimation.burst_grid import GridSpec
            from ..estimation.burst_models import A2GBursts, LogDistanceBursts

            sc = self.scenario
            if radio == BLE:  # one frame per unit, every one on the channel the scanner hears it on
                sc = ble_view(sc)
                pmf = np.array([0.0, 1.0])
                model = A2GBursts.from_scenario(sc, pmf, 1.0)
                if model is None:
                    raise EstimationError("BLE beacons are estimated under the air-to-ground channel: "
                                          "set [channel] environment")
            else:
                fp = np.asarray(frames_prior(sc).p, float)
                pmf = np.concatenate([[0.0], fp / fp.sum()])  # K = 0 .. Kmax frames sent
                # the air-to-ground channel where the scenario names an environment (the world's own)
                model = A2GBursts.from_scenario(sc, pmf, channel_share(sc)) or LogDistanceBursts.from_scenario(sc)
            vmax = float(self.model_speed_m_s)
            spec = self._grid[radio] = GridSpec(model, tuple(float(v) for v in pmf), vmax,
                                                1.0 if vmax <= 0 else float(sc.people.static_share),
                                                tuple((float(x), float(y)) for x, y in self.area_xy_m),
                                                GRID_AREA_MARGIN_M)
        return spec

    def scenario_for(self, emitter_id: int) -> Scenario:
        """The scenario as the person's radio sees it: uavloc_gcs.radios.ble_view for an identity
        heard only in BLE beacons (its looks and estimates use the BLE link budget and rate)."""
        p = self._people.get(int(emitter_id))
        if p is None or not p.batches:  # (a real sensor hears beacons whatever the simulation's share)
            return self.scenario
        return ble_view(self.scenario) if radio_of(p.batches[0]) == BLE else self.scenario

    def _bursts_of(self, p: "_Person") -> tuple:
        """``p``'s bursts as each vehicle heard them, and every vehicle that listened during one of
        them (its flight log within LISTEN_GAP_S of the burst, its receiver's reports through the
        burst) and heard none of it."""
        from ..estimation.burst_grid import Burst, bursts_from_slots, steady_addresses
        from ..estimation.evidence import LISTEN_GAP_S

        heard = bursts_from_slots(p.batches[0])
        out = list(heard)
        if radio_of(p.batches[0]) == BLE:  # a fixed schedule: every event missed is known
            from ..estimation.burst_grid import missed_beacons

            tracks = {}
            for v, parts in self._tracks.items():
                if len(parts) > 1:
                    self._tracks[v] = parts = [(np.concatenate([a for a, _ in parts]),
                                                np.vstack([c for _, c in parts]))]
                tracks[v] = parts[0]
            return tuple(out + missed_beacons(heard, self.scenario.emission.ble_interval_s, tracks,
                                              listen_gap_s=LISTEN_GAP_S, heard_until=self._heard_until))
        # the vehicles that heard none of a burst: only probe bursts are sent to every vehicle; a
        # phone answers the access point it joined, under the address it keeps, and only that
        # vehicle is known to hear it (sim_link's world: the others never do). A phone with one
        # address for everything cannot be told apart: all its units count, as before.
        own = np.isin(p.batches[0].address, steady_addresses(p.batches[0]))
        sent_to_all = bursts_from_slots(p.batches[0].take(~own)) if own.any() and not own.all() else heard
        times: list[float] = []
        for b in sent_to_all:  # one burst heard by several vehicles is one time
            if not times or b.t_s - times[-1] > 2.0:
                times.append(b.t_s)
        tracks = {}
        for v, parts in self._tracks.items():
            if len(parts) > 1:
                self._tracks[v] = parts = [(np.concatenate([a for a, _ in parts]), np.vstack([c for _, c in parts]))]
            tracks[v] = parts[0]
        for t in times:
            hearers = {b.vehicle for b in heard if abs(b.t_s - t) <= 2.0}
            for v, (tt, xyz) in tracks.items():
                if v in hearers or len(tt) == 0 or self._heard_until.get(v, math.inf) < t + 1.0:
                    continue
                k = int(np.argmin(np.abs(tt - t)))
                if abs(tt[k] - t) > LISTEN_GAP_S:
                    continue
                order = np.argsort(tt)
                pos = [float(np.interp(t, tt[order], xyz[order, c])) for c in range(3)]
                out.append(Burst(float(t), int(v), (pos[0], pos[1], pos[2])))
        return tuple(out)

    def _fit_order(self) -> list["_Person"]:
        """People with data not yet fitted, most urgent first: a look at them is under way or
        planned, then the other pending people, newest data first."""
        def urgency(p: "_Person"):
            looked_at = p.emitter_id in self._flown or p.emitter_id in self._awaiting
            return (0 if looked_at else 1, -p.last_slot_t_s, p.emitter_id)

        todo = [p for p in self._people.values()
                if p.dirty and not p.fitting and p.fix_t_s is None and not p.gave_up]
        return sorted(todo, key=urgency)

    def heard_slots(self, emitter_id: int) -> SlotBatch:
        """Every slot the policy holds as the person ``emitter_id``'s (linked, when a sensor reports
        fingerprints); empty for an unknown id. What a bench compares with the truth."""
        p = self._people.get(int(emitter_id))
        if p is None or not p.batches:
            return SlotBatch.empty()
        return SlotBatch.concat(p.batches)
