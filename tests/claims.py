"""What a search said about its vehicles, checked against what the vehicles said (issue 42).

The daemon stores every event with the host's time (``events.wall_s``) and writes every packet it
received to a ``.tlog`` stamped with the same clock, before it decodes it. So for each claim we
know what the vehicle had told the daemon when the claim was made: the last HEARTBEAT (armed or
not) and the last EXTENDED_SYS_STATE (landed state) of that vehicle received before it.

:func:`false_claims` lists the claims that telemetry does not support:

* a ``landed`` event for a vehicle whose last HEARTBEAT said armed, or whose last landed state
  (where it sends one) was not ON_GROUND;
* a statement that "All vehicles are home" while any vehicle heard in the search was, by its last
  messages, armed or not on the ground.

Shared by the end-to-end tests on the fakes and the SITL searches (tests/sitl/daemon_run.py).
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field
from pathlib import Path

from uavloc_gcs.dialect import mavlink
from uavloc_gcs.link.tlog import iter_tlog
from uavloc_gcs.service.store import StoreReader

MAV_AUTOPILOT_INVALID = 8  # a companion's or ground station's HEARTBEAT, not the autopilot's


@dataclass
class _Said:
    """One vehicle's armed state and landed state over time (host seconds), as received."""

    armed_t: list = field(default_factory=list)
    armed: list = field(default_factory=list)
    landed_t: list = field(default_factory=list)
    landed: list = field(default_factory=list)

    @staticmethod
    def _at(ts: list, values: list, t_s: float):
        i = bisect.bisect_right(ts, t_s)
        return values[i - 1] if i else None

    def at(self, t_s: float) -> tuple[bool | None, int | None]:
        """(armed, landed state) by the last messages received at or before host time ``t_s``."""
        return self._at(self.armed_t, self.armed, t_s), self._at(self.landed_t, self.landed, t_s)


def vehicle_reports(out_dir: Path) -> dict[int, _Said]:
    """Every vehicle's HEARTBEAT armed flag and EXTENDED_SYS_STATE landed state from the .tlog
    files in ``out_dir``, by MAVLink system id."""
    said: dict[int, _Said] = {}
    for path in sorted(Path(out_dir).glob("*.tlog")):
        for t_us, m in iter_tlog(path):
            kind = m.get_type()
            if kind == "HEARTBEAT" and m.autopilot != MAV_AUTOPILOT_INVALID:
                s = said.setdefault(m.get_srcSystem(), _Said())
                s.armed_t.append(t_us / 1e6)
                s.armed.append(bool(m.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED))
            elif kind == "EXTENDED_SYS_STATE" and m.landed_state != mavlink.MAV_LANDED_STATE_UNDEFINED:
                s = said.setdefault(m.get_srcSystem(), _Said())
                s.landed_t.append(t_us / 1e6)
                s.landed.append(int(m.landed_state))
    for s in said.values():  # several links' files: one time order per vehicle
        for ts, vs in ((s.armed_t, s.armed), (s.landed_t, s.landed)):
            order = sorted(range(len(ts)), key=ts.__getitem__)
            ts[:], vs[:] = [ts[i] for i in order], [vs[i] for i in order]
    return said


def _down(armed: bool | None, landed: int | None) -> bool:
    return armed is False and landed in (None, mavlink.MAV_LANDED_STATE_ON_GROUND)


def false_claims(out_dir: Path, store: Path | None = None) -> list[str]:
    """The claims about vehicles in ``out_dir``'s search that its telemetry does not support (see
    the module docstring); one sentence each, empty when every claim holds."""
    said = vehicle_reports(out_dir)
    with StoreReader(store or Path(out_dir) / "search.sqlite") as rd:
        events = rd.events()
    wrong = []
    for e in events:
        if e.kind == "landed" and e.vehicle is not None:
            armed, landed = said.get(e.vehicle, _Said()).at(e.wall_s)
            if not _down(armed, landed):
                wrong.append(f"'{e.text}' while vehicle {e.vehicle} said armed={armed}, landed state {landed}")
        if e.kind == "end" and "All vehicles are home" in e.text:
            for vid, s in sorted(said.items()):
                armed, landed = s.at(e.wall_s)
                if not _down(armed, landed):
                    wrong.append(f"'All vehicles are home' while vehicle {vid} said armed={armed}, "
                                 f"landed state {landed}")
    return wrong
