"""Real autopilots for the tests: ArduCopter SITL and PX4 SIH, started and stopped by pid.

>>> with start_arducopter(home=HOME) as ap:          # or start_px4(home=HOME)
...     run(fly(ap.connection, ap.sysid))             # the uavloc side connects to ap.connection

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

import atexit
import contextlib
import fcntl
import os
import signal
import socket
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from uavloc_gcs.dialect import mavlink

ROOT = Path(__file__).resolve().parents[2]
DEFAULT_SITL_DIR = ROOT.parent / "shared" / "sitl"

# Simulated time runs this many times faster than wall time. Measured on the 2-core CI box with
# other work running (docs/readme/sitl.md): ArduCopter keeps up at 5-10x, PX4 lockstep at ~5x.
ARDUPILOT_SPEEDUP = int(os.environ.get("UAVLOC_SITL_AP_SPEEDUP", "5"))
PX4_SPEEDUP = int(os.environ.get("UAVLOC_SITL_PX4_SPEEDUP", "5"))

AP_INSTANCES = range(0, 40)  # 40-49 are kept for SITLs run by hand
PX4_INSTANCES = range(0, 8)  # 8-9 are kept for SITLs run by hand; >9 share ports in PX4's scripts
LOCK_DIR = Path(tempfile.gettempdir()) / "uavloc-sitl-instances"
STOP_GRACE_S = 5.0
READY_TIMEOUT_S = 120.0  # wall seconds from start to ready (GPS in use / ready for takeoff)

HOME = (42.625, 13.283, 900.0, 0.0)  # lat, lon, alt AMSL m, heading deg: the project's scenario area

ENABLE_HINT = ("real-autopilot SITL builds not found: put them at ../shared/sitl beside the checkout "
               "or set UAVLOC_SITL_DIR (or UAVLOC_ARDUCOPTER / UAVLOC_PX4_DIR) to enable these tests")


class SitlError(RuntimeError):
    """A SITL instance did not start or did not become ready; the message carries its log tail."""


# -- where the builds are -------------------------------------------------------------------------

def arducopter_binary() -> Path | None:
    env = os.environ.get("UAVLOC_ARDUCOPTER")
    if env:
        return Path(env) if Path(env).is_file() else None
    base = Path(os.environ.get("UAVLOC_SITL_DIR", DEFAULT_SITL_DIR))
    path = base / "ardupilot" / "arducopter"
    return path if path.is_file() else None


def px4_dir() -> Path | None:
    env = os.environ.get("UAVLOC_PX4_DIR")
    base = Path(env) if env else Path(os.environ.get("UAVLOC_SITL_DIR", DEFAULT_SITL_DIR)) / "px4"
    return base if (base / "run-px4-sih.sh").is_file() else None


def skip_reason(kind: str) -> str | None:
    """None when the ``kind`` ("ardupilot" / "px4") build is present, else the skip sentence."""
    found = arducopter_binary() if kind == "ardupilot" else px4_dir()
    return None if found is not None else ENABLE_HINT


# -- instance numbers -----------------------------------------------------------------------------

class InstanceLock:
    """An instance number held through ``LOCK_DIR/<kind>-<n>.lock`` until :meth:`release`."""

    def __init__(self, kind: str, numbers: range):
        LOCK_DIR.mkdir(parents=True, exist_ok=True)
        for n in numbers:
            fd = os.open(LOCK_DIR / f"{kind}-{n}.lock", os.O_RDWR | os.O_CREAT, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                os.close(fd)
                continue
            os.ftruncate(fd, 0)
            os.write(fd, f"{os.getpid()}\n".encode())
            self.kind, self.number, self._fd = kind, n, fd
            return
        raise SitlError(f"all {kind} SITL instance numbers {numbers.start}-{numbers.stop - 1} are in use "
                        f"(lock files in {LOCK_DIR})")

    def release(self) -> None:
        if self._fd is not None:
            os.close(self._fd)  # closing drops the flock
            self._fd = None


def free_udp_port() -> int:
    """An ephemeral UDP port on 127.0.0.1 that was free a moment ago."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# -- processes ------------------------------------------------------------------------------------

_LIVE: set["SitlProcess"] = set()


@dataclass(eq=False)
class SitlProcess:
    """One running autopilot. ``connection`` is what uavloc opens to talk to it."""

    kind: str  # "ardupilot" | "px4"
    instance: int
    sysid: int
    connection: str
    workdir: Path
    home: tuple[float, float, float, float]
    speedup: float
    proc: subprocess.Popen | None = None
    started_wall_s: float = field(default_factory=time.monotonic)
    ready_after_s: float | None = None  # wall seconds from start to ready
    _lock: InstanceLock | None = None
    _tmp: tempfile.TemporaryDirectory | None = None

    @property
    def log_path(self) -> Path:
        return self.workdir / "sitl-output.log"

    def log_tail(self, lines: int = 40) -> str:
        try:
            text = self.log_path.read_text(errors="replace")
        except OSError:
            return "(no output)"
        return "\n".join(text.splitlines()[-lines:])

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def stop(self) -> None:
        """Stop the process group (TERM, then KILL after STOP_GRACE_S); free the instance number.
        Keeps the work dir when ``UAVLOC_SITL_KEEP`` is set (its path is in the log)."""
        proc, self.proc = self.proc, None
        if proc is not None and proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGTERM)
            try:
                proc.wait(STOP_GRACE_S)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(STOP_GRACE_S)
        elif proc is not None:
            with contextlib.suppress(ProcessLookupError):  # children may outlive a dead leader
                os.killpg(proc.pid, signal.SIGKILL)
        if self._lock is not None:
            self._lock.release()
            self._lock = None
        if self._tmp is not None and not os.environ.get("UAVLOC_SITL_KEEP"):
            self._tmp.cleanup()
            self._tmp = None
        _LIVE.discard(self)

    def __enter__(self) -> "SitlProcess":
        return self

    def __exit__(self, *exc) -> None:
        self.stop()


@atexit.register
def _stop_all() -> None:
    for p in list(_LIVE):
        p.stop()


def _spawn(sitl: SitlProcess, argv: list[str], env: dict[str, str] | None = None) -> None:
    out = open(sitl.log_path, "wb")
    try:
        sitl.proc = subprocess.Popen(argv, cwd=sitl.workdir, stdin=subprocess.DEVNULL, stdout=out,
                                     stderr=subprocess.STDOUT, start_new_session=True,
                                     env={**os.environ, **(env or {})})
    finally:
        out.close()
    sitl.started_wall_s = time.monotonic()
    _LIVE.add(sitl)


def _new(kind: str, numbers: range, home, speedup) -> SitlProcess:
    lock = InstanceLock(kind, numbers)
    tmp = tempfile.TemporaryDirectory(prefix=f"uavloc-{kind}{lock.number}-")
    return SitlProcess(kind, lock.number, 0, "", Path(tmp.name), tuple(home), speedup, _lock=lock, _tmp=tmp)


def start_arducopter(*, home=HOME, sysid: int = 1, speedup: float = ARDUPILOT_SPEEDUP,
                     gcs_port: int | None = None, serial1: str = "none:0", params: dict[str, float] | None = None,
                     wait: str = "gps", timeout_s: float = READY_TIMEOUT_S) -> SitlProcess:
    """Start ArduCopter (``--model +``, copter.parm, a wiped eeprom) and wait for ``wait``:
    "gps" (STATUSTEXT "... is using GPS": the EKF can arm soon), "heartbeat", or "none".

    ``gcs_port``: the UDP port the ground station listens on (default: a fresh ephemeral one;
    give the same port to several vehicles for one shared link). ``params``: extra parameters
    written to a defaults file after copter.parm.
    """
    binary = arducopter_binary()
    if binary is None:
        raise SitlError(ENABLE_HINT)
    sitl = _new("ardupilot", AP_INSTANCES, home, speedup)
    try:
        sitl.sysid = sysid
        port = gcs_port or free_udp_port()
        sitl.connection = f"udpin:127.0.0.1:{port}"
        defaults = [str(binary.parent / "copter.parm")]
        if params:
            extra = sitl.workdir / "uavloc.parm"
            extra.write_text("".join(f"{k} {v:g}\n" for k, v in params.items()))
            defaults.append(str(extra))
        argv = [str(binary), "--model", "+", "--speedup", f"{speedup:g}", "--defaults", ",".join(defaults),
                "-I", str(sitl.instance), "--home", ",".join(f"{v:g}" for v in home), "--wipe",
                "--sysid", str(sysid), "--serial0", f"udpclient:127.0.0.1:{port}", "--serial1", serial1,
                "--serial2", "none:0"]
        if wait != "none" and gcs_port is None:
            with _listener(port) as sock:
                _spawn(sitl, argv)
                _wait_ardupilot(sitl, sock, wait, timeout_s)
        else:
            _spawn(sitl, argv)
        return sitl
    except BaseException:
        sitl.stop()
        raise


def start_px4(*, home=HOME, speedup: float = PX4_SPEEDUP, gcs_port: int | None = None,
              env: dict[str, str] | None = None,
              wait: str = "ready", timeout_s: float = READY_TIMEOUT_S) -> SitlProcess:
    """Start PX4 SIH (quadrotor, as run-px4-sih.sh does) and wait for ``wait``: "ready" (console "Ready for takeoff") or
    "none". Its system id is 1 + instance. Its ground-station link sends to ``gcs_port`` (default:
    a fresh ephemeral one) where uavloc listens, like QGC on 14550.

    PX4 answers the first ground station it hears on a UDP link, for the rest of its life. With the
    remote port set to where uavloc listens, every later ``udpin`` on that port is that same peer,
    so several uavloc commands in a row can talk to one PX4 (``udpout`` to 18570+i works once).
    """
    folder = px4_dir()
    if folder is None:
        raise SitlError(ENABLE_HINT)
    sitl = _new("px4", PX4_INSTANCES, home, speedup)
    try:
        sitl.sysid = 1 + sitl.instance
        port = gcs_port or free_udp_port()
        sitl.connection = f"udpin:127.0.0.1:{port}"
        lat, lon, alt = home[:3]
        run_env = {"PX4_HOME_LAT": f"{lat:.7f}", "PX4_HOME_LON": f"{lon:.7f}", "PX4_HOME_ALT": f"{alt:g}",
                   "PX4_SIM_SPEED_FACTOR": f"{speedup:g}", **(env or {})}
        run_env.update(PX4_SYS_AUTOSTART="10040", PX4_SIMULATOR="sihsim", PX4_SIM_MODEL="sihsim_quadx",
                       PATH=f"{_px4_bin(folder, sitl.workdir, port)}{os.pathsep}{os.environ.get('PATH', '')}")
        (sitl.workdir / "px4").mkdir()
        _spawn(sitl, [str(folder / "bin" / "px4"), "-d", "-i", str(sitl.instance), "-w", str(sitl.workdir / "px4"),
                      str(folder / "etc")], run_env)
        if wait == "ready":
            _wait_log(sitl, "Ready for takeoff", timeout_s)
        return sitl
    except BaseException:
        sitl.stop()
        raise


def _px4_bin(folder: Path, workdir: Path, gcs_port: int) -> Path:
    """A bin dir of ``px4-<module>`` command links to ``px4``, which PX4's startup shell calls.

    run-px4-sih.sh does the same with the build's own bin/, but a copy of a build may have turned
    those symbolic links into small files holding the link's target ("px4"), which the shell cannot
    run; the links are made again here, in the instance's own directory.
    """
    src, dst = folder / "bin", workdir / "bin"
    dst.mkdir()
    for entry in src.iterdir():
        target = entry
        if entry.is_symlink():
            target = src / os.readlink(entry)
        elif entry.name.startswith("px4-") and entry.stat().st_size < 64 and not os.access(entry, os.X_OK):
            target = src / entry.read_text().strip()
        (dst / entry.name).symlink_to(target.resolve())
    # rcS sources px4-rc.mavlink from PATH ("user defined mavlink streams ... can be in PATH"):
    # the shipped one with the ground-station link's remote port (-o, default 14550) set.
    shipped = (folder / "etc" / "init.d-posix" / "px4-rc.mavlink").read_text()
    gcs_line = "mavlink start -x -u $udp_gcs_port_local -r 4000000 -f"
    if gcs_line not in shipped:
        raise SitlError(f"PX4's px4-rc.mavlink has no line {gcs_line!r} to give the ground station's port")
    (dst / "px4-rc.mavlink").write_text(shipped.replace(gcs_line, f"{gcs_line} -o {gcs_port}", 1))
    return dst


# -- readiness ------------------------------------------------------------------------------------

@contextlib.contextmanager
def _listener(port: int):
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.bind(("127.0.0.1", port))
        sock.settimeout(0.5)
        yield sock
    finally:
        sock.close()


def _check_alive(sitl: SitlProcess, waiting_for: str) -> None:
    if not sitl.alive():
        code = sitl.proc.returncode if sitl.proc is not None else None
        raise SitlError(f"{sitl.kind} SITL instance {sitl.instance} exited (code {code}) while waiting for "
                        f"{waiting_for}; its output ends:\n{sitl.log_tail()}")


def _timeout(sitl: SitlProcess, waiting_for: str, timeout_s: float) -> SitlError:
    return SitlError(f"{sitl.kind} SITL instance {sitl.instance} showed no {waiting_for} within {timeout_s:g} s "
                     f"(speed-up {sitl.speedup:g}); its output ends:\n{sitl.log_tail()}")


def _wait_ardupilot(sitl: SitlProcess, sock: socket.socket, wait: str, timeout_s: float) -> None:
    """Listen where serial0 sends; answer with a GCS heartbeat, since ArduPilot sends STATUSTEXT
    only on channels it has heard MAVLink on."""
    parser = mavlink.MAVLink(None)
    parser.robust_parsing = True
    gcs = mavlink.MAVLink(None, srcSystem=254, srcComponent=190)
    deadline = time.monotonic() + timeout_s
    what = "heartbeat" if wait == "heartbeat" else 'STATUSTEXT "... is using GPS"'
    peer, next_heartbeat = None, 0.0
    while time.monotonic() < deadline:
        _check_alive(sitl, what)
        if peer is not None and time.monotonic() >= next_heartbeat:
            sock.sendto(gcs.heartbeat_encode(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                                             mavlink.MAV_STATE_ACTIVE).pack(gcs), peer)
            next_heartbeat = time.monotonic() + 1.0
        try:
            data, peer = sock.recvfrom(65535)
        except socket.timeout:
            continue
        for msg in parser.parse_buffer(data) or ():
            kind = msg.get_type()
            if kind == "HEARTBEAT" and wait == "heartbeat" and msg.get_srcSystem() == sitl.sysid:
                sitl.ready_after_s = time.monotonic() - sitl.started_wall_s
                return
            if kind == "STATUSTEXT" and "is using GPS" in str(msg.text):
                sitl.ready_after_s = time.monotonic() - sitl.started_wall_s
                return
    raise _timeout(sitl, what, timeout_s)


def _wait_log(sitl: SitlProcess, text: str, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        with contextlib.suppress(OSError):
            if text in sitl.log_path.read_text(errors="replace"):
                sitl.ready_after_s = time.monotonic() - sitl.started_wall_s
                return
        _check_alive(sitl, f'"{text}"')
        time.sleep(0.2)
    raise _timeout(sitl, f'"{text}"', timeout_s)


def run(coro, timeout_s: float = 300.0):
    """Run ``coro`` on a fresh event loop with an overall wall-clock deadline."""
    import asyncio

    async def bounded():
        async with asyncio.timeout(timeout_s):
            return await coro
    return asyncio.run(bounded())
