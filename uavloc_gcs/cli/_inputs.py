"""Checking a command's own inputs: numeric flags, scenario overrides from flags, shipped files.

Every check ends in one sentence naming the flag (argparse prints ``argument --x: ...`` and exits
2), never a traceback and never the scenario file for a value the operator typed on the command
line.
"""

from __future__ import annotations

import argparse
import contextlib
import math
from typing import Any, Callable, Iterator

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


def number_list(kind: type = int, *, min: float | None = None, max: float | None = None,
                above: float | None = None, unit: str = "") -> Callable[[str], tuple]:
    """An argparse ``type=`` for a comma-separated list of numbers, each checked as :func:`number`
    checks one; the message names the entry that is wrong."""
    one = number(kind, min=min, max=max, above=above, unit=unit)

    def parse(text: str) -> tuple:
        entries = [t.strip() for t in text.split(",")]
        if not any(entries):
            raise argparse.ArgumentTypeError(f"expected comma-separated {'whole ' if kind is int else ''}numbers, "
                                             f"got {text!r}")
        values = []
        for t in entries:
            if not t:
                continue
            try:
                values.append(one(t))
            except argparse.ArgumentTypeError as err:
                raise argparse.ArgumentTypeError(f"entry {t!r}: {err}") from None
        return tuple(values)

    parse.__name__ = "list of numbers"
    return parse


def choice_list(allowed: tuple[str, ...] | list[str], *, extra: tuple[str, ...] = ()) -> Callable[[str], tuple]:
    """An argparse ``type=`` for a comma-separated subset of ``allowed`` (or one of ``extra``,
    alone, such as "all"); the message names the unknown entry and lists the choices."""

    def parse(text: str) -> tuple:
        entries = tuple(t.strip() for t in text.split(",") if t.strip())
        if len(entries) == 1 and entries[0] in extra:
            return entries
        if not entries:
            raise argparse.ArgumentTypeError(f"expected a comma-separated subset of {', '.join(allowed)}, got {text!r}")
        for e in entries:
            if e not in allowed:
                raise argparse.ArgumentTypeError(
                    f"unknown {e!r}; choose from {', '.join(list(allowed) + list(extra))}")
        return entries

    parse.__name__ = "list of names"
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


@contextlib.contextmanager
def blaming(flag: str, key: str) -> Iterator[None]:
    """Inside the block, a ConfigError about scenario ``key`` is reported against ``flag``, which
    set it."""
    try:
        yield
    except ConfigError as err:
        if err.key != key:
            raise
        raise ConfigError(f"{flag}: {getattr(err, 'message', str(err))}") from None


def _has_section(sc, section: str) -> bool:
    """Whether the scenario's file spells out ``[section]`` (True when it is not a file)."""
    import tomllib
    from pathlib import Path

    path = Path(sc.source)
    if sc.source == "<string>" or not path.is_file():
        return True
    try:
        return section in tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return True


def _default_fleet(sc) -> str:
    f = sc.fleet
    label = "ArduPilot" if f.autopilot == "ardupilot" else "PX4"
    return (f"{f.vehicles} {label} vehicles at {f.altitude_m:g} m and {f.speed_m_s:g} m/s, "
            f"{f.energy_budget_j / 1000:g} kJ each")


def fleet_note(sc) -> str | None:
    """The sentence to print when the scenario has no ``[fleet]`` section (what is planned then
    is for the default fleet, which may not be the operator's); None when it has one."""
    if _has_section(sc, "fleet"):
        return None
    return (f"Note: {sc.source} has no [fleet] section, so the default fleet is assumed: {_default_fleet(sc)}; "
            "add a [fleet] section with yours.")


def require_fleet(sc) -> None:
    """Refuse a scenario without ``[fleet]`` where real vehicles are flown."""
    if not _has_section(sc, "fleet"):
        raise ConfigError(f"missing: the daemon flies real vehicles and does not assume the default fleet "
                          f"({_default_fleet(sc)}); add a [fleet] section", source=sc.source, key="fleet")


def existing_files(out) -> set:
    """The files in directory ``out`` now (to tell later which ones a failed run created)."""
    from pathlib import Path

    out = Path(out)
    return {p.name for p in out.iterdir()} if out.is_dir() else set()


def discard_empty_leftovers(out, before: set) -> None:
    """After a run that failed: remove what it created in ``out`` that holds nothing -- empty
    files (a .tlog no vehicle ever wrote to) and a store with no rows beyond its header -- so a
    failure leaves nothing behind. A store or log with data stays (a later run resumes from it)."""
    import sqlite3
    from pathlib import Path

    out = Path(out)
    if not out.is_dir():
        return
    for p in sorted(out.iterdir()):
        if p.name in before or not p.is_file():
            continue
        if p.suffix == ".sqlite" and _store_is_empty(p, sqlite3):
            for q in (p, p.with_name(p.name + "-wal"), p.with_name(p.name + "-shm"), p.with_name(p.name + "-journal")):
                with contextlib.suppress(OSError):
                    q.unlink()
        elif p.exists() and p.stat().st_size == 0:
            with contextlib.suppress(OSError):
                p.unlink()


def _store_is_empty(path, sqlite3) -> bool:
    try:
        con = sqlite3.connect(f"file:{path}?mode=ro", uri=True, timeout=1.0)
        try:
            tables = [t for (t,) in con.execute("SELECT name FROM sqlite_master WHERE type = 'table'")]
            return all(con.execute(f'SELECT 1 FROM "{t}" LIMIT 1').fetchone() is None for t in tables if t != "meta")
        finally:
            con.close()
    except sqlite3.Error:
        return False
