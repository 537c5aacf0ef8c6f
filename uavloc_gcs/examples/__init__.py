"""The example scenarios and inputs shipped with uavloc, so an installed ``uavloc`` runs ``demo``,
``experiment`` and ``bench`` from any directory. The repository's top-level ``examples/`` holds
the same files for the README (tests/test_packaging.py keeps them identical).

``example_path("paper.toml")`` is the file on disk; :func:`scenario_path` also accepts a bare
name (``paper``, ``small``) wherever a scenario file is asked for.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path


def example_path(name: str) -> Path:
    """The shipped example ``name`` (a wheel installs them as plain files)."""
    return Path(str(files(__name__) / name))


def names() -> list[str]:
    return sorted(p.name for p in files(__name__).iterdir() if not p.name.startswith(("_", ".")))


def shipped_path(arg: str | Path, suffix: str) -> Path:
    """``arg`` itself when it names an existing file; else the shipped file of that name with or
    without ``suffix`` (``paper`` or ``paper.toml``, ``route_paper.json``); else ``arg`` (whose
    reading then says the file is missing). The one resolver every command uses."""
    p = Path(arg)
    if p.exists() or p.parent != Path("."):
        return p
    for name in (p.name, p.name + suffix):
        if name.endswith(suffix) and name in names():
            return example_path(name)
    return p


def scenario_path(arg: str | Path) -> Path:
    """A scenario file or a shipped scenario's name (:func:`shipped_path` with ``.toml``)."""
    return shipped_path(arg, ".toml")


def scenario_names() -> list[str]:
    return [n[:-len(".toml")] for n in names() if n.endswith(".toml")]
