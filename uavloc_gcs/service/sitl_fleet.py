"""A fleet of SITL vehicles for ``uavloc sitl`` and the tests: started side by side, each with its
ground link and companion, and the mission file that names them (the scenario with ``[fleet]`` and
``[link]`` set). Starting and stopping one autopilot is :mod:`.sitl`'s.
"""

from __future__ import annotations

import contextlib
import socket
from dataclasses import dataclass
from pathlib import Path

from ..errors import ConfigError
from .sitl import (
    AP_INSTANCES,
    DEFAULT_SPEEDUP,
    PX4_INSTANCES,
    READY_TIMEOUT_S,
    SitlProcess,
    _check_port,
    free_udp_port,
    start_arducopter,
    start_px4,
    wait_ardupilot,
    wait_log,
)


@dataclass
class SitlVehicle:
    """One vehicle of a fleet as the daemon and its companion see it."""

    sitl: SitlProcess
    rssi_url: str | None = None  # where the companion sends RSSI beside the autopilot (its udpout)
    daemon_rssi: str = ""  # what the daemon listens on for that RSSI ("" = through the autopilot)

    @property
    def sysid(self) -> int:
        return self.sitl.sysid

    @property
    def connection(self) -> str:
        return self.sitl.connection

    @property
    def companion_url(self) -> str:
        return self.sitl.companion_url


def start_vehicle(kind: str, build: Path, *, sysid: int, home, speedup: float = DEFAULT_SPEEDUP,
                  gcs_port: int | None = None, wait: str | None = None, timeout_s: float = READY_TIMEOUT_S,
                  instances=None) -> SitlVehicle:
    """An autopilot wired for a companion: ArduCopter's companion on serial1, its RSSI forwarded
    through the autopilot; PX4's on its onboard link, its RSSI sent beside the autopilot (PX4 drops
    message ids it does not know), to a port the daemon listens on (``[link] rssi_connections``)."""
    if kind == "ardupilot":
        proc = start_arducopter(build, home=home, sysid=sysid, speedup=speedup, gcs_port=gcs_port,
                                wait=wait or "gps", timeout_s=timeout_s, companion=True,
                                instances=instances or AP_INSTANCES)
        return SitlVehicle(proc)
    proc = start_px4(build, home=home, sysid=sysid, speedup=speedup, gcs_port=gcs_port, wait=wait or "ready",
                     timeout_s=timeout_s, companion=True, instances=instances or PX4_INSTANCES)
    rport = free_udp_port()
    return SitlVehicle(proc, f"udpout:127.0.0.1:{rport}", f"udpin:127.0.0.1:{rport}")


def link_block(vehicles: list[SitlVehicle], lost_timeout_s: float = 10.0) -> str:
    """The ``[link]`` table of a mission for ``uavloc daemon``: vehicle i (system id i) first."""
    q = lambda xs: "[" + ", ".join(f'"{x}"' for x in xs) + "]"  # noqa: E731
    lines = ["[link]", f"connections = {q(v.connection for v in vehicles)}"]
    if any(v.daemon_rssi for v in vehicles):
        lines.append(f"rssi_connections = {q(v.daemon_rssi for v in vehicles)}")
    lines.append(f"lost_timeout_s = {lost_timeout_s:g}")
    return "\n".join(lines) + "\n"


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def dump_toml(raw: dict) -> str:
    """TOML text of a scenario's table tree (scalars, arrays and nested tables; arrays of tables
    are written inline)."""
    out: list[str] = []

    def table(prefix: str, d: dict) -> None:
        scalars = [(k, v) for k, v in d.items() if not isinstance(v, dict)]
        if prefix and (scalars or not d):
            out.append(f"\n[{prefix}]")
        out.extend(f"{k} = {_toml_value(v)}" for k, v in scalars)
        for k, v in d.items():
            if isinstance(v, dict):
                table(f"{prefix}.{k}" if prefix else k, v)

    table("", raw)
    return "\n".join(out).lstrip("\n") + "\n"


def _absolute_paths(raw: dict, base_dir: Path) -> dict:
    """The table tree with every relative path that names an existing file under ``base_dir``
    made absolute, so the mission file may live anywhere."""
    def fix(v):
        if isinstance(v, dict):
            return {k: fix(x) for k, x in v.items()}
        if isinstance(v, str) and v and not Path(v).is_absolute() and "\n" not in v and len(v) < 4096:
            with contextlib.suppress(OSError):
                if (base_dir / v).is_file():
                    return str((base_dir / v).resolve())
        return v
    return fix(raw)


def mission_text(scenario_text: str, vehicles: list[SitlVehicle], *, autopilot: str, source: str,
                 base_dir: Path | None = None, lost_timeout_s: float = 10.0) -> str:
    """The scenario with ``[fleet] vehicles/autopilot`` and ``[link]`` set for these vehicles:
    what ``uavloc daemon --config`` reads."""
    import tomllib

    raw = tomllib.loads(scenario_text)
    if base_dir is not None:
        raw = _absolute_paths(raw, base_dir)
    raw.setdefault("fleet", {}).update(vehicles=len(vehicles), autopilot=autopilot)
    link = {k: v for k, v in raw.get("link", {}).items() if k not in ("connections", "rssi_connections")}
    link["connections"] = [v.connection for v in vehicles]
    if any(v.daemon_rssi for v in vehicles):
        link["rssi_connections"] = [v.daemon_rssi for v in vehicles]
    link.setdefault("lost_timeout_s", lost_timeout_s)
    raw["link"] = link
    names = ", ".join(f"{v.sysid}: {v.sitl.kind} instance {v.sitl.instance}" for v in vehicles)
    head = (f"# Written by uavloc sitl from {source} for its {len(vehicles)} SITL vehicle(s) "
            f"(system id: autopilot instance -- {names}).\n# Run: uavloc daemon --config THIS_FILE\n")
    return head + dump_toml(raw)


def launch_fleet(kind: str, build: Path, n: int, *, home, speedup: float = DEFAULT_SPEEDUP,
                 base_port: int | None = None, timeout_s: float = READY_TIMEOUT_S, instances=None,
                 on_ready=None) -> list[SitlVehicle]:
    """Start ``n`` autopilots wired for companions, system ids 1..n, ground links on ``base_port``
    + 0..n-1 (default: free ports), and wait until all are ready (in parallel). On any failure
    every one started is stopped and the first error raised.

    Processes are started from the calling thread (``PR_SET_PDEATHSIG`` follows the thread that
    forks); only the waiting runs in worker threads. ``on_ready(vehicle)`` is called as each
    becomes ready.
    """
    from concurrent.futures import ThreadPoolExecutor

    if base_port is not None:
        for p in range(base_port, base_port + n):
            _check_port(p, "--base-port")
    vehicles: list[SitlVehicle] = []
    socks: list[socket.socket] = []
    waiters = []
    pool = ThreadPoolExecutor(max_workers=n)
    try:
        for i in range(n):
            port = base_port + i if base_port is not None else free_udp_port()
            if kind == "ardupilot":
                sock = _bind(port)
                socks.append(sock)
                v = start_vehicle(kind, build, sysid=i + 1, home=home, speedup=speedup, gcs_port=port, wait="none",
                                  instances=instances)
                waiters.append((v, lambda v=v, sock=sock: wait_ardupilot(v.sitl, sock, "gps", timeout_s)))
            else:
                v = start_vehicle(kind, build, sysid=i + 1, home=home, speedup=speedup, gcs_port=port, wait="none",
                                  instances=instances)
                waiters.append((v, lambda v=v: wait_log(v.sitl, "Ready for takeoff", timeout_s)))
            vehicles.append(v)

        def wait(item):
            v, fn = item
            fn()
            if on_ready is not None:
                on_ready(v)

        futures = [pool.submit(wait, w) for w in waiters]
        errors = [f.exception() for f in futures]
        first = next((e for e in errors if e is not None), None)
        if first is not None:
            raise first
        return vehicles
    except BaseException:
        for v in vehicles:  # the waiters then end at once (their process is gone)
            v.sitl.stop()
        raise
    finally:
        pool.shutdown(wait=True)
        for s in socks:
            s.close()


def _bind(port: int) -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.bind(("127.0.0.1", port))
    except OSError:
        sock.close()
        raise ConfigError(f"UDP port {port} on 127.0.0.1 is busy; choose another", key="--base-port") from None
    sock.settimeout(0.5)
    return sock
