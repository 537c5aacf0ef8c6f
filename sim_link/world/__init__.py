"""The simulated world: people (:mod:`.people`), the radio channel (:mod:`.channel`), and
:class:`World`, which joins them for the fake vehicles, the companion emulator and the experiments."""

from .world import World

__all__ = ["World"]
