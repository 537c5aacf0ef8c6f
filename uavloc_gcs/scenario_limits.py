"""Plausible ranges of a scenario file's values: what no field, fleet or radio can have.

``scenario_checks.resolve`` refuses what is impossible (a negative speed, a range below the altitude);
this refuses what is possible to write but absurd -- ``comm_range_m = 1e9``, ``energy_budget_j =
1e308`` (issue 40) -- which used to pass and print a 300-digit kJ figure. Each limit says why, with
its source, and the error names the key and the plausible range. Applied to values read from a
file (:func:`check_plausible`), not to scenarios built in code (a POD layout uses a notional
unlimited budget); a command's flags have their own ranges (``cli/_inputs.number``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from .errors import ConfigError

# A phone's Wi-Fi is discovered up to about 300 m away in line of sight at 2.4 GHz, 150 m without
# (Wi2SAR, "Take Me Home, Wi-Fi Drone", arXiv 2604.09115, MobiCom '26; SPEC 1.1).
PHONE_DISCOVERY_LOS_M = 300.0
# Measured path-loss exponents: 1.6-1.8 in a building in line of sight to 4-6 obstructed in a
# building; 2 in free space, 2.7-3.5 for urban cellular radio (T. S. Rappaport, Wireless
# Communications: Principles and Practice, 2nd ed., 2002, Table 4.2).
PATH_LOSS_EXPONENT_MEASURED = (1.6, 6.0)
# UAVLOC_RSSI_BATCH(2) carry the slot length as uint16 microseconds and the frames of a slot as
# uint8 (uavloc_gcs/dialect/uavloc.xml, RSSI_DIALECT.md): longer slots or more frames do not fit.
SLOT_US_MAX = 65535
FRAMES_PER_SLOT_MAX = 255


@dataclass(frozen=True)
class Limit:
    """``low <= value <= high`` (either may be None), with the reason shown when refused."""

    key: str  # dotted, as in the file
    low: float | None
    high: float | None
    unit: str
    why: str | Callable[[object, float], str]


def _hover_hours(sc, value: float) -> str:
    power_w = sc.power_model.hover_power_w()
    return (f"{value:g} J would keep a vehicle of the power model hovering ({power_w:.0f} W) for "
            f"{value / power_w / 3600:.3g} h; 20 MJ (5.6 kWh) is already {20e6 / power_w / 3600:.0f} h, more than "
            "any multirotor flies on one charge")


LIMITS: tuple[Limit, ...] = (
    Limit("fleet.altitude_m", 5.0, 1000.0, "m",
          "lower than 5 m a multirotor flies into people and obstacles; from 1000 m up no phone is heard "
          f"(Wi2SAR discovered phones up to about {PHONE_DISCOVERY_LOS_M:g} m away in line of sight)"),
    Limit("fleet.comm_range_m", None, 5000.0, "m",
          f"over 16 times the {PHONE_DISCOVERY_LOS_M:g} m at which Wi2SAR discovered phones in line of sight "
          "(arXiv 2604.09115; SPEC 1.1)"),
    Limit("fleet.energy_budget_j", None, 20e6, "J", _hover_hours),
    Limit("fleet.max_acceleration_m_s2", None, 50.0, "m/s²", "5 g, beyond a multirotor carrying a receiver"),
    Limit("channel.path_loss_exponent", 1.0, 8.0, "",
          f"measured exponents lie between {PATH_LOSS_EXPONENT_MEASURED[0]:g} and {PATH_LOSS_EXPONENT_MEASURED[1]:g} "
          "(Rappaport, Wireless Communications, 2nd ed., Table 4.2)"),
    Limit("channel.shadowing_sigma_db", None, 20.0, "dB",
          "with 20 dB of shadowing one sample's range is uncertain by a factor of 90 either way (95 %, path-loss "
          "exponent 2)"),
    Limit("channel.reference_distance_m", None, 100.0, "m", "the reference power is measured close to the phone (1 m)"),
    Limit("channel.slot_s", None, SLOT_US_MAX / 1e6, "s",
          "the RSSI message carries the slot length as a 16-bit count of microseconds"),
    Limit("channel.samples_per_slot", None, FRAMES_PER_SLOT_MAX, "",
          "the RSSI message carries a slot's frame count in one byte"),
    Limit("planner.particles", None, 10_000, "", "the swarm is scored at every iteration (the paper uses 40)"),
    Limit("planner.iterations", None, 1_000_000, "", "the planner stops at planner.time_limit_s anyway"),
    Limit("planner.time_limit_s", None, 600.0, "s", "a replan in flight must not keep vehicles waiting (as "
          "daemon --planner-time-limit)"),
    Limit("simulation.people", None, 1000, "", "beyond this the simulated world does not start in time (as demo --people)"),
    Limit("simulation.seed", 0, 2**32 - 1, "", "a seed is an unsigned 32-bit number (as demo --seed)"),
    Limit("simulation.speedup", None, 1000.0, "", "as demo --speedup"),
    Limit("link.lost_timeout_s", None, 3600.0, "s", "a vehicle silent for an hour is lost whatever this says"),
)


def _get(sc, key: str):
    section, name = key.split(".")
    return getattr(getattr(sc, section), name)


def _fmt(x: float) -> str:
    return f"{x:,.0f}" if float(x).is_integer() and abs(x) >= 10_000 else f"{x:g}"


def check_plausible(sc) -> None:
    """Refuse the first value of ``sc`` outside its plausible range: ConfigError naming the file,
    the key and the range, with the reason."""
    for lim in LIMITS:
        value = _get(sc, lim.key)
        if value is None:
            continue
        if (lim.low is None or value >= lim.low) and (lim.high is None or value <= lim.high):
            continue
        u = f" {lim.unit}" if lim.unit else ""
        if lim.low is not None and lim.high is not None:
            span = f"{_fmt(lim.low)}-{_fmt(lim.high)}{u}"
        elif lim.high is not None:
            span = f"at most {_fmt(lim.high)}{u}"
        else:
            span = f"at least {_fmt(lim.low)}{u}"
        why = lim.why(sc, value) if callable(lim.why) else lim.why
        raise ConfigError(f"{value:g}{u} is not plausible (give {span}): {why}", source=sc.source, key=lim.key)
