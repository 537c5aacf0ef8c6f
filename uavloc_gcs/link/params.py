"""Parameters: PARAM_REQUEST_READ / PARAM_SET -> PARAM_VALUE (devguide ``services/parameter.md``),
and the one thing uavloc reads them for: the horizontal speeds a vehicle will really fly.

A mission's DO_CHANGE_SPEED does not decide the speed alone. Measured on SITL (see
``../shared/sitl/README.md``): ArduCopter flies at most ``WPNAV_SPEED`` (cm/s, 10 m/s stock)
whatever the mission asks, and RTL at ``RTL_SPEED`` (cm/s, 0 = WPNAV_SPEED); PX4 caps any mission
speed at ``MPC_XY_VEL_MAX`` (12 m/s stock), flies ``MPC_XY_CRUISE`` (5 m/s stock) where no speed
is given, and returns (RTL) at ``MPC_XY_CRUISE``. :func:`speed_limits` reads them;
:func:`raise_speed_limits` sets them to the scenario's speed (only with the operator's consent,
``[link] set_speed_params = true``).
"""

from __future__ import annotations

import logging
import math
import struct
from dataclasses import dataclass

from ..dialect import mavlink
from ..errors import LinkError
from .autopilots import Flavour
from .connection import Link

log = logging.getLogger(__name__)

PARAM_TIMEOUT_S = 1.0  # per try; QGC and MAVSDK use about the same
PARAM_RETRIES = 3
REAL32 = mavlink.MAV_PARAM_TYPE_REAL32


async def read_param(link: Link, target_system: int, target_component: int, name: str, *,
                     timeout_s: float = PARAM_TIMEOUT_S, retries: int = PARAM_RETRIES) -> float | None:
    """The value of parameter ``name``, or None if the vehicle does not answer (an unknown name:
    autopilots stay silent)."""
    return await _exchange(link, target_system, target_component, name, None, timeout_s, retries)


_INT_FORMATS = {mavlink.MAV_PARAM_TYPE_UINT8: "<B", mavlink.MAV_PARAM_TYPE_INT8: "<b", mavlink.MAV_PARAM_TYPE_UINT16: "<H",
                mavlink.MAV_PARAM_TYPE_INT16: "<h", mavlink.MAV_PARAM_TYPE_UINT32: "<I", mavlink.MAV_PARAM_TYPE_INT32: "<i"}


async def read_param_number(link: Link, target_system: int, target_component: int, name: str, *, bytewise: bool,
                            timeout_s: float = PARAM_TIMEOUT_S, retries: int = PARAM_RETRIES) -> float | None:
    """The value of parameter ``name`` as a number whatever its type, or None without an answer.
    ``bytewise``: the vehicle packs integer parameters into PARAM_VALUE's float bit for bit (PX4;
    measured: its BAT1_N_CELLS 4 arrives as 5.6e-45), not by value (ArduPilot)."""
    msg = await _exchange(link, target_system, target_component, name, None, timeout_s, retries, whole=True)
    if msg is None:
        return None
    fmt = _INT_FORMATS.get(int(msg.param_type))
    if bytewise and fmt is not None:
        raw = struct.pack("<f", float(msg.param_value))
        return float(struct.unpack(fmt, raw[:struct.calcsize(fmt)])[0])
    return float(msg.param_value)


async def set_param(link: Link, target_system: int, target_component: int, name: str, value: float, *,
                    timeout_s: float = PARAM_TIMEOUT_S, retries: int = PARAM_RETRIES) -> float:
    """Set ``name`` and return the value the vehicle reports back (it may clamp it). LinkError if
    it never answers."""
    got = await _exchange(link, target_system, target_component, name, float(value), timeout_s, retries)
    if got is None:
        raise LinkError(f"vehicle {target_system} did not confirm PARAM_SET {name} = {value:g} "
                        f"({retries} tries)", vehicle=str(target_system), operation="param")
    return got


async def _exchange(link: Link, sysid: int, compid: int, name: str, value: float | None,
                    timeout_s: float, retries: int, *, whole: bool = False):
    def is_ours(m) -> bool:
        pid = m.param_id if isinstance(m.param_id, str) else m.param_id.decode(errors="replace")
        return pid.rstrip("\x00") == name

    raw = name.encode()
    with link.subscribe("PARAM_VALUE", source_system=sysid, predicate=is_ours) as sub:
        for _ in range(max(1, retries)):
            if value is None:
                await link.send(link.mav.param_request_read_encode(sysid, compid, raw, -1))
            else:
                await link.send(link.mav.param_set_encode(sysid, compid, raw, value, REAL32))
            try:
                msg = await sub.get(timeout_s)
            except (TimeoutError, LinkError):
                continue
            return msg if whole else float(msg.param_value)
    return None


@dataclass(frozen=True)
class SpeedLimits:
    """Horizontal speeds [m/s] a vehicle will fly: at most ``max_m_s`` on a mission (whatever
    DO_CHANGE_SPEED asks), ``rtl_m_s`` when returning; None where the vehicle did not say."""

    max_m_s: float | None
    rtl_m_s: float | None
    source: str  # the parameters and their values, for the operator

    def mission_speed(self, wanted_m_s: float) -> float:
        return wanted_m_s if self.max_m_s is None else min(wanted_m_s, self.max_m_s)

    def return_speed(self, wanted_m_s: float) -> float:
        return self.mission_speed(wanted_m_s) if self.rtl_m_s is None else self.rtl_m_s


def _positive(x: float | None, scale: float) -> float | None:
    return x * scale if x is not None and math.isfinite(x) and x > 0 else None


async def _first(link: Link, sysid: int, compid: int, names: tuple[tuple[str, float], ...]):
    """(name, value in m/s) of the first of ``names`` (name, scale to m/s) the vehicle has."""
    for name, scale in names:
        value = await read_param(link, sysid, compid, name)
        if value is not None:
            return name, value, value * scale
    return None, None, None


# ArduCopter renamed its speed parameters (2025-26 master, as in ../shared/sitl: WP_SPD and
# RTL_SPEED_MS in m/s); older versions have WPNAV_SPEED and RTL_SPEED in cm/s. Newest first.
AP_WP_SPEED = (("WP_SPD", 1.0), ("WPNAV_SPEED", 0.01))
AP_RTL_SPEED = (("RTL_SPEED_MS", 1.0), ("RTL_SPEED", 0.01))


async def speed_limits(link: Link, sysid: int, flavour: Flavour, compid: int = 1) -> SpeedLimits:
    """Read the speed parameters of ``flavour`` (see the module docstring)."""
    if flavour.name == "ardupilot":
        wp_name, wp, wp_m_s = await _first(link, sysid, compid, AP_WP_SPEED)
        rtl_name, rtl, rtl_m_s = await _first(link, sysid, compid, AP_RTL_SPEED)
        mx = _positive(wp_m_s, 1.0)
        ret = _positive(rtl_m_s, 1.0) or mx  # 0 means "at the waypoint speed"
        return SpeedLimits(mx, ret, f"{wp_name or 'WP_SPD/WPNAV_SPEED'}={wp}, {rtl_name or 'RTL_SPEED(_MS)'}={rtl}")
    vmax = await read_param(link, sysid, compid, "MPC_XY_VEL_MAX")
    cruise = await read_param(link, sysid, compid, "MPC_XY_CRUISE")
    mx = _positive(vmax, 1.0)
    return SpeedLimits(mx, _positive(cruise, 1.0), f"MPC_XY_VEL_MAX={vmax} m/s, MPC_XY_CRUISE={cruise} m/s")


async def raise_speed_limits(link: Link, sysid: int, flavour: Flavour, speed_m_s: float,
                             compid: int = 1) -> SpeedLimits:
    """Set the vehicle's mission and return speeds to ``speed_m_s`` (the operator's consent is the
    caller's business) and return the limits read back."""
    if flavour.name == "ardupilot":
        for names in (AP_WP_SPEED, AP_RTL_SPEED):
            name, _, _ = await _first(link, sysid, compid, names)
            if name is not None:
                scale = dict(names)[name]
                await set_param(link, sysid, compid, name, speed_m_s / scale)
    else:
        vmax = await read_param(link, sysid, compid, "MPC_XY_VEL_MAX")
        if vmax is None or vmax < speed_m_s:
            await set_param(link, sysid, compid, "MPC_XY_VEL_MAX", speed_m_s)
        await set_param(link, sysid, compid, "MPC_XY_CRUISE", speed_m_s)
    return await speed_limits(link, sysid, flavour, compid)
