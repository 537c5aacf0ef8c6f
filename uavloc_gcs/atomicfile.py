"""Write a file so that a reader never sees half of it: a temporary sibling, then a rename."""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path
from typing import IO, Iterator

FILE_MODE = 0o644  # mkstemp creates 0600; mission files, results and pictures are meant to be shared


@contextlib.contextmanager
def atomic_open(path: str | Path, mode: str = "w", *, suffix: str = "") -> Iterator[IO]:
    """Open a temporary file next to ``path`` for writing (``mode`` "w" text or "wb" binary).

    When the block ends normally the file is made 0644 and renamed over ``path``; on any exception
    it is removed and ``path`` is left as it was.
    """
    p = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=suffix, dir=p.parent if str(p.parent) else ".")
    try:
        if "b" in mode:
            fh = os.fdopen(fd, mode)
        else:
            fh = os.fdopen(fd, mode, encoding="utf-8", newline="")
        with fh:
            yield fh
        os.chmod(tmp, FILE_MODE)
        os.replace(tmp, p)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8, newlines as given) to ``path`` atomically."""
    with atomic_open(path, "w") as fh:
        fh.write(text)
    return Path(path)
