"""Output helpers for commands: all-or-nothing output directories and files, and the checks that
refuse an output path that cannot be written before any work is done."""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from pathlib import Path
from typing import Iterator

from ..atomicfile import commit_staged, discard_staged, reason, stage_beside
from ..errors import OutputError

STAGING_PREFIX = ".uavloc-partial-"


@contextlib.contextmanager
def atomic_output_dir(path: str | Path) -> Iterator[Path]:
    """Yield a temporary directory whose files replace/merge into ``path`` only if the block succeeds.

    The temporary directory lies inside ``path`` when it exists (so nothing crosses filesystems
    and the parent need not be writable: a USB stick's mount point), else beside it. On success
    every file is first staged beside its destination (a rename, or a copy where it must cross
    filesystems) and only then renamed into place; on any exception the temporary directory is
    removed and ``path`` is left exactly as it was (not created if it did not exist).
    """
    target = Path(path)
    if target.exists() and not target.is_dir():
        raise OutputError(f"output path {target} exists and is not a directory")
    try:
        if target.is_dir():
            tmp = Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, dir=target))
        else:
            parent = target.parent if str(target.parent) else Path(".")
            parent.mkdir(parents=True, exist_ok=True)
            tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.partial-", dir=parent))
    except OSError as exc:
        raise OutputError(f"cannot create output directory {target}: {reason(exc)}") from None
    try:
        yield tmp
        try:
            target.mkdir(exist_ok=True)
        except OSError as exc:
            raise OutputError(f"cannot create output directory {target}: {reason(exc)}") from None
        _merge(tmp, target)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _merge(tmp: Path, target: Path) -> None:
    """Move every item of ``tmp`` into ``target``: all staged beside their destinations first,
    then all renamed, so a failure while staging (a full disk) changes nothing in ``target``."""
    staged: list[tuple[Path, Path]] = []
    try:
        for item in sorted(tmp.iterdir()):
            dest = target / item.name
            staged.append((stage_beside(item, dest), dest))
    except BaseException as exc:
        for s, _ in staged:
            discard_staged(s)
        if isinstance(exc, OSError):
            raise OutputError(f"cannot write into {target}: {reason(exc)}; nothing was changed there") from None
        raise
    for k, (s, dest) in enumerate(staged):
        try:
            commit_staged(s, dest)
        except OSError as exc:
            for rest, _ in staged[k:]:
                discard_staged(rest)
            raise OutputError(f"cannot write {dest}: {reason(exc)}") from None


def _nearest_existing(path: Path) -> Path:
    p = path
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def _probe(directory: Path) -> None:
    """Create and remove a temporary directory in ``directory`` (what writing there needs)."""
    os.rmdir(tempfile.mkdtemp(prefix=".uavloc-probe-", dir=directory))


def check_output_dir(path: str | Path, option: str) -> Path:
    """Refuse, before any work is done, an output directory that cannot be written: an existing
    file, a path under a file, a directory (or the nearest existing one above it) where nothing
    can be created. One sentence naming ``option``."""
    if str(path).strip() == "":  # an unset shell variable: not "the current directory"
        raise OutputError(f"{option} needs a directory name, got an empty one (for the current directory give .)")
    target = Path(path)
    if target.exists() and not target.is_dir():
        raise OutputError(f"{option} {path} is a file, not a directory; give a directory to write into")
    where = target if target.is_dir() else _nearest_existing(target)
    if not where.is_dir():
        raise OutputError(f"{option} {path}: {where} is a file, not a directory")
    try:
        _probe(where)
    except OSError as exc:
        raise OutputError(f"{option} {path}: cannot write in {where} ({reason(exc)})") from None
    return target


def check_output_file(path: str | Path, option: str) -> Path:
    """Refuse, before any work is done, an output file that cannot be written: an existing
    directory, a file in a directory that does not exist or where nothing can be created (one
    sentence naming ``option``)."""
    p = Path(path)
    if str(path).strip() == "":
        raise OutputError(f"{option} needs a file name, got an empty one")
    if p.is_dir():
        raise OutputError(f"{option} {path} is a directory; give a file name, e.g. {p / ('out' + (p.suffix or '.json'))}")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        if parent.exists():
            raise OutputError(f"{option} {path}: {parent} is a file, not a directory")
        raise OutputError(f"{option} {path}: the directory {parent} does not exist; create it first")
    try:
        _probe(parent)
    except OSError as exc:
        raise OutputError(f"{option} {path}: cannot write in {parent} ({reason(exc)})") from None
    return p


def check_not_input(path: str | Path, option: str, inputs: dict[str, str | Path | None]) -> None:
    """Refuse an output ``path`` that is one of the command's input files (``inputs``: what each
    is, e.g. {"the mission file": "m.plan"}): writing it would destroy what is being read."""
    p = Path(path)
    for what, inp in inputs.items():
        if inp is not None and p.exists() and Path(inp).exists() and os.path.samefile(p, inp):
            raise OutputError(f"{option} {path} is {what}; writing there would destroy it, give another name")
