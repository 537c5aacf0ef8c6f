"""What the daemon is told besides the scenario: where it keeps its store and logs, how it starts
the vehicles, its timeouts, signing, and what the vehicles do when it stops."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class DaemonOptions:
    store_path: Path
    start: str = "auto"  # "auto" or "operator"
    signing_key: bytes | None = None
    tlog_dir: Path | None = None
    lost_timeout_s: float = 5.0  # wall seconds of silence before a vehicle is lost
    connect_timeout_s: float = 15.0
    planner_time_limit_s: float | None = None  # None: the scenario's, capped to ~2 s of mission time
    tick_s: float = 0.05
    source_system: int = 245  # not QGroundControl's 255 (operators keep QGC open beside us)
    max_mission_s: float = 4 * 3600.0
    resume: bool = True
    rssi_connections: tuple = ()  # [(vehicle, connection)]: RSSI beside the autopilot ([link] rssi_connections)
    set_speed_params: bool = False  # the operator's consent to set the vehicles' speed parameters
    on_stop: str = "rtl"  # when the daemon is stopped (Ctrl-C, SIGTERM): "rtl" sends the airborne home
    scan_hold_s: float = 120.0  # mission seconds a finished scan holds before its RTL (the next mission
    # is normally uploaded well before; without a daemon the vehicle then comes home by itself)
