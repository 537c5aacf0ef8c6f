"""Bluetooth LE beacons of the simulated phones: Apple Find My offline finding (issue 39).

An iPhone (iOS 13 or later, Find My on) that has lost its internet connection -- the cell network
is down after a disaster -- advertises its current public key over BLE so that passing Apple
devices can report it (Heinrich et al., "Who Can Find My Devices?", PETS 2021; the message layout
in furiousMAC/continuity, messages/findmy.md). What the world draws, per phone that sends them
(``emission.findmy_share`` of the phones, chosen once per world):

- an advertising event every ``emission.ble_interval_s`` (2 s, as seemoo-lab/openhaystack's
  firmware advertises), each event late by the advDelay the Bluetooth Core specification adds to
  every event (uniform in 0-10 ms, Vol 6 Part B 4.4.2.2.1), from a random phase;
- each event sends one copy on each of the three advertising channels; a scanner sits on one of
  them at a time, so one copy per event can be heard: the channel it is heard on cycles 37, 38, 39
  with the events (what a one-channel scanner that hops per scan interval sees, on average);
- the address is a random static address (the two top bits set) made of the first bytes of the
  current key, which rotates every ``emission.ble_key_rotation_s`` (15 min: public reverse
  engineering of the protocol, stated as such) from a random offset: one identity lives 15 minutes
  and shares nothing with the next one or with the phone's Wi-Fi bursts.

Every beacon is its own unit of the air-to-ground channel (sim_link/world/airground.py): its
shadowing is correlated with the phone's previous beacons over the distance moved (beacons a
few metres apart nearly share it), its fading its own. The link budget is the BLE one
(uavloc_gcs.radios.ble_view): the phone's BLE power below its Wi-Fi power, the BLE scanner's
sensitivity.

Everything is drawn from per-phone, per-chunk random streams, so what a phone sends does not depend
on when or how often the world is asked.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uavloc_gcs.radios import BLE_ADV_CHANNELS

from .emission import Frames

ADV_DELAY_MAX_S = 0.010  # Bluetooth Core 5.x, Vol 6 Part B 4.4.2.2.1: advDelay in [0, 10 ms]
CHUNK_EVENTS = 1024  # events drawn per (phone, chunk)
_STATIC_RANDOM = np.int64(0b11) << np.int64(46)  # random static address: the two top bits set
_ADDR_BITS = (1 << 46) - 1
# spawn keys under the world's seed (sim_link/world/world.py uses 0..6)
_BEACON_TRAITS, _BEACON_DELAY, _BEACON_KEY = 7, 8, 9


@dataclass(frozen=True)
class BeaconParams:
    interval_s: float = 2.0
    key_rotation_s: float = 900.0

    @staticmethod
    def from_scenario(sc) -> "BeaconParams":
        return BeaconParams(sc.emission.ble_interval_s, sc.emission.ble_key_rotation_s)


class FindMyBeacons:
    """The beacons of the phones that send them (see the module docstring). ``rng_for(*key)``
    gives the world's random stream for a spawn key."""

    def __init__(self, params: BeaconParams, n_phones: int, share: float, rng_for, horizon_s: float):
        self.params = params
        traits = rng_for(_BEACON_TRAITS)
        n = int(n_phones)
        self.sends = traits.uniform(size=n) < float(share)
        self.phase_s = traits.uniform(0.0, params.interval_s, size=n)
        self.key_offset_s = traits.uniform(0.0, params.key_rotation_s, size=n)
        self._rng_for = rng_for
        self._delays: dict[tuple[int, int], np.ndarray] = {}
        self._keys: dict[tuple[int, int], int] = {}
        self.owner: dict[int, int] = {}
        periods = int(np.ceil((horizon_s + params.key_rotation_s) / params.key_rotation_s)) + 1
        for i in np.nonzero(self.sends)[0]:  # every address a phone will use within the horizon
            for j in range(periods):
                self.owner[self._address(int(i), j)] = int(i)

    def __len__(self) -> int:
        return len(self.sends)

    @property
    def senders(self) -> np.ndarray:
        return np.nonzero(self.sends)[0]

    def _address(self, i: int, period: int) -> int:
        key = (i, period)
        a = self._keys.get(key)
        if a is None:
            bits = int(self._rng_for(_BEACON_KEY, i, period).integers(0, _ADDR_BITS, dtype=np.int64, endpoint=True))
            a = self._keys[key] = int(_STATIC_RANDOM | np.int64(bits))
        return a

    def _delay(self, i: int, chunk: int) -> np.ndarray:
        key = (i, chunk)
        d = self._delays.get(key)
        if d is None:
            d = self._delays[key] = self._rng_for(_BEACON_DELAY, i, chunk).uniform(0.0, ADV_DELAY_MAX_S, CHUNK_EVENTS)
        return d

    def frames(self, t_from_s: float, t_to_s: float) -> Frames:
        """Every beacon sent in [t_from_s, t_to_s), one frame per advertising event (the copy the
        scanner's channel gets), in time order (ties by person); ``burst`` -1 (each its own unit)."""
        p = self.params
        parts = []
        for i in self.senders:
            i = int(i)
            k0 = max(int(np.floor((t_from_s - self.phase_s[i] - ADV_DELAY_MAX_S) / p.interval_s)), 0)
            k1 = int(np.ceil((t_to_s - self.phase_s[i]) / p.interval_s)) + 1
            if k1 <= k0:
                continue
            k = np.arange(k0, k1)
            delay = np.concatenate([self._delay(i, c) for c in range(k0 // CHUNK_EVENTS, (k1 - 1) // CHUNK_EVENTS + 1)])
            t = self.phase_s[i] + k * p.interval_s + delay[k - (k0 // CHUNK_EVENTS) * CHUNK_EVENTS]
            keep = (t >= t_from_s) & (t < t_to_s)
            k, t = k[keep], t[keep]
            if len(k) == 0:
                continue
            period = np.floor((t + self.key_offset_s[i]) / p.key_rotation_s).astype(int)
            addr = np.array([self._address(i, int(j)) for j in period], dtype=np.int64)
            chan = np.asarray(BLE_ADV_CHANNELS)[k % 3]
            n = len(k)
            parts.append(Frames(np.full(n, i), t, chan.astype(int), addr, np.full(n, -1), np.full(n, -1)))
        if not parts:
            z = np.zeros(0, dtype=int)
            return Frames(z, np.zeros(0), z, np.zeros(0, dtype=np.int64), z, z)
        out = Frames.concat(parts)
        return out.take(np.lexsort((out.person, out.t_s)))


def fingerprint_of(address: np.ndarray) -> np.ndarray:
    """A beacon's content fingerprint: the key bytes its payload carries beyond the address, which
    only this identity sends (modelled as a nonzero 32-bit hash of the address): never equal to a
    Wi-Fi model's fingerprint or another identity's, so the identity module never links them."""
    a = np.asarray(address, dtype=np.uint64)
    h = (a * np.uint64(0x9E3779B97F4A7C15)) >> np.uint64(32)
    h = (h & np.uint64(0xFFFFFFFF)).astype(np.int64)
    return np.where(h == 0, 1, h)
