"""A fake vehicle's battery (issue 38): the pack it carries, and what its autopilot says of it.

The pack drains with the energy model (``energy.RotorcraftPower`` at the flown speed, only in the
air) and its voltage falls linearly with its charge from 16.8 to 14.0 V (a 4S LiPo, as before).
The team gives it a fresh one (:meth:`Battery.swap`); on a real multirotor the pack also powers the
autopilot, so a swap is a reboot as well (``FakeFleet.swap_pack``).

What each autopilot reports, as measured on ``../shared/sitl`` (docs/guide/sitl.md, "Battery"):

* **ArduPilot** (AP_BattMonitor with ``BATT_MONITOR 4``, voltage and current) integrates the current
  since boot: remaining = 1 - consumed / capacity, whatever the pack's voltage. A pack put in
  without a reboot keeps the old figure; after a reboot it says 100 % even of a used pack (only the
  voltage tells). ``MAV_CMD_BATTERY_RESET`` (param1 the battery mask, param2 the percentage) sets
  the remaining and clears the consumed figures. BATTERY_STATUS: id 0, function 0, type 0,
  ``voltages[0]`` the pack (the rest UINT16_MAX), current [cA], consumed [mAh] and [hJ],
  time_remaining 0. Below ``BATT_LOW_VOLT`` for ``BATT_LOW_TIMER`` s on the ground it refuses to
  arm, "Arm: Battery 1 low voltage failsafe", until the voltage is back; the same in the air
  triggers the battery failsafe (charge state LOW), which stays until a reboot: "Arm: Battery
  failsafe" also after a fresh pack (SITL). It arms on a used pack otherwise (35 % measured):
  ``BATT_ARM_VOLT`` and ``BATT_ARM_MAH`` are 0 unless set ("Arm: Battery 1 below minimum arming
  voltage" / "... capacity"). ``BATT_LOW_VOLT`` is ArduCopter's default
  10.5 V, below this pack's empty 14.0 V, so it trips only where a test sets it.
  ``SIM_BATT_VOLTAGE`` is SITL's simulated pack: setting it gives the pack the charge of that
  resting voltage (full at 16.8 V here).
* **PX4** estimates the charge from the voltage, so its remaining follows the pack (SITL's filter
  takes a few seconds; not modelled). SYS_STATUS and BATTERY_STATUS current -100 cA ("-1 A",
  not measured), consumed 0 mAh and -1 hJ; BATTERY_STATUS function 1 (all), type 1 (LiPo). The
  charge state is LOW, CRITICAL, EMERGENCY below ``BAT_LOW_THR``, ``BAT_CRIT_THR``,
  ``BAT_EMERGEN_THR`` (0.15, 0.07, 0.05); at CRITICAL and below arming is refused ("Critical
  battery", "Emergency battery level"; PX4's commander, batteryCheck.cpp: SITL cannot be put on the
  ground with a low pack). ``MAV_CMD_BATTERY_RESET`` is UNSUPPORTED (measured). With
  ``refill_on_disarm`` every disarm gives a full pack, as SIH's battery simulator does.
"""

from __future__ import annotations

from dataclasses import dataclass

from uavloc_gcs.dialect import mavlink as mav

MAV_CMD_BATTERY_RESET = 42651  # ArduPilot's dialect (ardupilotmega.xml), not in common.xml
FULL_V, EMPTY_V = 16.8, 14.0  # 4S LiPo: the pack's voltage at full and at empty charge
CELLS = 4
AP_LOW_TIMER_S = 10.0  # ArduPilot's BATT_LOW_TIMER default
PX4_THRESHOLDS = {"BAT_LOW_THR": 0.15, "BAT_CRIT_THR": 0.07, "BAT_EMERGEN_THR": 0.05}  # PX4 defaults (measured)
UINT16_MAX = 65535
INT16_MAX = 32767


@dataclass
class Battery:
    """One vehicle's pack and its autopilot's monitor. Energies in J, times in simulated s."""

    flavour: str  # "ardupilot" or "px4"
    capacity_j: float  # the pack's (the vehicle's energy budget)
    used_j: float = 0.0  # taken from the pack in this pack's life
    consumed_j: float = 0.0  # ArduPilot's monitor: integrated since boot or the last reset
    consumed_mah: float = 0.0
    failsafe: bool = False  # ArduPilot's battery failsafe (triggered in the air), latched until reboot
    low: bool = False  # below BATT_LOW_VOLT for BATT_LOW_TIMER s (a pre-arm failure on the ground)
    low_since_s: float | None = None
    refill_on_disarm: bool = False  # PX4 SIH's battery simulator

    # -- the pack -----------------------------------------------------------------------------
    @property
    def charge(self) -> float:
        """The pack's state of charge, 0..1."""
        return max(0.0, 1.0 - self.used_j / self.capacity_j)

    @property
    def voltage_v(self) -> float:
        return EMPTY_V + (FULL_V - EMPTY_V) * self.charge

    def burn(self, power_w: float, dt_s: float) -> None:
        """Flight at ``power_w`` for ``dt_s``: the pack drains, ArduPilot's monitor counts it."""
        e = power_w * dt_s
        volts = self.voltage_v
        self.used_j += e
        self.consumed_j += e
        self.consumed_mah += e / volts / 3.6

    def swap(self) -> None:
        """A fresh pack (the team's hands). ArduPilot's monitor keeps counting until a reboot or
        MAV_CMD_BATTERY_RESET; PX4 reads the new voltage."""
        self.used_j = 0.0

    def set_resting_voltage(self, volts: float) -> None:
        """SITL's SIM_BATT_VOLTAGE: the pack gets the charge of this resting voltage."""
        frac = min(max((volts - EMPTY_V) / (FULL_V - EMPTY_V), 0.0), 1.0)
        self.used_j = (1.0 - frac) * self.capacity_j

    def on_boot(self) -> None:
        """The autopilot restarts: ArduPilot's monitor starts again at 100 %, its failsafe clears."""
        self.consumed_j = self.consumed_mah = 0.0
        self.failsafe, self.low, self.low_since_s = False, False, None

    def on_disarm(self) -> None:
        if self.refill_on_disarm:
            self.swap()

    def reset(self, mask: int, percent: float) -> int:
        """MAV_CMD_BATTERY_RESET: the MAV_RESULT."""
        if self.flavour != "ardupilot":
            return mav.MAV_RESULT_UNSUPPORTED
        if not (mask & 1) or not 0.0 <= percent <= 100.0:
            return mav.MAV_RESULT_FAILED
        self.consumed_j = (1.0 - percent / 100.0) * self.capacity_j
        self.consumed_mah = self.consumed_j / ((FULL_V + EMPTY_V) / 2) / 3.6
        return mav.MAV_RESULT_ACCEPTED

    # -- what the autopilot says --------------------------------------------------------------
    @property
    def remaining(self) -> float:
        """The autopilot's remaining charge, 0..1 (ArduPilot: its monitor; PX4: the pack)."""
        if self.flavour == "ardupilot":
            return max(0.0, 1.0 - self.consumed_j / self.capacity_j)
        return self.charge

    def watch(self, t_s: float, params: dict, armed: bool) -> None:
        """ArduPilot's low voltage: BATT_LOW_TIMER s below BATT_LOW_VOLT; armed, the failsafe latches."""
        threshold = float(params.get("BATT_LOW_VOLT", 0.0))
        if self.flavour != "ardupilot" or threshold <= 0.0 or self.voltage_v >= threshold:
            self.low, self.low_since_s = False, None
            return
        if self.low_since_s is None:
            self.low_since_s = t_s
        self.low = t_s - self.low_since_s >= float(params.get("BATT_LOW_TIMER", AP_LOW_TIMER_S))
        self.failsafe |= self.low and armed

    def charge_state(self, params: dict) -> int:
        """MAV_BATTERY_CHARGE_STATE."""
        if self.flavour == "ardupilot":
            return mav.MAV_BATTERY_CHARGE_STATE_LOW if self.failsafe else mav.MAV_BATTERY_CHARGE_STATE_OK
        r = self.remaining
        for name, state in (("BAT_EMERGEN_THR", mav.MAV_BATTERY_CHARGE_STATE_EMERGENCY),
                            ("BAT_CRIT_THR", mav.MAV_BATTERY_CHARGE_STATE_CRITICAL),
                            ("BAT_LOW_THR", mav.MAV_BATTERY_CHARGE_STATE_LOW)):
            if r <= float(params.get(name, PX4_THRESHOLDS[name])):
                return state
        return mav.MAV_BATTERY_CHARGE_STATE_OK

    def arm_refusal(self, params: dict) -> str | None:
        """Why the autopilot refuses to arm on this pack (its own words), or None."""
        if self.flavour == "ardupilot":
            if self.failsafe:
                return "Arm: Battery failsafe"
            if self.low:
                return "Arm: Battery 1 low voltage failsafe"
            if float(params.get("BATT_ARM_VOLT", 0.0)) > 0 and self.voltage_v < params["BATT_ARM_VOLT"]:
                return "Arm: Battery 1 below minimum arming voltage"
            cap_mah = float(params.get("BATT_CAPACITY", 0.0))
            if float(params.get("BATT_ARM_MAH", 0.0)) > 0 and cap_mah * self.remaining < params["BATT_ARM_MAH"]:
                return "Arm: Battery 1 below minimum arming capacity"
            return None
        state = self.charge_state(params)
        if state == mav.MAV_BATTERY_CHARGE_STATE_EMERGENCY:
            return "Emergency battery level"
        if state == mav.MAV_BATTERY_CHARGE_STATE_CRITICAL:
            return "Critical battery"
        return None

    def current_ca(self, power_w: float) -> int:
        if self.flavour == "px4":
            return -100  # PX4 SITL: no current sensor, sent as -100 cA (measured)
        return int(power_w / self.voltage_v * 100)

    def battery_status(self, power_w: float, params: dict):
        """BATTERY_STATUS as the autopilot sends it (see the module docstring)."""
        volts = [min(int(round(self.voltage_v * 1000)), UINT16_MAX - 1)] + [UINT16_MAX] * 9
        ext = [0, 0, 0, 0]
        remaining = int(round(100 * self.remaining))
        if self.flavour == "ardupilot":
            return mav.MAVLink_battery_status_message(
                0, mav.MAV_BATTERY_FUNCTION_UNKNOWN, mav.MAV_BATTERY_TYPE_UNKNOWN, INT16_MAX, volts,
                self.current_ca(power_w), int(round(self.consumed_mah)), int(round(self.consumed_j / 100)),
                remaining, 0, self.charge_state(params), ext, 0, 0)
        return mav.MAVLink_battery_status_message(
            0, mav.MAV_BATTERY_FUNCTION_ALL, mav.MAV_BATTERY_TYPE_LIPO, INT16_MAX, volts, -100, 0, -1,
            remaining, 0, self.charge_state(params), ext, 0, 0)


def default_battery_params(flavour: str) -> dict[str, float]:
    """The battery parameters the fake answers for (their autopilots' defaults)."""
    if flavour == "ardupilot":
        # MOT_BAT_VOLT_MAX / _MIN: the pack's full and empty voltage, as ../shared/sitl's copter.parm
        # gives them for its 3S (12.8 / 9.6 V); ArduCopter's own default is 0 (not set)
        return {"BATT_LOW_VOLT": 10.5, "BATT_LOW_TIMER": AP_LOW_TIMER_S, "BATT_ARM_VOLT": 0.0, "BATT_ARM_MAH": 0.0,
                "SIM_BATT_VOLTAGE": FULL_V, "MOT_BAT_VOLT_MAX": FULL_V, "MOT_BAT_VOLT_MIN": EMPTY_V}
    return {**PX4_THRESHOLDS, "COM_ARM_BAT_MIN": -1.0, "BAT1_N_CELLS": float(CELLS),
            "BAT1_V_CHARGED": FULL_V / CELLS, "BAT1_V_EMPTY": EMPTY_V / CELLS}  # this pack's, not PX4's 4.05 / 3.6 V

