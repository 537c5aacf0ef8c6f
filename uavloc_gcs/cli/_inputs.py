"""Checking a command's own inputs: numeric flags, scenario overrides from flags, shipped files.

Every check ends in one sentence naming the flag (argparse prints ``argument --x: ...`` and exits
2), never a traceback and never the scenario file for a value the operator typed on the command
line.
"""

from __future__ import annotations

import argparse
import math
from typing import Any, Callable

from ..errors import ConfigError


def number(kind: type = float, *, min: float | None = None, max: float | None = None,
           above: float | None = None, unit: str = "") -> Callable[[str], Any]:
    """An argparse ``type=`` that accepts a finite ``kind`` (int or float) within the bounds:
    ``min``/``max`` inclusive, ``above`` exclusive. The message says what is allowed."""
    u = f" {unit}" if unit else ""

    def parse(text: str):
        try:
            value = kind(text)
        except (TypeError, ValueError):
            raise argparse.ArgumentTypeError(
                f"{text!r} is not {'a whole number' if kind is int else 'a number'}") from None
        if kind is float and not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"must be a finite number, got {text}")
        if above is not None and not value > above:
            raise argparse.ArgumentTypeError(f"must be more than {above:g}{u}, got {text}")
        if min is not None and value < min:
            raise argparse.ArgumentTypeError(f"must be at least {min:g}{u}, got {text}")
        if max is not None and value > max:
            raise argparse.ArgumentTypeError(f"must be at most {max:g}{u}, got {text}")
        return value

    parse.__name__ = "whole number" if kind is int else "number"
    return parse


def port(text: str) -> int:
    return number(int, min=0, max=65535)(text)


def override(sc, flag: str, **sections: Any):
    """``sc.replace(**sections)``, but a value the scenario refuses is blamed on ``flag`` (the
    operator typed it), not on the scenario file and its key."""
    try:
        return sc.replace(**sections)
    except ConfigError as err:
        raise ConfigError(f"{flag}: {getattr(err, 'message', str(err))}") from None
