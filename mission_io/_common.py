"""Small helpers shared by the mission file formats."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from uavloc_gcs.atomicfile import atomic_write_text
from uavloc_gcs.errors import FileFormatError



def read_text(path: str | Path) -> str:
    """The file's text, or FileFormatError naming the file."""
    p = Path(path)
    try:
        return p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise FileFormatError("file not found", path=str(p)) from None
    except IsADirectoryError:
        raise FileFormatError("is a directory, not a file", path=str(p)) from None
    except UnicodeDecodeError:
        raise FileFormatError("is not UTF-8 text", path=str(p)) from None
    except OSError as exc:
        raise FileFormatError(f"cannot read file ({exc.strerror})", path=str(p)) from None


def write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` atomically (temporary file + rename), so a reader never sees half a file."""
    return atomic_write_text(path, text)


def fmt_float(value: float) -> str:
    """Shortest exact decimal for ``value`` without an exponent ('nan' for NaN).

    Full precision (the float reads back bit-identical), unlike the ``%f`` of pymavlink's
    ``mavwp`` which keeps 6 decimals (~0.1 m).
    """
    if math.isnan(value):
        return "nan"
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    if value == 0.0:
        return "0"
    return np.format_float_positional(float(value), unique=True, trim="-")


def json_number(value: float):
    """A float as JSON: NaN -> None (null), integral values as int (as QGC writes them)."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return None
    if isinstance(value, bool):
        return value
    f = float(value)
    if f.is_integer() and abs(f) < 2**53:
        return int(f)
    return f
