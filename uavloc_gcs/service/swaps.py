"""Sorties in flight (issue 38): a vehicle home at its reserve waits on the ground for a fresh
pack, then is started again exactly as on a first start. Mixed into :class:`~.daemon.Daemon`.

With ``fleet.batteries`` > 1 each vehicle's scan is flown as the sorties ``uavloc_gcs.sorties``
cuts it into: the first is uploaded and started as the scan always was; every other one ends in
RTL, and its landing (``VehicleLife.observe``) is its end. Then, each tick (:meth:`_pack_step`,
on the facts read then):

* a vehicle that has flown on its pack and is home, on the ground and disarmed, with packs left,
  waits ("waiting for pack") when it has sorties of its scan left or reports less than
  SWAP_BELOW_PCT remaining; otherwise it flies its looks on what it has (the planner counts it);
* a waiting vehicle is asked for its battery every PACK_POLL_S (``link.check_fresh_pack``) and is
  ready again when it reports a fresh pack, or when the operator says so (:meth:`pack_fresh`, or
  ``uavloc pack-fresh`` from another process, through the store) and the vehicle reports no figure
  that says otherwise;
* ready, it is prepared as on a first start: it waits until it says it is ready to arm (its
  swap rebooted it), its next sortie is uploaded and started with the first start's checks and
  take-off confirmation (``_start``), or, its scan flown, it is left on the ground for the next
  plan, whose look starts with a take-off;
* until it is in the air again it is not ready to arm while it reports less remaining than a
  fresh pack (``VehicleAgent.pack_floor_pct``), read at every arm: a pack that is not fresh is
  never launched;
* a vehicle whose packs are spent stays down: the planner gives its looks to the others (it plans
  with the charge each reports), and sorties of its scan it could not fly are reported unsearched.

A restarted daemon resumes a search flown in sorties: each vehicle's sortie, packs left and flown
and whether it flew on the pack it has are kept in the store (:meth:`_save_sorties`, every tick
they change); the restart plans the sorties again from the scenario, takes each vehicle's up from
its sortie, and a vehicle found on the ground after a sortie it flew waits for a fresh pack, as
if the daemon had seen it land (``service/preparing.py``).
"""

from __future__ import annotations

import asyncio
import logging
import sqlite3
import time

from ..errors import LinkError, UavlocError
from ..link.battery import FRESH_REMAINING_PCT, PackVerdict, check_fresh_pack, pack_limits
from .store import PACK_FRESH_REQUEST, StoreReader
from .vehiclelife import VehicleLife as _Vehicle

log = logging.getLogger(__name__)

WAITING_FOR_PACK = "waiting for pack"  # a vehicle's phase on the ground until its pack is fresh
PACK_POLL_S = 2.0  # wall seconds between two asks of a waiting vehicle's battery
# A vehicle home from its looks with at least this much left flies on without a swap: a swap
# takes a pack and battery_swap_s, and the planner plans with the charge it reports.
SWAP_BELOW_PCT = 50.0


def _reported_not_fresh(verdict: PackVerdict | None) -> bool:
    """Whether the vehicle reported a figure that says its pack is not fresh (not merely too little
    to tell: then the operator's word decides)."""
    if verdict is None or verdict.fresh:
        return False
    r = verdict.reading
    if r.remaining_pct is None:
        return False
    return not (r.remaining_pct >= FRESH_REMAINING_PCT and r.voltage_v is None and r.charge_state is None)


class PackSwaps:
    """The swaps between sorties, for :class:`~.daemon.Daemon`."""

    def _sortie_wires(self, plan, hold_s: float) -> dict[int, list]:
        """Each vehicle's scan as its sorties' wire missions ({vehicle: [sortie 1, sortie 2, ...]}):
        every sortie ends in RTL; the last holds at its end (as a scan does) until the longest
        vehicle's sorties, swaps included, are over plus ``hold_s``."""
        from ..mission import to_wire  # noqa: PLC0415
        from ..sorties import scan_sorties, sortie_missions  # noqa: PLC0415
        from ..terrain_missions import terrain_safe  # noqa: PLC0415
        from .missionstate import with_hold_before_rtl  # noqa: PLC0415

        pp = getattr(self, "_scan_pod", None)
        sorties = (getattr(pp, "sorties", ()) if pp is not None else ()) or scan_sorties(self.sc, plan)
        longest = max((sp.duration_s for sp in sorties), default=0.0)
        out = {}
        for vid, p, sp, missions in zip(sorted(self.vehicles), plan.vehicles, sorties,
                                        sortie_missions(self.sc, plan, sorties)):
            last = len(missions) - 1
            held = [with_hold_before_rtl(m, longest - sp.duration_s + hold_s) if j == last else m
                    for j, m in enumerate(missions)]
            out[vid] = [to_wire(terrain_safe(m, self.sc, name=f"uav{p.index + 1} sortie {j + 1}"),
                                self.sc.fleet.autopilot) for j, m in enumerate(held)]
        return out

    def _sortie_state(self) -> dict:
        return {str(v.id): {"sortie": v.sortie, "left": len(v.sorties), "packs_left": v.packs_left,
                            "packs_flown": v.packs_flown, "unflown": v.unflown_sorties,
                            "pack_counted": bool(v.pack_counted), "scan_done": bool(v.scan_done)}
                for v in self.vehicles.values()}

    def _save_sorties(self) -> None:
        """Keep each vehicle's sortie state in the store when it changed (a restart resumes it)."""
        if self.sc.fleet.batteries <= 1 or self.store is None:
            return
        state = self._sortie_state()
        if state != getattr(self, "_saved_sorties", None):
            self.store.set_meta("sorties", state)
            self._saved_sorties = state

    def _restore_sorties(self, sorties: dict) -> dict[int, int]:
        """After a restart: each vehicle's sortie state as stored, on the sorties planned again
        (``sorties``: vehicle -> its sorties' wire missions). {vehicle: the sortie it flies}."""
        stored = getattr(self, "_stored_sorties", None) or {}
        out = {}
        for v in self.vehicles.values():
            st = stored.get(v.id)
            if st is None:
                continue
            planned = sorties.get(v.id) or []
            k = int(st["sortie"])
            if not 1 <= k <= len(planned) or len(planned) - k != int(st["left"]) and not st.get("scan_done"):
                raise UavlocError(f"the stored search flew vehicle {v.id}'s scan in sorties that the scenario no longer "
                                  f"plans (sortie {k} of {k + int(st['left'])} stored, {len(planned)} planned now); "
                                  "start a new search with --fresh or another --out")
            v.sortie, v.sorties = k, list(planned[k:]) if not st.get("scan_done") else []
            v.packs_left, v.packs_flown = int(st["packs_left"]), int(st["packs_flown"])
            v.unflown_sorties, v.pack_counted = int(st["unflown"]), bool(st["pack_counted"])
            out[v.id] = k
        if out:
            self._event("resume", "sorties resumed: " + ", ".join(
                f"vehicle {vid} on sortie {k} ({self.vehicles[vid].packs_left} pack(s) left)" for vid, k in out.items()))
        return out

    async def _resume_landed_sortie(self, v: _Vehicle, items: list) -> str | None:
        """After a restart: ``v`` is on the ground, disarmed, with sortie ``v.sortie``'s mission on
        board. "wait": it flew that sortie on the pack it has (landing was its end, as
        VehicleLife.observe takes it): it waits for the team's swap. "start": it was given the
        sortie on a fresh pack and had not taken off: it is started. None: its last sortie, resumed
        as a scan is (``_resume_landed_scan``). Each sortie flies on a pack of its own, so the
        sortie was flown when as many packs were flown as its number."""
        flown = v.packs_flown >= v.sortie
        if flown and not v.sorties:
            return None
        if flown and v.pack_counted:
            self._adopt(v, "scan", items)
            v.home, v.phase, v.pack_flown = True, "landed", True
            self._event("resume", f"vehicle {v.id} is on the ground, disarmed, after sortie {v.sortie} of its scan: "
                        "it waits for a fresh pack", v.id)
            return "wait"
        if flown:  # its pack was swapped and judged fresh; its next sortie was not uploaded yet
            items = v.sorties.pop(0)
            v.sortie += 1
            v.phase, v.home = "uploading scan", False
            self._event("resume", f"vehicle {v.id} is on the ground on a fresh pack: it flies sortie {v.sortie} "
                        "of its scan", v.id)
            await self._upload(v, "scan", items, first_seq=None)
            return "start"
        self._adopt(v, "scan", items)
        v.phase = "uploading scan"
        self._event("resume", f"vehicle {v.id} is on the ground on a fresh pack with sortie {v.sortie} of its scan "
                    "on board, not flown: it is started", v.id)
        return "start"

    def _pack_step(self, v: _Vehicle) -> None:
        """After ``v``'s state machine stepped: start waiting for a pack, or say its packs are spent
        (see the module docstring), on the facts read now."""
        a = v.agent
        if self.sc.fleet.batteries <= 1 or a is None or v.lost or v.unusable:
            return
        if a.tel.armed and not a.on_ground():
            v.pack_flown = True
            if not v.pack_counted:
                v.packs_flown, v.pack_counted = v.packs_flown + 1, True
            a.pack_floor_pct = None  # launched: the floor is for a launch
            return
        if (v.waiting or v.job is not None or not v.home or not v.pack_flown or self._finishing_since is not None
                or a.tel.armed or not a.on_ground()):
            return
        v.pack_flown = False  # (judged once per landing)
        pct = a.tel.battery_pct
        if v.packs_left <= 0:
            if v.sorties:
                v.unflown_sorties, v.sorties, v.scan_done = len(v.sorties), [], True
                self._event("pack", f"vehicle {v.id} landed with its packs spent and {v.unflown_sorties} sortie(s) of "
                            "its scan unflown: it stays down, and that part of the area is not searched", v.id)
            return
        if not v.sorties and (pct is None or pct >= SWAP_BELOW_PCT):
            return  # flies its looks on what it has
        v.waiting, v.phase = "a fresh pack", WAITING_FOR_PACK
        a.pack_floor_pct = FRESH_REMAINING_PCT
        left = "" if pct is None else f" with {pct:.0f} % left"
        nxt = f"sortie {v.sortie + 1} of its scan" if v.sorties else "its looks"
        self._event("pack", f"vehicle {v.id} landed{left} and waits for a fresh pack ({v.packs_left} left): it flies "
                    f"{nxt} once it reports a fresh pack, or when the operator says so", v.id)
        self._launch(v, self._await_pack(v))

    def _packs_text(self) -> str:
        """The statement's sentences on sorties: flown per vehicle, packs left, scan sorties unflown."""
        rows = ", ".join(f"vehicle {v.id} {v.packs_flown} ({v.packs_left} left)" for v in self.vehicles.values())
        text = f"Sorties flown (packs left): {rows}."
        for v in self.vehicles.values():
            if v.unflown_sorties:
                text += (f" Vehicle {v.id} did not fly {v.unflown_sorties} sortie(s) of its scan (its packs were "
                         "spent); that part of the area was not searched.")
        return text

    def pack_fresh(self, vehicle: int) -> str:
        """The operator says ``vehicle``'s pack is fresh: it is launched unless it reports a figure
        that says otherwise. One sentence saying what happens."""
        v = self.vehicles.get(vehicle)
        if v is None:
            raise UavlocError(f"there is no vehicle {vehicle} in this search (vehicles {sorted(self.vehicles)})")
        if not v.waiting:
            return f"vehicle {vehicle} does not wait for a pack (it is {v.phase}); nothing to do"
        v.operator_fresh = True
        text = f"the operator says vehicle {vehicle} has a fresh pack; it is checked before it is launched"
        self._event("operator", text, vehicle)
        return text

    def _operator_requests(self, v: _Vehicle, since_wall: float, heard: int) -> int:
        """Take the operator's "fresh pack" for ``v`` recorded in the store since ``since_wall``
        (``uavloc pack-fresh``) beyond the ``heard`` already taken; the number taken now."""
        try:
            with StoreReader(self.opt.store_path) as rd:
                n = sum(1 for e in rd.events(PACK_FRESH_REQUEST) if e.vehicle == v.id and e.wall_s >= since_wall)
        except sqlite3.Error as exc:  # read again at the next poll
            log.info("vehicle %d: operator requests not read: %s", v.id, exc)
            return heard
        if n > heard:
            self.pack_fresh(v.id)
        return n

    async def _await_pack(self, v: _Vehicle) -> None:
        """Wait until ``v`` reports a fresh pack (or the operator says so), then prepare it as on a
        first start and give it its next sortie, or leave it on the ground for the next plan."""
        a = v.agent
        limits, said, verdict = None, "", None
        since_wall, heard = time.time(), 0  # the operator's requests from another process (uavloc pack-fresh)
        while True:
            heard = self._operator_requests(v, since_wall, heard)
            verdict, why, asked = None, "it does not answer (a swap reboots it)", False
            if a.silent_for_s() < 1.0 and a.on_ground() and not a.tel.armed:  # heard now, on the ground
                asked = True
                try:
                    if limits is None:
                        limits = await pack_limits(v.link, v.id, a.flavour)
                    verdict = await check_fresh_pack(v.link, v.id, a.flavour, limits=limits,
                                                     vehicle=f"vehicle {v.id}")
                    why = verdict.reason
                except LinkError as exc:
                    why = f"it did not report its battery ({exc})"
            if verdict is not None and verdict.fresh:
                break
            if v.operator_fresh and asked:  # (while it does not answer, the operator's word waits)
                if not _reported_not_fresh(verdict):
                    break
                v.operator_fresh = False
                self._event("pack", f"vehicle {v.id}: the operator said its pack is fresh, but {why}; "
                            "it is not launched", v.id)
            elif why != said:
                self._event("pack", f"vehicle {v.id} waits for a fresh pack: {why}", v.id)
            said = why
            await asyncio.sleep(PACK_POLL_S)
        how = verdict.reason if verdict is not None and verdict.fresh else f"the operator said so ({why})"
        v.packs_left -= 1
        v.waiting, v.operator_fresh, v.pack_counted = "", False, False
        self._event("pack", f"vehicle {v.id} is ready again: {how}; {v.packs_left} pack(s) left; it is prepared "
                    "as on a first start", v.id)
        await self._until_ready(v)  # readiness before arming: the swap rebooted it
        if not v.sorties:
            v.phase = "landed"  # home: the next plan's look starts with a take-off
            self._replan_due = True
            return
        items = v.sorties.pop(0)
        v.sortie += 1
        v.phase, v.home = "uploading scan", False
        await self._upload(v, "scan", items, first_seq=None)
        await self._start(v)
        self._event("start", f"vehicle {v.id} started sortie {v.sortie} of its scan", v.id)
