"""RSSI observations: per-slot aggregates of the samples a vehicle heard from one emitter.

Within one time slot the UAV-phone distance is constant, so the slot's mean RSSI (in dBm) and its
sample count are a sufficient statistic for the log-normal ranging model. Everything between
the channel and the estimator (the simulator, the MAVLink dialect, the CSV/.tlog readers, the
store) passes these around in columnar form as a :class:`SlotBatch`.

Frames: ``xyz_m`` is the vehicle position in the scenario's local ENU frame (east, north, up),
with z the height above the launch point; times are seconds on one clock shared by all vehicles.

What a real sensor knows of a phone is not a person: ``address`` is the 802.11 source address the
slot's frames came from (48 bits as an integer; a phone may use a new random one for every burst),
``fingerprint`` a hash of the frames' content (information elements; phones of one model and OS
share it, 0 = unknown), ``channel`` the 802.11 channel heard on (0 = unknown) and ``radio`` the
radio that heard it (0 Wi-Fi, 1 Bluetooth LE, as :data:`uavloc_gcs.sense.frames.RADIO_NAMES`: each
radio has its own channel parameters and address rotation; old logs read as Wi-Fi). ``emitter_id`` is
the identity the estimator works on: the address as it arrives from a sensor, and the linked
person once :mod:`uavloc_gcs.estimation.identity` has grouped the addresses into people. Where a
source has no address (old logs, the paper's world), ``address`` defaults to ``emitter_id``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SlotBatch:
    """N slots, column-wise. ``vehicle`` is a small integer (e.g. the MAVLink system id)."""

    t_s: np.ndarray  # (N,) slot start time [s]
    vehicle: np.ndarray  # (N,) int
    xyz_m: np.ndarray  # (N, 3) vehicle position, local ENU [m]
    emitter_id: np.ndarray  # (N,) int64
    rssi_dbm: np.ndarray  # (N,) mean of the slot's samples [dBm]
    n_samples: np.ndarray  # (N,) int, >= 1
    address: np.ndarray | None = None  # (N,) int64 802.11 source address; None: = emitter_id
    fingerprint: np.ndarray | None = None  # (N,) int64 content fingerprint; None: 0 (unknown)
    channel: np.ndarray | None = None  # (N,) int 802.11 channel; None: 0 (unknown)
    radio: np.ndarray | None = None  # (N,) int 0 Wi-Fi, 1 BLE; None: 0 (Wi-Fi)

    def __post_init__(self) -> None:
        n = len(self.t_s)
        if self.address is None:
            object.__setattr__(self, "address", np.asarray(self.emitter_id, dtype=np.int64).copy())
        if self.fingerprint is None:
            object.__setattr__(self, "fingerprint", np.zeros(n, dtype=np.int64))
        if self.channel is None:
            object.__setattr__(self, "channel", np.zeros(n, dtype=int))
        if self.radio is None:
            object.__setattr__(self, "radio", np.zeros(n, dtype=int))
        for name in ("vehicle", "emitter_id", "rssi_dbm", "n_samples", "address", "fingerprint", "channel", "radio"):
            if len(getattr(self, name)) != n:
                raise ValueError(f"SlotBatch.{name} has {len(getattr(self, name))} rows, t_s has {n}")
        if np.shape(self.xyz_m) != (n, 3):
            raise ValueError(f"SlotBatch.xyz_m must be ({n}, 3), got {np.shape(self.xyz_m)}")

    def __len__(self) -> int:
        return len(self.t_s)

    @staticmethod
    def empty() -> "SlotBatch":
        return SlotBatch(
            np.zeros(0), np.zeros(0, dtype=int), np.zeros((0, 3)), np.zeros(0, dtype=np.int64),
            np.zeros(0), np.zeros(0, dtype=int),
        )

    @staticmethod
    def from_columns(t_s, vehicle, xyz_m, emitter_id, rssi_dbm, n_samples, *, address=None, fingerprint=None,
                     channel=None, radio=None) -> "SlotBatch":
        return SlotBatch(
            np.asarray(t_s, dtype=float).reshape(-1),
            np.asarray(vehicle, dtype=int).reshape(-1),
            np.asarray(xyz_m, dtype=float).reshape(-1, 3),
            np.asarray(emitter_id, dtype=np.int64).reshape(-1),
            np.asarray(rssi_dbm, dtype=float).reshape(-1),
            np.asarray(n_samples, dtype=int).reshape(-1),
            None if address is None else np.asarray(address, dtype=np.int64).reshape(-1),
            None if fingerprint is None else np.asarray(fingerprint, dtype=np.int64).reshape(-1),
            None if channel is None else np.asarray(channel, dtype=int).reshape(-1),
            None if radio is None else np.asarray(radio, dtype=int).reshape(-1),
        )

    @staticmethod
    def concat(batches: "list[SlotBatch]") -> "SlotBatch":
        batches = [b for b in batches if len(b)]
        if not batches:
            return SlotBatch.empty()
        return SlotBatch(
            np.concatenate([b.t_s for b in batches]),
            np.concatenate([b.vehicle for b in batches]),
            np.concatenate([b.xyz_m for b in batches]),
            np.concatenate([b.emitter_id for b in batches]),
            np.concatenate([b.rssi_dbm for b in batches]),
            np.concatenate([b.n_samples for b in batches]),
            np.concatenate([b.address for b in batches]),
            np.concatenate([b.fingerprint for b in batches]),
            np.concatenate([b.channel for b in batches]),
            np.concatenate([b.radio for b in batches]),
        )

    def take(self, index) -> "SlotBatch":
        """Rows selected by a boolean mask or integer index array."""
        return SlotBatch(
            self.t_s[index], self.vehicle[index], self.xyz_m[index], self.emitter_id[index],
            self.rssi_dbm[index], self.n_samples[index], self.address[index], self.fingerprint[index],
            self.channel[index], self.radio[index],
        )

    def with_emitter_ids(self, emitter_id) -> "SlotBatch":
        """The same slots under other emitter ids (e.g. the linked people), addresses kept."""
        return SlotBatch(
            self.t_s, self.vehicle, self.xyz_m, np.asarray(emitter_id, dtype=np.int64).reshape(-1), self.rssi_dbm,
            self.n_samples, self.address, self.fingerprint, self.channel, self.radio,
        )

    def for_emitter(self, emitter_id: int) -> "SlotBatch":
        return self.take(self.emitter_id == emitter_id)

    def emitters(self) -> np.ndarray:
        return np.unique(self.emitter_id)

    def sorted_by_time(self) -> "SlotBatch":
        return self.take(np.argsort(self.t_s, kind="stable"))
