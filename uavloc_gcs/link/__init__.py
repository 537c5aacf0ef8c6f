"""The MAVLink link layer: transports, a :class:`Link` per connection, one module per protocol
exchange (mission upload / download / clear, commands), telemetry tracking, ``.tlog`` files.

pymavlink is used only as a codec (``uavloc_gcs.dialect.mavlink``); sockets, timing and retries
live here. Everything is asyncio: each exchange is one ``async`` function with its timeouts as
named constants next to the MAVLink devguide's values.
"""

from .autopilots import ARDUPILOT, PX4, Flavour, flavour_for, flavour_named
from .battery import BatteryReading, PackLimits, PackVerdict, check_fresh_pack, judge_pack, pack_limits, read_battery
from .command import (arm, command_long, disarm, return_to_launch, set_current_item, set_message_interval,
                      set_mode, start_mission, takeoff)
from .connection import Link, LinkStats, Subscription, open_link, parse_signing_key
from .telemetry import StatusText, VehicleState, VehicleTracker
from .mission_clear import clear_mission
from .mission_download import download_mission, home_position, qgc_form
from .mission_upload import UploadResult, upload_mission
from .mission_control import (DEFAULT_STREAMS, StartRefused, StatusWatch, arm_when_ready, request_streams, return_home,
                              set_current, start_mission_from, switch_mission, wait_until_positioned)
from .tlog import TlogWriter, iter_tlog
from .transport import parse_connection

__all__ = [
    "ARDUPILOT", "PX4", "Flavour", "flavour_for", "flavour_named",
    "BatteryReading", "PackLimits", "PackVerdict", "check_fresh_pack", "judge_pack", "pack_limits", "read_battery",
    "arm", "command_long", "disarm", "return_to_launch", "set_current_item", "set_message_interval", "set_mode",
    "start_mission", "takeoff",
    "Link", "LinkStats", "Subscription", "open_link", "parse_signing_key",
    "clear_mission", "download_mission", "home_position", "qgc_form", "UploadResult", "upload_mission",
    "TlogWriter", "iter_tlog", "parse_connection",
    "StatusText", "VehicleState", "VehicleTracker",
    "DEFAULT_STREAMS", "StartRefused", "StatusWatch", "arm_when_ready", "request_streams", "return_home", "set_current",
    "start_mission_from", "switch_mission", "wait_until_positioned",
]
