"""Does the vehicle report a fresh pack? The one exchange the daemon needs for sorties (issue 38).

A vehicle back from a sortie lands and waits for its pack to be swapped; it may be launched again
only when *it* reports a fresh pack. :func:`check_fresh_pack` asks for BATTERY_STATUS and
SYS_STATUS with MAV_CMD_REQUEST_MESSAGE (registering for the replies before sending), reads what
the pack's full and empty voltages are (:func:`pack_limits`, once per vehicle) and judges
(:func:`judge_pack`, pure): fresh when the remaining charge is at least FRESH_REMAINING_PCT, the
charge state is OK and the voltage at least FRESH_VOLTAGE_SHARE of the way from empty to full.

Both figures, because each autopilot can be wrong in its own way (measured on ../shared/sitl,
docs/guide/sitl.md "Battery"): ArduPilot counts the charge from the current it integrated since
boot, so after the reboot a swap causes it says 100 % of any pack and only the voltage tells a
used one; PX4 judges by the voltage. Where the full voltage is not known the remaining decides
alone, and the verdict says so. The full and empty voltages: PX4 ``BAT1_N_CELLS`` x
``BAT1_V_CHARGED`` / ``BAT1_V_EMPTY`` (an integer parameter it packs bit for bit), ArduPilot
``MOT_BAT_VOLT_MAX`` / ``MOT_BAT_VOLT_MIN`` (the voltage range its thrust scaling assumes; set by
the operator, 0 = unknown).

Timeouts: MAV_CMD_REQUEST_MESSAGE is a command (command.py's devguide timeout and retries); the
message it asks for comes within REPLY_TIMEOUT_S of the ACK or is taken as not sent.
"""

from __future__ import annotations

import asyncio
import logging
import time
from dataclasses import dataclass

from ..dialect import mavlink
from ..errors import CommandError
from .autopilots import Flavour
from .command import command_long
from .connection import Link
from .params import read_param_number

log = logging.getLogger(__name__)

FRESH_REMAINING_PCT = 95.0  # a fresh pack reports at least this much remaining
FRESH_VOLTAGE_SHARE = 0.9  # ... and a voltage at least this far from empty to full (LiPo at rest: ~85 %
#                            charge at 90 % of the 3.5-4.2 V range per cell; ArduPilot SITL's table)
REPLY_TIMEOUT_S = 1.5  # the requested message after the command's ACK (the devguide's command timeout)
MESSAGES = ("BATTERY_STATUS", "SYS_STATUS")

_STATES = {mavlink.MAV_BATTERY_CHARGE_STATE_OK: "OK", mavlink.MAV_BATTERY_CHARGE_STATE_LOW: "LOW",
           mavlink.MAV_BATTERY_CHARGE_STATE_CRITICAL: "CRITICAL", mavlink.MAV_BATTERY_CHARGE_STATE_EMERGENCY: "EMERGENCY",
           mavlink.MAV_BATTERY_CHARGE_STATE_FAILED: "FAILED", mavlink.MAV_BATTERY_CHARGE_STATE_UNHEALTHY: "UNHEALTHY",
           mavlink.MAV_BATTERY_CHARGE_STATE_CHARGING: "CHARGING"}


@dataclass(frozen=True)
class BatteryReading:
    """What a vehicle said of its pack (None: not reported). ``source``: the messages it came from."""

    voltage_v: float | None
    remaining_pct: float | None
    current_a: float | None = None
    consumed_mah: float | None = None
    charge_state: int | None = None  # MAV_BATTERY_CHARGE_STATE (BATTERY_STATUS only)
    source: str = ""

    @classmethod
    def from_messages(cls, battery_status=None, sys_status=None) -> "BatteryReading":
        """BATTERY_STATUS first (battery 0: voltage of its cells, charge state), SYS_STATUS where
        it says nothing."""
        v = rem = cur = mah = state = None
        used = []
        if battery_status is not None:
            used.append("BATTERY_STATUS")
            cells = [c for c in battery_status.voltages if c not in (0, 65535)]
            v = sum(cells) / 1000.0 if cells else None  # a total in voltages[0], or each cell
            rem = None if battery_status.battery_remaining < 0 else float(battery_status.battery_remaining)
            cur = None if battery_status.current_battery < 0 else battery_status.current_battery / 100.0
            mah = None if battery_status.current_consumed < 0 else float(battery_status.current_consumed)
            state = int(battery_status.charge_state) or None
        if sys_status is not None and (v is None or rem is None):
            used.append("SYS_STATUS")
            if v is None and sys_status.voltage_battery not in (0, 65535):
                v = sys_status.voltage_battery / 1000.0
            if rem is None and sys_status.battery_remaining >= 0:
                rem = float(sys_status.battery_remaining)
            if cur is None and sys_status.current_battery >= 0:
                cur = sys_status.current_battery / 100.0
        return cls(v, rem, cur, mah, state, " and ".join(used))


@dataclass(frozen=True)
class PackLimits:
    """A pack's voltage when full and when empty [V], and the parameters that said so."""

    full_v: float
    empty_v: float
    source: str

    @property
    def fresh_v(self) -> float:
        """The least voltage a fresh pack shows."""
        return self.empty_v + FRESH_VOLTAGE_SHARE * (self.full_v - self.empty_v)


@dataclass(frozen=True)
class PackVerdict:
    """Whether the pack counts as fresh, and one sentence why (for the log and the live view)."""

    fresh: bool
    reason: str
    reading: BatteryReading


def judge_pack(reading: BatteryReading, limits: PackLimits | None, *, vehicle: str = "the vehicle") -> PackVerdict:
    """A fresh pack or not, from what the vehicle reported (see the module docstring)."""
    r = reading
    said = ", ".join(x for x in (
        None if r.remaining_pct is None else f"{r.remaining_pct:.0f} % remaining",
        None if r.voltage_v is None else f"{r.voltage_v:.2f} V",
        None if r.charge_state is None else f"charge state {_STATES.get(r.charge_state, r.charge_state)}") if x)
    head = f"{vehicle} reports {said or 'nothing of its battery'} ({r.source or 'no battery message'})"
    if r.remaining_pct is None:
        return PackVerdict(False, f"{head}: no remaining charge reported, so it is not judged fresh", r)
    if r.remaining_pct < FRESH_REMAINING_PCT:
        return PackVerdict(False, f"{head}: not a fresh pack (a fresh one reports {FRESH_REMAINING_PCT:g} % or more)", r)
    if r.charge_state is not None and r.charge_state != mavlink.MAV_BATTERY_CHARGE_STATE_OK:
        return PackVerdict(False, f"{head}: not a fresh pack (its charge state is not OK)", r)
    if limits is None:
        return PackVerdict(True, f"{head}: a fresh pack by the remaining charge alone (its full voltage is unknown)", r)
    if r.voltage_v is None:
        return PackVerdict(False, f"{head}: no voltage reported, so it is not judged fresh", r)
    if r.voltage_v < limits.fresh_v:
        return PackVerdict(False, f"{head}: not a fresh pack, {r.voltage_v:.2f} V is below the {limits.fresh_v:.2f} V "
                                  f"a fresh one shows (full {limits.full_v:.2f} V, {limits.source})", r)
    return PackVerdict(True, f"{head}: a fresh pack (at least {limits.fresh_v:.2f} V of a full "
                             f"{limits.full_v:.2f} V, {limits.source})", r)


async def read_battery(link: Link, system: int, component: int = 1, *,
                       reply_timeout_s: float = REPLY_TIMEOUT_S) -> BatteryReading:
    """Ask ``system`` for BATTERY_STATUS and SYS_STATUS now (MAV_CMD_REQUEST_MESSAGE) and return
    what it said. A message the vehicle refuses to send or does not send within
    ``reply_timeout_s`` of the ACK is left out (PX4 sends BATTERY_STATUS, ArduPilot both); none at
    all is a CommandError naming the vehicle."""
    got: dict[str, object] = {}
    with link.subscribe(MESSAGES, source_system=system,
                        callback=lambda m: got.__setitem__(m.get_type(), m)) as _:
        for name in MESSAGES:
            if name in got:
                continue
            msg_id = getattr(mavlink, f"MAVLINK_MSG_ID_{name}")
            try:
                await command_long(link, system, component, mavlink.MAV_CMD_REQUEST_MESSAGE, (msg_id,))
            except CommandError as err:
                log.info("vehicle %d: %s", system, err)
                continue
            deadline = time.monotonic() + reply_timeout_s
            while name not in got and time.monotonic() < deadline:
                await asyncio.sleep(0.05)
    if not got:
        raise CommandError("sent neither BATTERY_STATUS nor SYS_STATUS when asked", vehicle=str(system),
                           operation="battery")
    return BatteryReading.from_messages(got.get("BATTERY_STATUS"), got.get("SYS_STATUS"))


async def pack_limits(link: Link, system: int, flavour: Flavour, component: int = 1) -> PackLimits | None:
    """The pack's full and empty voltages from the vehicle's parameters (see the module docstring),
    or None when it does not say."""
    async def num(name: str) -> float | None:
        return await read_param_number(link, system, component, name, bytewise=flavour.name == "px4")

    if flavour.name == "px4":
        cells, full, empty = await num("BAT1_N_CELLS"), await num("BAT1_V_CHARGED"), await num("BAT1_V_EMPTY")
        if cells and full and empty and cells >= 1 and full > empty > 0:
            return PackLimits(cells * full, cells * empty,
                              f"BAT1_N_CELLS {cells:g} x BAT1_V_CHARGED {full:.2f} / BAT1_V_EMPTY {empty:.2f} V")
        return None
    full, empty = await num("MOT_BAT_VOLT_MAX"), await num("MOT_BAT_VOLT_MIN")
    if full and empty and full > empty > 0:
        return PackLimits(full, empty, f"MOT_BAT_VOLT_MAX {full:.2f} V, MOT_BAT_VOLT_MIN {empty:.2f} V")
    return None


async def check_fresh_pack(link: Link, system: int, flavour: Flavour, component: int = 1, *,
                           limits: PackLimits | None = None, vehicle: str | None = None) -> PackVerdict:
    """The exchange: read the battery now and judge the pack (``limits`` from :func:`pack_limits`,
    read here when not given). Call it on the ground, disarmed: the voltage under load is lower."""
    if limits is None:
        limits = await pack_limits(link, system, flavour, component)
    reading = await read_battery(link, system, component)
    return judge_pack(reading, limits, vehicle=vehicle or f"vehicle {system}")
