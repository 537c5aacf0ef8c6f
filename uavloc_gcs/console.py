"""A console that can never stop or freeze a search.

Issue 26: ``uavloc demo --no-web | head -2`` exited 0 after 4 s and abandoned the search (the
first write after ``head`` left raised BrokenPipeError); ``uavloc daemon ... | timeout 8 cat`` kept
running but made no decision after 138 s. Writing to a pipe whose reader is gone raises, and one
whose reader stalls blocks the writer -- in the event loop, the whole search.

:class:`Console` wraps ``sys.stdout``/``sys.stderr``: writes go into a bounded queue that one
background thread writes out. A reader that is gone (BrokenPipeError, any OSError) closes the
console for good: its file descriptor is pointed at /dev/null (so nothing later, not even the
interpreter's flush at exit, raises), and the search goes on, its events in the store and in
``uavloc.log`` (service/run.py). A reader that stalls fills the queue: lines are then dropped and
counted, never waited for. :func:`drain` at the end gives the last lines (the results table) a
bounded time to be written.
"""

from __future__ import annotations

import os
import queue
import sys
import threading
import time

QUEUE_LINES = 2000
DRAIN_S = 5.0  # wall seconds the end waits for the console to take the last lines


class Console:
    """A write-only text stream in front of ``stream`` that never raises and never blocks."""

    def __init__(self, stream, name: str):
        self.stream = stream
        self.name = name
        self.closed_reason = ""  # why the console was given up ("" while it works)
        self.dropped = 0  # writes dropped because the reader did not keep up
        self._queue: queue.Queue = queue.Queue(QUEUE_LINES)
        self._idle = threading.Event()
        self._idle.set()
        self._thread = threading.Thread(target=self._run, name=f"console-{name}", daemon=True)
        self._thread.start()

    # -- the stream interface the CLI and logging use ---------------------------------------------
    def write(self, text: str) -> int:
        if self.closed_reason or not text:
            return len(text)
        try:
            self._idle.clear()
            self._queue.put_nowait(text)
        except queue.Full:
            self.dropped += 1
        return len(text)

    def flush(self) -> None:  # written by the thread as soon as it can
        pass

    def isatty(self) -> bool:
        try:
            return self.stream.isatty()
        except (OSError, ValueError):
            return False

    def __getattr__(self, name):  # encoding, fileno, ...: the real stream's
        return getattr(self.stream, name)

    # -- the writer thread ------------------------------------------------------------------------
    def _run(self) -> None:
        while True:
            text = self._queue.get()
            if not self.closed_reason:
                try:
                    self.stream.write(text)
                    self.stream.flush()
                except (OSError, ValueError) as exc:  # BrokenPipeError, a closed file, ...
                    self._give_up(exc)
            if self._queue.empty():
                self._idle.set()

    def _give_up(self, exc: BaseException) -> None:
        self.closed_reason = f"{type(exc).__name__}: {exc}"
        try:  # later writes and the flush at exit go nowhere instead of raising
            fd = self.stream.fileno()
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, fd)
            os.close(devnull)
        except (OSError, ValueError, AttributeError):
            pass
        import logging  # noqa: PLC0415

        logging.getLogger(__name__).warning(
            "%s closed (%s): the search goes on; its events are in the store and uavloc.log", self.name,
            self.closed_reason)

    def drain(self, timeout_s: float = DRAIN_S) -> bool:
        """Wait up to ``timeout_s`` for what was written so far to be written out."""
        deadline = time.monotonic() + timeout_s
        while not self._idle.wait(0.05):
            if time.monotonic() >= deadline:
                return False
        return True


def install() -> tuple[Console, Console]:
    """Put a :class:`Console` in front of sys.stdout and sys.stderr (idempotent)."""
    if not isinstance(sys.stdout, Console):
        sys.stdout = Console(sys.stdout, "stdout")
    if not isinstance(sys.stderr, Console):
        sys.stderr = Console(sys.stderr, "stderr")
    return sys.stdout, sys.stderr


def drain(timeout_s: float = DRAIN_S) -> None:
    """Give the consoles up to ``timeout_s`` to write out what they hold."""
    for stream in (sys.stdout, sys.stderr):
        if isinstance(stream, Console):
            stream.drain(timeout_s)
