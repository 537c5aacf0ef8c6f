"""Small pure helpers of the daemon: the mission clock's rate, and comparing missions/routes."""

from __future__ import annotations

import dataclasses
from typing import Sequence

import numpy as np

from ..mission import (NAV_LOITER_TIME, NAV_WAYPOINT, NAV_RETURN_TO_LAUNCH, POSITIONAL_COMMANDS, MissionItem, MissionPlan, WireItem,
                       return_to_launch)


class ClockRate:
    """Mission seconds per wall second, from the vehicles' SYSTEM_TIME (the fake fleet's speed-up;
    1 for real vehicles). Feed it each vehicle's :class:`~.vehicle.Telemetry`."""

    def __init__(self) -> None:
        self.rate = 1.0
        self._first: dict[int, tuple[float, float]] = {}

    def observe(self, tel) -> None:
        if tel.unix_s is None or tel.unix_wall_s is None:
            return
        first = self._first.setdefault(id(tel), (tel.unix_s, tel.unix_wall_s))
        dw = tel.unix_wall_s - first[1]
        if dw > 0.5:
            self.rate = max(1e-3, (tel.unix_s - first[0]) / dw)


def without_final_rtl(plan: MissionPlan) -> MissionPlan:
    """The mission without its closing RTL (the vehicle then holds at its last waypoint)."""
    items = plan.items
    if items and items[-1].command == NAV_RETURN_TO_LAUNCH:
        return dataclasses.replace(plan, items=items[:-1])
    return plan


def final_seq(items: Sequence[WireItem]) -> int:
    """Seq of the mission's last RTL item, else of its last item (0 when empty)."""
    rtl = [it.seq for it in items if it.command == NAV_RETURN_TO_LAUNCH]
    return rtl[-1] if rtl else (items[-1].seq if items else 0)


def same_stored_mission(on_board: Sequence[WireItem], sent: Sequence[WireItem], flavour) -> bool:
    """Whether the vehicle stores what we sent (ArduPilot rewrites item 0 with its home);
    ``flavour`` is a ``link.Flavour``."""
    if len(on_board) != len(sent):
        return False
    skip = 1 if flavour.home_at_seq0 else 0
    return all(flavour.stored_equal(s, g) for s, g in zip(sent[skip:], on_board[skip:]))


def same_route(a: np.ndarray, b: np.ndarray | None, tolerance_m: float) -> bool:
    """Same number of points, each within ``tolerance_m`` [m] of its counterpart."""
    if b is None or a.shape != b.shape:
        return False
    return bool(np.all(np.linalg.norm(a - b, axis=1) <= tolerance_m))


def with_hold_before_rtl(plan: MissionPlan, hold_s: float) -> MissionPlan:
    """The mission with a NAV_LOITER_TIME of ``hold_s`` seconds at its last waypoint before its
    closing RTL: the vehicle waits there for its next mission, and flies home by itself when none
    comes. A mission without a closing RTL gets one."""
    items = list(plan.items)
    if items and items[-1].command == NAV_RETURN_TO_LAUNCH:
        items.pop()
    last = next((it for it in reversed(items) if it.command in POSITIONAL_COMMANDS), None)
    if last is not None:
        items.append(MissionItem(NAV_LOITER_TIME, last.frame, (float(round(max(0.0, hold_s))), 0.0, 0.0, 0.0),
                                 last.lat_deg, last.lon_deg, last.alt_m))
    items.append(return_to_launch())
    return dataclasses.replace(plan, items=tuple(items))


def hold_seq(items: Sequence[WireItem]) -> int:
    """Seq of the hold before the mission's closing RTL (0 when there is none)."""
    rtl = final_seq(items)
    holds = [it.seq for it in items if it.command == NAV_LOITER_TIME and it.seq < rtl]
    return holds[-1] if holds else 0


def scan_rest(items: Sequence[WireItem], from_seq: int) -> list[WireItem]:
    """The scan ``items`` flown again from item ``from_seq``: what comes before its first waypoint
    (ArduPilot's home, the take-off, the speed) then everything from ``from_seq`` on, renumbered.
    For a vehicle that landed mid-scan: it takes off and flies only the unflown rest."""
    first_wp = next((it.seq for it in items if it.command == NAV_WAYPOINT and it.seq > 0), None)
    if first_wp is None or from_seq <= first_wp:
        return list(items)
    kept = [it for it in items if it.seq < first_wp or it.seq >= from_seq]
    return [dataclasses.replace(it, seq=i) for i, it in enumerate(kept)]
