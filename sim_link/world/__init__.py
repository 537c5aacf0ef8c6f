"""The simulated world: people (:mod:`.people`), how their phones transmit (:mod:`.emission`), the
radio channel and receiver (:mod:`.channel`), and :class:`World`, which joins them for the fake
vehicles, the companion emulator and the experiments. docs/science/world.md describes both worlds
(the paper's continuous emitters, the field's probe bursts) and their calibration."""

from .emission import Frames, ProbeBursts
from .world import World

__all__ = ["Frames", "ProbeBursts", "World"]
