"""A few autopilot parameters, so ground stations that read parameters on connect (QGroundControl,
Mission Planner) are satisfied: PARAM_REQUEST_LIST, PARAM_REQUEST_READ and PARAM_SET, each
answered with PARAM_VALUE. The values mirror what the fake vehicle actually does; setting one that
it uses (speed, acceleration, RTL altitude, acceptance radius, take-off altitude) changes its flight.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from uavloc_gcs.dialect import mavlink as mav

from .battery import default_battery_params
from .mission_server import Peer, Reply

if TYPE_CHECKING:  # pragma: no cover
    from .vehicle import FakeVehicle

REAL32 = mav.MAV_PARAM_TYPE_REAL32


def default_params(v: "FakeVehicle") -> dict[str, float]:
    c = v.cfg
    if v.flavour.name == "ardupilot":
        return {  # ArduCopter units: cm, cm/s, cm/s^2
            "SYSID_THISMAV": float(v.sysid), "WPNAV_SPEED": c.cruise_speed_m_s * 100,
            "WPNAV_ACCEL": c.max_accel_m_s2 * 100, "WPNAV_RADIUS": c.acceptance_radius_m * 100,
            "WPNAV_SPEED_UP": c.climb_rate_m_s * 100, "WPNAV_SPEED_DN": c.descent_rate_m_s * 100,
            "RTL_ALT": c.rtl_alt_m * 100, "BATT_CAPACITY": c.energy_budget_j / 3.6 / 16.8,
            "RTL_SPEED": 0.0,  # 0: RTL at WPNAV_SPEED, as ArduCopter
            # the same two under the names of the 2025-26 ArduCopter master (../shared/sitl), in m/s
            "WP_SPD": c.cruise_speed_m_s, "RTL_SPEED_MS": 0.0,
            "FS_GCS_ENABLE": 1.0, "FS_GCS_TIMEOUT": 5.0,  # a fleet set up for the field: RTL on link loss
            **default_battery_params("ardupilot"),
        }
    return {  # PX4 units: m, m/s, m/s^2
        "MAV_SYS_ID": float(v.sysid), "MPC_XY_CRUISE": c.cruise_speed_m_s, "MPC_ACC_HOR": c.max_accel_m_s2,
        "MPC_XY_VEL_MAX": max(12.0, c.cruise_speed_m_s),  # PX4's default cap, raised to the fleet's speed
        "NAV_ACC_RAD": c.acceptance_radius_m, "MPC_Z_V_AUTO_UP": c.climb_rate_m_s,
        "MPC_Z_V_AUTO_DN": c.descent_rate_m_s, "RTL_RETURN_ALT": c.rtl_alt_m,
        "MIS_TAKEOFF_ALT": v.flavour.takeoff_alt_default_m,
        "NAV_DLL_ACT": 2.0, "COM_DL_LOSS_T": 10.0,  # a fleet set up for the field: return on link loss
        **default_battery_params("px4"),
    }


def _value(name: str, value: float, index: int, count: int) -> Reply:
    return Reply(mav.MAVLink_param_value_message(name.encode(), float(value), REAL32, count, index))


def handle_param(v: "FakeVehicle", msg, peer: Peer) -> list[Reply]:
    params = v.params
    names = list(params)
    kind = msg.get_type()
    if kind == "PARAM_REQUEST_LIST":
        return [_value(n, params[n], i, len(names)) for i, n in enumerate(names)]
    name = msg.param_id if isinstance(msg.param_id, str) else msg.param_id.decode(errors="replace")
    name = name.rstrip("\x00")
    if kind == "PARAM_REQUEST_READ":
        if 0 <= msg.param_index < len(names):
            name = names[msg.param_index]
        if name not in params:
            return []
    elif kind == "PARAM_SET":
        if name not in params:
            return []  # autopilots stay silent; the GCS times out
        params[name] = float(msg.param_value)
        _apply(v, name, float(msg.param_value))
    else:
        return []
    return [_value(name, params[name], names.index(name), len(names))]


def _apply(v: "FakeVehicle", name: str, value: float) -> None:
    """Parameters that change the flight (ArduPilot values are in cm)."""
    k = 0.01 if v.flavour.name == "ardupilot" else 1.0
    if name in ("WPNAV_SPEED", "MPC_XY_CRUISE") and value > 0:
        v.speed_m_s = value * k
        if name == "WPNAV_SPEED":
            v.params["WP_SPD"] = v.speed_m_s
    elif name == "SIM_BATT_VOLTAGE" and v.flavour.name == "ardupilot":
        v.battery.set_resting_voltage(value)  # ArduPilot SITL: the simulated pack starts again at this voltage
    elif name == "WP_SPD" and value > 0:
        v.speed_m_s = value
        v.params["WPNAV_SPEED"] = value * 100
    elif name in ("WPNAV_ACCEL", "MPC_ACC_HOR") and value > 0:
        v.kin.max_accel_m_s2 = value * k
