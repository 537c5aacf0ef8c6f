"""Link fault injection between the fake vehicles and their ground stations.

:class:`FaultConfig` describes one direction of a link (loss, duplication, reordering, latency);
:class:`LinkFaults` pairs the two directions. :class:`FaultyPipe` applies a config to datagrams:
for each one it returns the (delay, datagram) deliveries -- none when lost, two when duplicated, a
later one when reordered. Random draws come from a ``numpy.random.Generator`` the caller seeds, so
a run is repeatable. Delays are wall-clock seconds (the link is real, only the flight is sped up).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class FaultConfig:
    """One direction of a link. Probabilities per datagram; times in wall seconds."""

    loss: float = 0.0
    duplicate: float = 0.0
    reorder: float = 0.0
    latency_s: float = 0.0
    jitter_s: float = 0.0
    reorder_delay_s: float = 0.03  # a reordered datagram is held back this much extra

    def __post_init__(self) -> None:
        for name in ("loss", "duplicate", "reorder"):
            p = getattr(self, name)
            if not 0.0 <= p <= 1.0:
                raise ValueError(f"FaultConfig.{name} must be a probability in [0, 1], got {p}")
        for name in ("latency_s", "jitter_s", "reorder_delay_s"):
            if getattr(self, name) < 0:
                raise ValueError(f"FaultConfig.{name} must be >= 0, got {getattr(self, name)}")

    @property
    def is_clean(self) -> bool:
        return self.loss == self.duplicate == self.reorder == self.latency_s == self.jitter_s == 0.0


@dataclass(frozen=True)
class LinkFaults:
    """Faults per direction: ``to_vehicle`` (uplink) and ``to_gcs`` (downlink)."""

    to_vehicle: FaultConfig = FaultConfig()
    to_gcs: FaultConfig = FaultConfig()

    @staticmethod
    def of(faults: "FaultConfig | LinkFaults | None") -> "LinkFaults":
        """A FaultConfig applies to both directions; None means a clean link."""
        if faults is None:
            return LinkFaults()
        if isinstance(faults, FaultConfig):
            return LinkFaults(faults, faults)
        return faults


@dataclass
class FaultCounters:
    sent: int = 0
    lost: int = 0
    duplicated: int = 0
    reordered: int = 0
    blocked: int = 0  # dropped while the link was down


class FaultyPipe:
    """Applies one direction's faults; :meth:`deliveries` says when each copy should arrive."""

    def __init__(self, cfg: FaultConfig, rng: np.random.Generator):
        self.cfg = cfg
        self.rng = rng
        self.counters = FaultCounters()
        self.down_until_wall_s = -np.inf

    def deliveries(self, now_wall_s: float) -> list[float]:
        """Delays [s] after which copies of one datagram arrive ([] = lost)."""
        c = self.cfg
        self.counters.sent += 1
        if now_wall_s < self.down_until_wall_s:
            self.counters.blocked += 1
            return []
        if c.is_clean:
            return [0.0]
        if c.loss and self.rng.random() < c.loss:
            self.counters.lost += 1
            return []
        copies = 2 if c.duplicate and self.rng.random() < c.duplicate else 1
        if copies == 2:
            self.counters.duplicated += 1
        out = []
        for _ in range(copies):
            delay = c.latency_s + (self.rng.uniform(0.0, c.jitter_s) if c.jitter_s else 0.0)
            if c.reorder and self.rng.random() < c.reorder:
                delay += c.reorder_delay_s
                self.counters.reordered += 1
            out.append(delay)
        return out
