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


def scenario_path(arg: str | Path) -> Path:
    """``arg`` itself when it names an existing file; else the shipped scenario of that name
    (``paper`` or ``paper.toml``); else ``arg`` (whose loading then says the file is missing)."""
    p = Path(arg)
    if p.exists() or p.parent != Path("."):
        return p
    for name in (p.name, p.name + ".toml"):
        if name.endswith(".toml") and name in names():
            return example_path(name)
    return p
