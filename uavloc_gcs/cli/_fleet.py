"""Run the fake fleet in a child process (its own interpreter, so its own GIL and core).

The demo's daemon and the fleet would otherwise share one interpreter lock: the planner's and
estimator's bursts would delay the fake vehicles' answers, which looks like a slow radio link.
The child sends back its endpoints and clock epoch; the parent rebuilds the same deterministic
world (``sim_link.world.World(scenario, seed=...)``) when it needs the truth.
"""

from __future__ import annotations

import asyncio
import contextlib
import multiprocessing as mp
import os
import queue as queue_mod
import signal
import threading
from dataclasses import dataclass

from ..errors import LinkError, UavlocError

START_TIMEOUT_S = 30.0


@dataclass
class FleetProcess:
    endpoints: list  # [(name, connection)]
    epoch_unix_s: float
    speedup: float
    _proc: mp.process.BaseProcess
    _stop: object
    _commands: object = None

    def drop_link(self, vehicle: int, seconds: float) -> None:
        """Drop every datagram to and from ``vehicle`` for ``seconds`` of mission time."""
        self._commands.put(("drop_link", vehicle, seconds))

    def reboot(self, vehicle: int, keep_mission: bool | None = None) -> None:
        self._commands.put(("reboot", vehicle, keep_mission))

    def swap_pack(self, vehicle: int) -> None:
        """The team gives ``vehicle`` a fresh pack (on the ground, disarmed; a reboot)."""
        self._commands.put(("swap_pack", vehicle))

    def stop(self, timeout_s: float = 5.0) -> None:
        self._stop.set()
        self._proc.join(timeout_s)
        if self._proc.is_alive():
            _kill(self._proc, timeout_s)


def _kill(proc, timeout_s: float = 5.0) -> None:
    if proc.pid is None:  # never started
        return
    proc.terminate()
    proc.join(timeout_s)
    if proc.is_alive():
        proc.kill()
        proc.join(timeout_s)


def _child(scenario, kwargs: dict, queue, stop, commands, parent_pid: int) -> None:
    # Ctrl-C in the terminal reaches the whole process group: the parent decides when the fleet
    # stops (after sending it home); and if the parent dies without stopping it, the fleet ends.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    from sim_link.vehicles.fleet import FakeFleet

    async def main() -> None:
        try:
            fleet = FakeFleet(scenario, **kwargs)
            await fleet.start()
        except OSError as exc:
            queue.put(("error", f"cannot open the fake vehicles' UDP ports ({exc.strerror}); "
                                "try another --base-port"))
            return
        except Exception as exc:  # said in the parent, not as a child's traceback and a 30 s wait
            queue.put(("failed", f"the fake fleet could not start: {type(exc).__name__}: {exc}"))
            return
        queue.put(("ok", fleet.endpoints, fleet.epoch_unix_s, fleet.speedup))
        while not stop.is_set() and os.getppid() == parent_pid:
            while not commands.empty():
                name, *cargs = commands.get()
                getattr(fleet, name)(*cargs)
            await asyncio.sleep(0.02)
        await fleet.aclose()

    asyncio.run(main())


@contextlib.contextmanager
def _signals_held():
    """While the child is spawned: SIGTERM is held and delivered after, SIGINT ignored.

    A handler that raises (the demo's SIGTERM, Ctrl-C) between the child's fork and the parent's
    write of its start-up data left the child to die on a half-sent pickle, with a traceback on the
    operator's terminal (CI, 2026-11-27). SIGINT is ignored rather than held so that the child
    inherits the ignoring from birth: Ctrl-C reaches the whole process group, and a child still
    importing would print a KeyboardInterrupt traceback before its own ``SIG_IGN``. A Ctrl-C in
    those few milliseconds is not seen (the operator presses again)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []
    previous = {}
    for signum, handler in ((signal.SIGTERM, lambda s, _frame: held.append(s)), (signal.SIGINT, signal.SIG_IGN)):
        if signal.getsignal(signum) is not None:  # None: installed outside Python, cannot be put back
            previous[signum] = signal.signal(signum, handler)
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        if held:
            signal.raise_signal(signal.SIGTERM)


def start_fleet_process(scenario, **kwargs) -> FleetProcess:
    """Start ``sim_link.vehicles.fleet.FakeFleet(scenario, **kwargs)`` in a child process."""
    ctx = mp.get_context("spawn")
    queue, stop, commands = ctx.Queue(), ctx.Event(), ctx.Queue()
    proc = ctx.Process(target=_child, args=(scenario, kwargs, queue, stop, commands, os.getpid()),
                       name="uavloc-fake-fleet", daemon=True)
    try:
        with _signals_held():
            proc.start()
        msg = None
        for _ in range(int(START_TIMEOUT_S / 0.5)):
            try:
                msg = queue.get(timeout=0.5)
                break
            except queue_mod.Empty:
                if not proc.is_alive():  # died without a word (killed, out of memory)
                    raise UavlocError(f"the fake fleet's process ended at start (exit code {proc.exitcode})") \
                        from None
        if msg is None:
            raise queue_mod.Empty
    except queue_mod.Empty:
        _kill(proc)
        raise LinkError(f"the fake fleet did not start within {START_TIMEOUT_S:g} s", operation="demo") from None
    except BaseException:  # a signal while waiting: never leave the fleet behind
        _kill(proc)
        raise
    if msg[0] != "ok":
        proc.join(5)
        raise (LinkError(msg[1], operation="demo") if msg[0] == "error" else UavlocError(msg[1]))
    return FleetProcess(msg[1], msg[2], msg[3], proc, stop, commands)
