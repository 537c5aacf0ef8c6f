"""Battery packs on the real autopilots' SITL (issue 38): how each simulates one, and a swap.

Measured on ../shared/sitl (``python -m tests.sitl.battery_measure``, docs/guide/sitl.md "Battery"):

* ArduCopter SITL simulates the pack in its physics (``SIM_BATT_VOLTAGE`` full, ``SIM_BATT_CAP_AH``
  capacity; 0, the default, is a pack that never sags) and monitors it with ``BATT_MONITOR 4``:
  the remaining is the current integrated since boot against ``BATT_CAPACITY``. A swap is two
  things here: the simulated pack starts again when ``SIM_BATT_VOLTAGE`` changes, and the monitor
  when told by MAV_CMD_BATTERY_RESET (a real swap reboots the autopilot, which does both).
* PX4 SIH's battery simulator drains by time while armed (``SIM_BAT_DRAIN`` s from full to empty,
  held at ``SIM_BAT_MIN_PCT``) and gives a full pack at every disarm: a landing is the swap.
"""

from __future__ import annotations

import asyncio

from uavloc_gcs.link import Flavour, command_long
from uavloc_gcs.link.params import read_param, set_param

MAV_CMD_BATTERY_RESET = 42651  # ArduPilot's dialect (ardupilotmega.xml)

# ArduCopter SITL with a pack that sags: 2 Ah (about 4 minutes of hover at its 28-31 A), the monitor
# told the same capacity. copter.parm's MOT_BAT_VOLT_MAX / _MIN (12.8 / 9.6 V) give the full and
# empty voltages uavloc_gcs.link.pack_limits reads.
AP_PACK_PARAMS = {"SIM_BATT_CAP_AH": 2.0, "BATT_CAPACITY": 2000}


async def sitl_swap(link, system: int, flavour: Flavour) -> None:
    """Give a landed, disarmed SITL vehicle a fresh pack the way its simulator takes one."""
    if flavour.name != "ardupilot":
        return  # PX4 SIH refilled it when it disarmed
    volts = await read_param(link, system, 1, "SIM_BATT_VOLTAGE")
    await set_param(link, system, 1, "SIM_BATT_VOLTAGE", volts - 0.01)  # a change re-starts the simulated pack
    await asyncio.sleep(0.3)
    await set_param(link, system, 1, "SIM_BATT_VOLTAGE", volts)
    await command_long(link, system, 1, MAV_CMD_BATTERY_RESET, (1, 100))  # ... and the monitor's count
