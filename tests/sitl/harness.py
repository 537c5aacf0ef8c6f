"""Real autopilots for the tests: ArduCopter SITL and PX4 SIH, started and stopped by pid.

>>> with start_arducopter(home=HOME) as ap:          # or start_px4(home=HOME)
...     run(fly(ap.connection, ap.sysid))             # the uavloc side connects to ap.connection

The processes, instance numbers, ports and readiness are uavloc's own (``uavloc_gcs/service/sitl.py``,
what ``uavloc sitl`` runs); this module adds where the tests find the builds, their speed-ups and
instance ranges, and the sentence a test skips with.

Where the builds are: ``$UAVLOC_ARDUCOPTER`` (the ``arducopter`` binary; ``copter.parm`` beside it)
and ``$UAVLOC_PX4_DIR`` (the folder holding ``run-px4-sih.sh``), else ``$UAVLOC_SITL_DIR/ardupilot``
and ``$UAVLOC_SITL_DIR/px4``, else ``../shared/sitl`` beside the project root (where CI puts it).
Missing builds make :func:`skip_reason` return the one sentence a test skips with.

Every instance gets its own temporary directory (eeprom, logs, the process's stdout/stderr) and an
instance number taken from a lock file in the system temp dir (``fcntl.flock``, held while the
process lives and released by the kernel if the test process dies), so concurrent pytest runs never
share ports. Processes are started in their own session and stopped by process group id: TERM,
then KILL after a grace period, from :meth:`SitlProcess.stop`, a context manager exit, and atexit.

Ports on 127.0.0.1:
* ArduCopter ``-I N`` sends serial0 to the ground station (``udpclient``) on an ephemeral port
  chosen here; the uavloc side listens there (``connection`` = ``udpin:127.0.0.1:PORT``).
* PX4 instance i binds 18570+i for its ground-station link and sends to an ephemeral port chosen
  here (``-o`` in its px4-rc.mavlink); the uavloc side listens there, as for ArduCopter.
"""

from __future__ import annotations

import os
from pathlib import Path

from uavloc_gcs.service import sitl as _sitl
from uavloc_gcs.service.sitl import (LOCK_DIR, READY_TIMEOUT_S, STOP_GRACE_S, InstanceLock,  # noqa: F401
                                     SitlError, SitlProcess, free_udp_port)

ROOT = Path(__file__).resolve().parents[2]
DEFAULT_SITL_DIR = ROOT.parent / "shared" / "sitl"

# Simulated time runs this many times faster than wall time. Measured on the 2-core CI box with
# other work running (docs/guide/sitl.md): ArduCopter keeps up at 5-10x, PX4 lockstep at ~5x.
ARDUPILOT_SPEEDUP = int(os.environ.get("UAVLOC_SITL_AP_SPEEDUP", "5"))
PX4_SPEEDUP = int(os.environ.get("UAVLOC_SITL_PX4_SPEEDUP", "5"))

AP_INSTANCES = range(0, 40)  # 40-49 are kept for SITLs run by hand
PX4_INSTANCES = range(0, 8)  # 8-9 are kept for SITLs run by hand; >9 share ports in PX4's scripts

HOME = (42.625, 13.283, 900.0, 0.0)  # lat, lon, alt AMSL m, heading deg: the project's scenario area

ENABLE_HINT = ("real-autopilot SITL builds not found: put them at ../shared/sitl beside the checkout "
               "or set UAVLOC_SITL_DIR (or UAVLOC_ARDUCOPTER / UAVLOC_PX4_DIR) to enable these tests")


# -- where the builds are -------------------------------------------------------------------------

def arducopter_binary() -> Path | None:
    env = os.environ.get("UAVLOC_ARDUCOPTER")
    if env:
        return Path(env).resolve() if Path(env).is_file() else None
    base = Path(os.environ.get("UAVLOC_SITL_DIR", DEFAULT_SITL_DIR))
    path = base / "ardupilot" / "arducopter"
    return path.resolve() if path.is_file() else None


def px4_dir() -> Path | None:
    env = os.environ.get("UAVLOC_PX4_DIR")
    base = Path(env) if env else Path(os.environ.get("UAVLOC_SITL_DIR", DEFAULT_SITL_DIR)) / "px4"
    return base.resolve() if (base / "run-px4-sih.sh").is_file() else None


def skip_reason(kind: str) -> str | None:
    """None when the ``kind`` ("ardupilot" / "px4") build is present, else the skip sentence."""
    found = arducopter_binary() if kind == "ardupilot" else px4_dir()
    return None if found is not None else ENABLE_HINT


def build(kind: str) -> Path:
    """The ArduCopter binary or the PX4 folder; SitlError with the enabling sentence if absent."""
    found = arducopter_binary() if kind == "ardupilot" else px4_dir()
    if found is None:
        raise SitlError(ENABLE_HINT)
    return found


# -- processes ------------------------------------------------------------------------------------

def start_arducopter(*, home=HOME, sysid: int = 1, speedup: float = ARDUPILOT_SPEEDUP,
                     gcs_port: int | None = None, serial1: str = "none:0", params: dict[str, float] | None = None,
                     wait: str = "gps", timeout_s: float = READY_TIMEOUT_S, companion: bool = False) -> SitlProcess:
    """Start ArduCopter (``--model +``, copter.parm, a wiped eeprom) and wait for ``wait``:
    "gps" (STATUSTEXT "... is using GPS": the EKF can arm soon), "heartbeat", or "none".

    ``gcs_port``: the UDP port the ground station listens on (default: a fresh ephemeral one;
    give the same port to several vehicles for one shared link). ``params``: extra parameters
    written to a defaults file after copter.parm. ``companion``: serial1 wired for a companion
    (``.companion_url``), as ``uavloc sitl`` does.
    """
    return _sitl.start_arducopter(build("ardupilot"), home=home, sysid=sysid, speedup=speedup, gcs_port=gcs_port,
                                  serial1=serial1, params=params, wait=wait, timeout_s=timeout_s,
                                  instances=AP_INSTANCES, companion=companion)


def start_px4(*, home=HOME, speedup: float = PX4_SPEEDUP, gcs_port: int | None = None,
              env: dict[str, str] | None = None, wait: str = "ready", timeout_s: float = READY_TIMEOUT_S,
              sysid: int | None = None, companion: bool = False) -> SitlProcess:
    """Start PX4 SIH (quadrotor, as run-px4-sih.sh does) and wait for ``wait``: "ready" (console
    "Ready for takeoff") or "none". Its system id is ``sysid`` (default PX4's own: 1 + instance).
    Its ground-station link sends to ``gcs_port`` (default: a fresh ephemeral one) where uavloc
    listens, like QGC on 14550; with ``companion`` its onboard link sends to a fresh port
    (``.companion_url``), else to PX4's 14540 + instance.

    PX4 answers the first ground station it hears on a UDP link, for the rest of its life. With the
    remote port set to where uavloc listens, every later ``udpin`` on that port is that same peer,
    so several uavloc commands in a row can talk to one PX4 (``udpout`` to 18570+i works once).
    """
    return _sitl.start_px4(build("px4"), home=home, sysid=sysid, speedup=speedup, gcs_port=gcs_port, env=env,
                           wait=wait, timeout_s=timeout_s, instances=PX4_INSTANCES, companion=companion)


def run(coro, timeout_s: float = 300.0):
    """Run ``coro`` on a fresh event loop with an overall wall-clock deadline."""
    import asyncio

    async def bounded():
        async with asyncio.timeout(timeout_s):
            return await coro
    return asyncio.run(bounded())
