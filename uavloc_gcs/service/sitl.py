"""Real autopilots on this machine: ArduCopter SITL and PX4 SIH, started, wired and stopped.

Used by ``uavloc sitl`` (a fleet for ``uavloc daemon``) and by the SITL tests (tests/sitl/harness.py).

>>> with start_arducopter(binary, home=HOME) as ap:   # or start_px4(folder, home=HOME, sysid=2)
...     ...                                            # uavloc connects to ap.connection

Each instance gets its own temporary directory (eeprom, logs, the process's output) and an instance
number taken from a lock file in the system temp dir (``fcntl.flock``, held while the process lives
and released by the kernel if its parent dies), so concurrent users never share ports; an instance
whose fixed ports are busy is passed over. Processes run in their own session and are stopped by
process group: TERM, then KILL after a grace period (:meth:`SitlProcess.stop`, a context manager
exit, atexit), and the kernel kills them when the process that started them dies
(``PR_SET_PDEATHSIG``).

Ports, all on 127.0.0.1:
* ArduCopter ``-I N`` sends serial0 to the ground station (``udpclient``) on a port chosen here;
  uavloc listens there (``connection`` = ``udpin:127.0.0.1:PORT``). A companion on serial1 is the
  same, on a port of its own. ArduCopter exits when its parent process does: whoever starts it
  stays alive while it flies.
* PX4 instance i binds 18570+i (ground station), 14580+i (onboard/API), 14280+i, 13030+i and
  19450+i. Its shipped scripts send the ground link to 14550 and the onboard link to 14540+i and
  set its system id to i+1; here a ``px4-rc.mavlink`` found first on PATH (PX4's rcS sources it
  from there) sends both links to ports chosen here and sets ``MAV_SYS_ID`` to the id asked for.
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

from ..dialect import mavlink
from ..errors import ConfigError, UavlocError

AUTOPILOTS = ("ardupilot", "px4")
AP_INSTANCES = range(0, 50)
PX4_INSTANCES = range(0, 10)  # PX4's scripts give instances above 9 the same ports
MAX_VEHICLES = 10
LOCK_DIR = Path(tempfile.gettempdir()) / "uavloc-sitl-instances"
STOP_GRACE_S = 5.0
READY_TIMEOUT_S = 120.0  # wall seconds from start to ready (GPS in use / ready for takeoff)
DEFAULT_SPEEDUP = 5.0  # measured on a loaded 2-core machine: ArduCopter keeps up at 5-10x, PX4 at ~5x

# ArduCopter's serial1 (MAVLink channel 2) carries the companion: position and time streams for it,
# forwarding of the RSSI message (an id ArduPilot does not know) with MAV2_OPTIONS bit 3, and a
# 20 Ah battery (the stock SITL battery is too small for a search).
AP_COMPANION_PARAMS = {"MAV2_POSITION": 10, "MAV2_EXTRA3": 2, "MAV2_OPTIONS": 8, "BATT_CAPACITY": 20000}


class SitlError(UavlocError):
    """An autopilot did not start or did not become ready; the message ends with its output's tail."""


# -- where the builds are -------------------------------------------------------------------------

def checkout_sitl_dir() -> Path:
    """``../shared/sitl`` beside the project checkout (where CI puts the builds)."""
    return Path(__file__).resolve().parents[3] / "shared" / "sitl"


def default_sitl_dirs() -> list[Path]:
    """Where ``uavloc sitl`` looks without ``--sitl-dir``: ``$UAVLOC_SITL_DIR``, ``../shared/sitl``
    from the current directory, then beside the checkout."""
    env = os.environ.get("UAVLOC_SITL_DIR")
    dirs = [Path(env)] if env else []
    return dirs + [Path("..") / "shared" / "sitl", checkout_sitl_dir()]


def arducopter_in(path: Path) -> Path | None:
    """The ``arducopter`` binary given as ``path`` itself, in it, or in its ``ardupilot/``."""
    for p in (path, path / "arducopter", path / "ardupilot" / "arducopter"):
        if p.is_file():
            return p
    return None


def px4_in(path: Path) -> Path | None:
    """The PX4 build folder (``bin/px4`` and ``etc/``) given as ``path``, its ``px4/``, or the
    folder of ``path`` when it is the ``px4`` binary itself."""
    if path.is_file() and path.name == "px4":
        path = path.parent.parent
    for p in (path, path / "px4"):
        if (p / "bin" / "px4").is_file() and (p / "etc" / "init.d-posix" / "rcS").is_file():
            return p
    return None


def find_build(kind: str, path: Path | None = None) -> Path:
    """The ArduCopter binary or the PX4 build folder, at ``path`` or in the default places; a
    ConfigError naming ``--sitl-dir`` when there is none."""
    find = arducopter_in if kind == "ardupilot" else px4_in
    what = ("ArduCopter SITL binary ('arducopter')" if kind == "ardupilot"
            else "PX4 SITL build (bin/px4 and etc/init.d-posix/rcS)")
    if path is not None:
        found = find(Path(path))
        if found is None:
            raise ConfigError(f"{path} holds no {what} (give the folder with ardupilot/ and px4/, or the "
                              "build itself)", key="--sitl-dir")
        return found.resolve()
    for d in default_sitl_dirs():
        found = find(d)
        if found is not None:
            return found.resolve()
    raise ConfigError(f"no {what} in {', '.join(str(d) for d in default_sitl_dirs())}: give --sitl-dir "
                      "(a folder with ardupilot/ and px4/ as in ../shared/sitl, or your own build)",
                      key="--sitl-dir")


def copter_parm(binary: Path) -> Path:
    """copter.parm beside the binary, or in the ArduPilot checkout a ``./waf copter`` build is in."""
    for p in (binary.parent / "copter.parm",
              binary.parent.parent.parent.parent / "Tools" / "autotest" / "default_params" / "copter.parm"):
        if p.is_file():
            return p
    raise ConfigError(f"no copter.parm beside {binary} (copy Tools/autotest/default_params/copter.parm of your "
                      "ArduPilot checkout there)", key="--sitl-dir")


# -- instance numbers and ports -------------------------------------------------------------------

def port_free(port: int, kind: int = socket.SOCK_DGRAM) -> bool:
    with socket.socket(socket.AF_INET, kind) as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


def free_udp_port() -> int:
    """An ephemeral UDP port on 127.0.0.1 that was free a moment ago."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def instance_ports(kind: str, n: int) -> list[int]:
    """The UDP ports an instance binds whatever it is told (PX4's per-instance links, ArduCopter's
    RC input)."""
    if kind == "px4":
        return [18570 + n, 14580 + n, 14280 + n, 13030 + n, 19450 + n]
    if kind == "ardupilot":
        return [5501 + 10 * n]
    return []


class InstanceLock:
    """An instance number held through ``LOCK_DIR/<kind>-<n>.lock`` until :meth:`release`."""

    def __init__(self, kind: str, numbers):
        LOCK_DIR.mkdir(parents=True, exist_ok=True)
        numbers = list(numbers)
        self._fd = None
        for n in numbers:
            fd = os.open(LOCK_DIR / f"{kind}-{n}.lock", os.O_RDWR | os.O_CREAT, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                os.close(fd)
                continue
            busy = (kind == "px4" and _px4_instance_running(n)) or not all(map(port_free, instance_ports(kind, n)))
            if busy:  # a PX4 nobody's lock accounts for, or another program on its ports
                os.close(fd)
                continue
            os.ftruncate(fd, 0)
            os.write(fd, f"{os.getpid()}\n".encode())
            self.kind, self.number, self._fd = kind, n, fd
            return
        raise SitlError(f"all {kind} SITL instance numbers {numbers[0]}-{numbers[-1]} are in use or their ports "
                        f"are busy (lock files in {LOCK_DIR})")

    def release(self) -> None:
        if self._fd is not None:
            os.close(self._fd)  # closing drops the flock
            self._fd = None


def _px4_instance_running(n: int) -> bool:
    """Whether a PX4 server holds its own per-instance lock (``/tmp/px4_lock-N``, a POSIX record
    lock while it runs), e.g. one started by hand or left by a process that was killed."""
    path = Path("/tmp") / f"px4_lock-{n}"
    if not path.exists():
        return False
    try:
        fd = os.open(path, os.O_RDWR)
    except OSError:
        return True
    try:
        fcntl.lockf(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        fcntl.lockf(fd, fcntl.LOCK_UN)
        return False
    except OSError:
        return True
    finally:
        os.close(fd)


def _die_with_parent() -> None:
    """In the child before exec: SIGKILL when the starting process dies, however it dies (a killed
    process runs no atexit handler, and the SITL lives in its own session)."""
    try:
        import ctypes
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except Exception:  # not Linux: the finalizers and atexit still stop it
        pass


# -- processes ------------------------------------------------------------------------------------

_LIVE: set["SitlProcess"] = set()


@dataclass(eq=False)
class SitlProcess:
    """One running autopilot. ``connection`` is what uavloc opens to talk to it; ``companion_url``
    (if wired) is where a companion computer talks to it."""

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
    companion_url: str = ""
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
        Keeps the work dir when ``UAVLOC_SITL_KEEP`` is set."""
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
def stop_all() -> None:
    for p in list(_LIVE):
        p.stop()


def _spawn(sitl: SitlProcess, argv: list[str], env: dict[str, str] | None = None) -> None:
    out = open(sitl.log_path, "wb")
    try:
        sitl.proc = subprocess.Popen(argv, cwd=sitl.workdir, stdin=subprocess.DEVNULL, stdout=out,
                                     stderr=subprocess.STDOUT, start_new_session=True, preexec_fn=_die_with_parent,
                                     env={**os.environ, **(env or {})})
    finally:
        out.close()
    sitl.started_wall_s = time.monotonic()
    _LIVE.add(sitl)


def _new(kind: str, numbers, home, speedup) -> SitlProcess:
    lock = InstanceLock(kind, numbers)
    tmp = tempfile.TemporaryDirectory(prefix=f"uavloc-{kind}{lock.number}-")
    return SitlProcess(kind, lock.number, 0, "", Path(tmp.name), tuple(home), speedup, _lock=lock, _tmp=tmp)


def _check_port(port: int | None, what: str) -> None:
    if port is not None and not port_free(port):
        raise ConfigError(f"UDP port {port} on 127.0.0.1 is busy; choose another", key=what)


def start_arducopter(binary: Path, *, home, sysid: int = 1, speedup: float = DEFAULT_SPEEDUP,
                     gcs_port: int | None = None, serial1: str = "none:0", params: dict[str, float] | None = None,
                     wait: str = "gps", timeout_s: float = READY_TIMEOUT_S, instances=AP_INSTANCES,
                     companion: bool = False, companion_port: int | None = None) -> SitlProcess:
    """Start ArduCopter (``--model +``, copter.parm, a wiped eeprom) and wait for ``wait``:
    "gps" (STATUSTEXT "... is using GPS": the EKF can arm soon), "heartbeat", or "none".

    ``gcs_port``: the UDP port the ground station listens on (default: a fresh one; several
    vehicles given the same port share one link). ``params``: extra parameters written to a
    defaults file after copter.parm. ``companion``: wire serial1 to a companion computer listening
    on ``companion_port`` (default: a fresh one) with AP_COMPANION_PARAMS; ``companion_url`` is
    then where the companion listens.
    """
    parm = copter_parm(binary)
    _check_port(companion_port, "companion port")
    sitl = _new("ardupilot", instances, home, speedup)
    try:
        sitl.sysid = sysid
        port = gcs_port or free_udp_port()
        sitl.connection = f"udpin:127.0.0.1:{port}"
        if companion:
            cport = companion_port or free_udp_port()
            serial1 = f"udpclient:127.0.0.1:{cport}"
            sitl.companion_url = f"udpin:127.0.0.1:{cport}"
            params = {**AP_COMPANION_PARAMS, **(params or {})}
        defaults = [str(parm)]
        if params:
            extra = sitl.workdir / "uavloc.parm"
            extra.write_text("".join(f"{k} {v:g}\n" for k, v in params.items()))
            defaults.append(str(extra))
        argv = [str(binary), "--model", "+", "--speedup", f"{speedup:g}", "--defaults", ",".join(defaults),
                "-I", str(sitl.instance), "--home", ",".join(f"{v:g}" for v in home), "--wipe",
                "--sysid", str(sysid), "--serial0", f"udpclient:127.0.0.1:{port}", "--serial1", serial1,
                "--serial2", "none:0"]
        if wait != "none" and gcs_port is None:
            with listener(port) as sock:
                _spawn(sitl, argv)
                wait_ardupilot(sitl, sock, wait, timeout_s)
        else:
            _spawn(sitl, argv)
        return sitl
    except BaseException:
        sitl.stop()
        raise


def start_px4(folder: Path, *, home, sysid: int | None = None, speedup: float = DEFAULT_SPEEDUP,
              gcs_port: int | None = None, env: dict[str, str] | None = None, wait: str = "ready",
              timeout_s: float = READY_TIMEOUT_S, instances=PX4_INSTANCES, companion: bool = False,
              companion_port: int | None = None) -> SitlProcess:
    """Start PX4 SIH (quadrotor, as run-px4-sih.sh does) and wait for ``wait``: "ready" (console
    "Ready for takeoff") or "none". Its system id is ``sysid`` (default: PX4's own, 1 + instance).
    Its ground-station link sends to ``gcs_port`` (default: a fresh one) where uavloc listens, like
    QGC on 14550; with ``companion`` its onboard link sends to ``companion_port`` (default: a fresh
    one; without it, PX4's 14540 + instance), where ``companion_url`` listens.

    PX4 answers the first ground station it hears on a UDP link, for the rest of its life. With the
    remote port set to where uavloc listens, every later ``udpin`` on that port is that same peer,
    so several uavloc commands in a row can talk to one PX4.
    """
    _check_port(companion_port, "companion port")
    sitl = _new("px4", instances, home, speedup)
    try:
        sitl.sysid = sysid if sysid is not None else 1 + sitl.instance
        port = gcs_port or free_udp_port()
        sitl.connection = f"udpin:127.0.0.1:{port}"
        cport = (companion_port or free_udp_port()) if companion else 14540 + sitl.instance
        sitl.companion_url = f"udpin:127.0.0.1:{cport}"
        lat, lon, alt = home[:3]
        run_env = {"PX4_HOME_LAT": f"{lat:.7f}", "PX4_HOME_LON": f"{lon:.7f}", "PX4_HOME_ALT": f"{alt:g}",
                   "PX4_SIM_SPEED_FACTOR": f"{speedup:g}", **(env or {})}
        bin_dir = _px4_bin(folder, sitl.workdir, port, sysid=sysid, onboard_port=cport if companion else None)
        run_env.update(PX4_SYS_AUTOSTART="10040", PX4_SIMULATOR="sihsim", PX4_SIM_MODEL="sihsim_quadx",
                       PATH=f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}")
        (sitl.workdir / "px4").mkdir()
        _spawn(sitl, [str(folder / "bin" / "px4"), "-d", "-i", str(sitl.instance), "-w", str(sitl.workdir / "px4"),
                      str(folder / "etc")], run_env)
        if wait == "ready":
            wait_log(sitl, "Ready for takeoff", timeout_s)
        return sitl
    except BaseException:
        sitl.stop()
        raise


def _px4_bin(folder: Path, workdir: Path, gcs_port: int, *, sysid: int | None = None,
             onboard_port: int | None = None) -> Path:
    """A bin dir of ``px4-<module>`` command links to ``px4``, which PX4's startup shell calls,
    and the ``px4-rc.mavlink`` that sets the links' remote ports and the system id.

    run-px4-sih.sh puts the build's own bin/ on PATH, but a copy of a build may have turned those
    symbolic links into small files holding the link's target ("px4"), which the shell cannot run;
    the links are made again here, in the instance's own directory.
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
    text = (folder / "etc" / "init.d-posix" / "px4-rc.mavlink").read_text()
    gcs_line = "mavlink start -x -u $udp_gcs_port_local -r 4000000 -f"
    if gcs_line not in text:
        raise SitlError(f"PX4's px4-rc.mavlink has no line {gcs_line!r} to give the ground station's port")
    text = text.replace(gcs_line, f"{gcs_line} -o {gcs_port}", 1)
    if onboard_port is not None:
        onboard = "-m onboard -o $udp_offboard_port_remote"
        if onboard not in text:
            raise SitlError(f"PX4's px4-rc.mavlink has no {onboard!r} to give the companion's port")
        text = text.replace(onboard, f"-m onboard -o {onboard_port}", 1)
    if sysid is not None:
        # rcS sets MAV_SYS_ID to instance + 1 before it sources this file; the modules read it
        # again on the parameter update, before any MAVLink link starts
        text = f"param set MAV_SYS_ID {int(sysid)}\n" + text
    (dst / "px4-rc.mavlink").write_text(text)
    return dst


# -- readiness ------------------------------------------------------------------------------------

@contextlib.contextmanager
def listener(port: int):
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        try:
            sock.bind(("127.0.0.1", port))
        except OSError:
            raise ConfigError(f"UDP port {port} on 127.0.0.1 is busy; choose another", key="ground-station port") \
                from None
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


def wait_ardupilot(sitl: SitlProcess, sock: socket.socket, wait: str, timeout_s: float) -> None:
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


def wait_log(sitl: SitlProcess, text: str, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        with contextlib.suppress(OSError):
            if text in sitl.log_path.read_text(errors="replace"):
                sitl.ready_after_s = time.monotonic() - sitl.started_wall_s
                return
        _check_alive(sitl, f'"{text}"')
        time.sleep(0.2)
    raise _timeout(sitl, f'"{text}"', timeout_s)


# -- a fleet for the daemon -----------------------------------------------------------------------
