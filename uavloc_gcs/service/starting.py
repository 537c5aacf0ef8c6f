"""Starting a mission: the facts the decision reads, read at the moment it acts, and what makes a
start safe and what makes it a start at all.

Issue 26: a look planned while a vehicle hovered had no take-off; its upload stalled, the vehicle
landed meanwhile, and the daemon then started it on the strength of "airborne", read before the
upload: PX4 armed by the mission start and climbed off the ground towards a point 442 m away.
And an ArduCopter that refused its start ("Auto: Missing Takeoff Cmd") was taken for started;
its scan was "finished" 0.8 s later with nothing flown.

Rules, each a function of facts read now (:func:`read_facts`, never kept across an await):

* :func:`start_refusal` -- a mission is started on a vehicle on the ground only when it goes on
  with a take-off from the item it starts at; the check runs again right before every arm and
  every MISSION_START (the link layer's ``before_start``), so a vehicle that landed during any
  await before it is not started.
* :func:`start_refusal` also refuses to arm a vehicle that reports it is not ready (SYS_STATUS
  pre-arm check bit unhealthy, no 3D GPS fix, PX4's estimator without an absolute position:
  ``VehicleAgent.not_ready``); the start first waits up to ``READY_WAIT_S`` for it to be ready,
  and the link layer arms only in the mode the start needs (GUIDED / Hold), never a manual one.
* :func:`takeoff_seen` -- a start from the ground is a start once the vehicle climbs; a
  refusal the vehicle states (:data:`REFUSALS`) or no climb within ``CLIMB_WAIT_S`` is a failed
  start (:class:`StartFailed`, with the vehicle's own words), never a scan flown.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Sequence

from ..errors import LinkError, UavlocError
from ..mission import NAV_RETURN_TO_LAUNCH, POSITIONAL_COMMANDS, TAKEOFF_COMMANDS, WireItem

CLIMB_WAIT_S = 20.0  # wall seconds after a start from the ground for the vehicle to leave the ground
READY_WAIT_S = 120.0  # wall seconds a start waits for the vehicle to be ready to arm (EKF, GPS, pre-arm)
REFUSAL_GRACE_S = 2.0  # wall seconds a vehicle that stated a refusal has to show it flies the mission anyway
CLIMB_M = 2.0  # above LANDED_ALT_M: metres of relative altitude that count as "it left the ground"
# What autopilots say when they refuse to start or to fly what they were told (lower case):
# ArduCopter ModeAuto::init "Auto: Missing Takeoff Cmd"; Copter::set_mode "Mode change to Auto
# failed: requires position"; PX4 "Mission start denied! No valid mission", "Arming denied: ...".
REFUSALS = ("missing takeoff", "mode change to auto failed", "start denied", "arming denied", "takeoff denied",
            "mission rejected")


class UnsafeStart(UavlocError):
    """Starting this mission now would send the vehicle up without a take-off item (not a link
    fault: the caller re-plans with a take-off or holds; nothing was sent)."""

    def __init__(self, message: str, *, vehicle: int):
        self.vehicle = vehicle
        super().__init__(f"vehicle {vehicle}: {message}")


class StartFailed(LinkError):
    """The vehicle was told to start and did not: it said why, or it never left the ground."""


@dataclass(frozen=True)
class StartFacts:
    """What a start decision reads, as the vehicle reported it last."""

    armed: bool
    on_ground: bool
    mode: str
    mission_seq: int | None
    rel_alt_m: float
    not_ready: str | None = None  # why it is not ready to arm, as it reports it (None: ready, or nothing said)


def read_facts(agent) -> StartFacts:
    """The facts now (``agent``: a :class:`~.vehicle.VehicleAgent`)."""
    t = agent.tel
    not_ready = getattr(agent, "not_ready", None)
    return StartFacts(bool(t.armed), bool(agent.on_ground()), str(t.mode), t.mission_seq, float(t.rel_alt_m),
                      not_ready() if not_ready is not None else None)


def takeoff_first(items: Sequence[WireItem], first_seq: int) -> bool:
    """Whether flying ``items`` from ``first_seq`` begins with a take-off: the first navigation
    item from there, DO items skipped (as ArduPilot's ``AP_Mission::starts_with_takeoff_cmd``)."""
    for it in items:
        if it.seq < first_seq:
            continue
        if it.command in TAKEOFF_COMMANDS:
            return True
        if it.command in POSITIONAL_COMMANDS or it.command == NAV_RETURN_TO_LAUNCH:
            return False
    return False


def start_refusal(facts: StartFacts, items: Sequence[WireItem], first_seq: int) -> str | None:
    """Why ``items`` must not be started from ``first_seq`` now, or None when it may: on the
    ground only with a take-off, and armed only when the vehicle says it is ready (issue 26: an
    ArduCopter armed before its EKF used GPS, then refused AUTO "requires position" x3)."""
    if not facts.armed and facts.not_ready:
        return f"it is not ready to arm: {facts.not_ready}"
    if facts.on_ground and not takeoff_first(items, first_seq):
        armed = "armed" if facts.armed else "disarmed"
        return f"it is on the ground ({armed}, {facts.mode}) and its mission has no take-off from item {first_seq}"
    return None


def start_guard(agent, items: Sequence[WireItem], first_seq: int, vehicle: int) -> Callable[[], None]:
    """A check that raises :class:`UnsafeStart` when :func:`start_refusal` says no, reading the
    facts each time it is called (right before each arm and MISSION_START)."""
    items = list(items)

    def check() -> None:
        reason = start_refusal(read_facts(agent), items, first_seq)
        if reason is not None:
            raise UnsafeStart(f"not started: {reason}", vehicle=vehicle)

    return check


def refusal_in(texts, since_wall_s: float) -> str | None:
    """The latest refusal among ``texts`` ((wall s, text) pairs) that came at or after ``since_wall_s``."""
    found = [text for wall_s, text in texts if wall_s >= since_wall_s and any(w in text.lower() for w in REFUSALS)]
    return found[-1] if found else None


def takeoff_seen(facts: StartFacts, ground_alt_m: float) -> bool:
    """Whether the vehicle has left the ground since the start (armed and climbing)."""
    return facts.armed and not facts.on_ground and math.isfinite(facts.rel_alt_m) \
        and facts.rel_alt_m >= ground_alt_m + CLIMB_M
