"""Output helpers for commands: all-or-nothing output directories and files."""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from pathlib import Path
from typing import Iterator

from ..errors import ConfigError


@contextlib.contextmanager
def atomic_output_dir(path: str | Path) -> Iterator[Path]:
    """Yield a temporary directory that replaces/merges into ``path`` only if the block succeeds.

    Files are written into a fresh sibling directory; on success each file is moved into ``path``
    (created if missing); on any exception the temporary directory is removed and ``path`` is left
    exactly as it was (not created if it did not exist).
    """
    target = Path(path)
    if target.exists() and not target.is_dir():
        raise ConfigError(f"output path {target} exists and is not a directory")
    parent = target.parent if str(target.parent) else Path(".")
    try:
        parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.partial-", dir=parent))
    except OSError as exc:
        raise ConfigError(f"cannot create output directory {target}: {exc.strerror}") from None
    try:
        yield tmp
        target.mkdir(exist_ok=True)
        for item in sorted(tmp.iterdir()):
            dest = target / item.name
            if dest.is_dir() and not item.is_dir():
                shutil.rmtree(dest)
            os.replace(item, dest) if not item.is_dir() else _move_dir(item, dest)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _move_dir(src: Path, dest: Path) -> None:
    if dest.exists():
        shutil.rmtree(dest)
    os.replace(src, dest)


def check_output_file(path: str | Path, option: str) -> Path:
    """Refuse, before any work is done, an output file that cannot be written: an existing
    directory, or a file in a directory that does not exist (one sentence naming ``option``)."""
    p = Path(path)
    if p.is_dir():
        raise ConfigError(f"{option} {path} is a directory; give a file name, e.g. {p / ('out' + (p.suffix or '.json'))}")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        what = "is not a directory" if parent.exists() else "does not exist"
        raise ConfigError(f"{option} {path}: the directory {parent} {what}; create it first")
    return p
