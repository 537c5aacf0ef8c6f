"""Write a file so that a reader never sees half of it: a temporary sibling, then a rename.

A rename cannot cross filesystems (``EXDEV``: the destination is a USB stick's mount point, or
behind a symbolic link to another disk). There :func:`replace` falls back to copying onto the
destination's filesystem -- a temporary file beside the destination, flushed to disk -- and
renaming that, so the destination still holds the old file or the new one, never half of one.

A file that cannot be written at all (a read-only or full disk, a directory that cannot hold
files such as ``/proc``) is an :class:`~uavloc_gcs.errors.OutputError` naming the path, not a
traceback.
"""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
import tempfile
from pathlib import Path
from typing import IO, Iterator

from .errors import OutputError

FILE_MODE = 0o644  # mkstemp creates 0600; mission files, results and pictures are meant to be shared
# errno values of a write that failed for the disk's sake (full, over quota, broken), not the writer's
_DISK_FAILURES = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EIO}


def reason(exc: OSError) -> str:
    """The operating system's words for ``exc`` ("No space left on device")."""
    return exc.strerror or str(exc)


@contextlib.contextmanager
def atomic_open(path: str | Path, mode: str = "w", *, suffix: str = "") -> Iterator[IO]:
    """Open a temporary file next to ``path`` for writing (``mode`` "w" text or "wb" binary).

    When the block ends normally the file is made 0644 and renamed over ``path`` (copied across
    filesystems where it must be); on any exception it is removed and ``path`` is left as it was.
    A file that cannot be written (the directory refuses it, the disk is full) raises OutputError
    naming ``path``.
    """
    p = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=suffix, dir=p.parent if str(p.parent) else ".")
    except OSError as exc:
        raise OutputError(f"cannot write {p}: {reason(exc)}") from None
    try:
        fh = os.fdopen(fd, mode) if "b" in mode else os.fdopen(fd, mode, encoding="utf-8", newline="")
        try:
            with fh:
                yield fh
        except OSError as exc:
            if exc.errno not in _DISK_FAILURES:
                raise
            raise OutputError(f"cannot write {p}: {reason(exc)}") from None
        try:
            os.chmod(tmp, FILE_MODE)
            replace(tmp, p)
        except OSError as exc:
            raise OutputError(f"cannot write {p}: {reason(exc)}") from None
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8, newlines as given) to ``path`` atomically."""
    with atomic_open(path, "w") as fh:
        fh.write(text)
    return Path(path)


def replace(src: str | Path, dest: str | Path) -> None:
    """``os.replace(src, dest)`` for a file or a directory (an existing ``dest`` directory is
    replaced whole), also across filesystems (see the module's docstring)."""
    src, dest = Path(src), Path(dest)
    if not (dest.is_dir() and not dest.is_symlink()):
        try:
            os.replace(src, dest)
            return
        except OSError as exc:
            if exc.errno != errno.EXDEV:
                raise
    commit_staged(stage_beside(src, dest), dest)


def stage_beside(src: str | Path, dest: str | Path) -> Path:
    """Move the file or directory ``src`` into a private hidden directory beside ``dest`` and
    return its new path, from where :func:`commit_staged` renames it over ``dest`` within one
    filesystem (or :func:`discard_staged` drops it).

    A plain rename where ``src`` is on ``dest``'s filesystem; where it is not (EXDEV), a copy
    flushed to disk, then ``src`` removed. On failure nothing is left beside ``dest`` and ``src``
    is as it was.
    """
    src, dest = Path(src), Path(dest)
    parent = dest.parent if str(dest.parent) else Path(".")
    staged = Path(tempfile.mkdtemp(prefix=f".{dest.name}.staged-", dir=parent)) / dest.name
    try:
        try:
            os.rename(src, staged)
            return staged
        except OSError as exc:
            if exc.errno != errno.EXDEV:
                raise
        _copy_synced(src, staged)
    except BaseException:
        discard_staged(staged)
        raise
    _remove(src)
    return staged


def commit_staged(staged: Path, dest: str | Path) -> None:
    """Rename what :func:`stage_beside` staged over ``dest`` (a directory there is replaced)."""
    dest = Path(dest)
    if dest.is_dir() and not dest.is_symlink():
        shutil.rmtree(dest)
    os.replace(staged, dest)
    with contextlib.suppress(OSError):
        os.rmdir(staged.parent)


def discard_staged(staged: Path) -> None:
    """Remove what :func:`stage_beside` staged, and its private directory."""
    shutil.rmtree(staged.parent, ignore_errors=True)


def _copy_synced(src: Path, dest: Path) -> None:
    """Copy a file (with its mode) or a directory tree to ``dest`` and flush it to disk."""
    if src.is_dir():
        shutil.copytree(src, dest)
        files = [p for p in dest.rglob("*") if p.is_file()]
    else:
        shutil.copy2(src, dest)
        files = [dest]
    for f in files:
        with open(f, "rb+") as fh:
            os.fsync(fh.fileno())


def _remove(path: Path) -> None:
    with contextlib.suppress(OSError):
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()
