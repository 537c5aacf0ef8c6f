"""One daemon per store: an exclusive ``fcntl`` lock on ``DIR/.uavloc.lock``.

The lock belongs to the open file, so it dies with the process however the process ends (crash,
SIGKILL, power loss of a laptop): a restarted daemon is never locked out by a stale file. The file
holds the holder's pid so a refused second daemon can name it.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
from pathlib import Path
from typing import Iterator

from ..errors import ConfigError

LOCK_NAME = ".uavloc.lock"


@contextlib.contextmanager
def store_lock(out_dir: Path, what: str = "search") -> Iterator[Path]:
    """Hold the lock on ``out_dir`` (created if missing) for the ``with`` block; ConfigError when
    another process holds it."""
    out_dir = Path(out_dir)
    created = not out_dir.exists()
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        path = out_dir / LOCK_NAME
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise ConfigError(f"cannot use {out_dir} as the output directory: {exc.strerror}") from None
    held = False
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "unknown"
            raise ConfigError(f"{out_dir} is in use by another uavloc {what} (pid {holder}); stop it first "
                              "or choose another --out") from None
        held = True
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield path
    finally:
        if held:  # nothing left behind: the lock file goes, and the directory if it is empty and ours
            with contextlib.suppress(OSError):
                path.unlink()
            if created:
                with contextlib.suppress(OSError):
                    out_dir.rmdir()
        os.close(fd)  # releases the lock
