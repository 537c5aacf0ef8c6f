"""The simulated world: people walking in the search area and the radio channel to the vehicles.

One :class:`World` drives both the fake MAVLink vehicles and the in-process experiment runner, so
the two never disagree (SPEC §6). Time ``t_s`` is seconds since mission start; positions are in
the scenario's local ENU frame (metres, launch point at the origin, people at z = 0, vehicle z =
height above the launch point).

Determinism: everything follows from ``seed``. The people, their ids and transmit offsets come
from their own random streams; each vehicle has its own channel stream and shadowing memory, so
what one vehicle hears depends only on the sequence of its own ``hear``/``hear_track`` calls, not
on how the calls of several concurrently simulated vehicles interleave. Hearing a track slot by
slot gives the same numbers as hearing it in one ``hear_track`` call.

Example::

    world = World(load_scenario("examples/paper.toml"), seed=3)
    t = np.arange(0, 20, sc.channel.slot_s)
    track = np.column_stack([25 * t, np.full_like(t, 80), np.full_like(t, 100)])
    slots = world.hear_track(1, t, track)      # SlotBatch, one row per (slot, phone in range)
"""

from __future__ import annotations

import numpy as np

from uavloc_gcs.observations import SlotBatch
from uavloc_gcs.scenario import Scenario

from .channel import ChannelParams, ShadowingState, draw_shadowing_db
from .people import Tracks, constant_velocity_tracks, make_tracks

# spawn keys of the independent random streams derived from the seed
_PEOPLE, _IDS, _TX, _VEHICLE = 0, 1, 2, 3


class World:
    """Simulated people and channel for one scenario (defaults from ``scenario.simulation``)."""

    def __init__(
        self,
        scenario: Scenario,
        *,
        seed: int | None = None,
        people: int | None = None,
        motion: str | None = None,
        tracks: Tracks | None = None,
        horizon_s: float = 4 * 3600.0,
    ):
        sim = scenario.simulation
        self.scenario = scenario
        self.seed = int(sim.seed if seed is None else seed)
        self.motion = sim.motion if motion is None else motion
        self.channel = ChannelParams.from_scenario(scenario)
        self.comm_range_m = scenario.fleet.comm_range_m
        if tracks is None:
            count = sim.people if people is None else int(people)
            tracks = make_tracks(scenario.area_xy_m(), count, self.motion, scenario.people.max_speed_m_s,
                                 self._rng(_PEOPLE), horizon_s=horizon_s)
        self.tracks = tracks
        n = len(tracks)
        self.emitter_ids = _unique_ids(n, self._rng(_IDS))
        spread = sim.tx_power_spread_db
        self.tx_offset_db = spread * self._rng(_TX).standard_normal(n) if spread > 0 else np.zeros(n)
        self._vehicles: dict[int, ShadowingState] = {}

    @classmethod
    def with_people(cls, scenario: Scenario, start_xy_m, velocity_m_s=None, *, seed: int | None = None) -> "World":
        """A world with explicit people: start positions (S, 2) [m] and constant velocities (S, 2)
        [m/s] (zero if omitted), each stopping at the area boundary. For tests and benchmarks."""
        start = np.asarray(start_xy_m, dtype=float).reshape(-1, 2)
        vel = np.zeros_like(start) if velocity_m_s is None else np.asarray(velocity_m_s, float).reshape(-1, 2)
        tracks = constant_velocity_tracks(scenario.area_xy_m(), start, vel)
        return cls(scenario, seed=seed, tracks=tracks, motion="constant_velocity")

    # -- truth ----------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.tracks)

    def positions(self, t_s) -> np.ndarray:
        """True positions (S, 2) at time t_s [m]; (T, S, 2) for an array of times."""
        return self.tracks.positions(t_s)

    def velocities(self, t_s) -> np.ndarray:
        """True velocities (S, 2) at time t_s [m/s]; (T, S, 2) for an array of times."""
        return self.tracks.velocities(t_s)

    def index_of(self, emitter_id: int) -> int:
        """Row of an emitter id in ``positions``/``emitter_ids``."""
        hit = np.nonzero(self.emitter_ids == emitter_id)[0]
        if hit.size == 0:
            raise KeyError(f"no person with emitter id {emitter_id}")
        return int(hit[0])

    # -- hearing --------------------------------------------------------------------------
    def hear(self, vehicle: int, t_s: float, xyz_m) -> SlotBatch:
        """One slot heard by ``vehicle`` at local position ``xyz_m`` at time ``t_s``: one row per
        person within the 3-D communication range; rssi = mean of the slot's dBm samples."""
        return self.hear_track(vehicle, np.array([float(t_s)]), np.asarray(xyz_m, float).reshape(1, 3))

    def hear_track(self, vehicle: int, t_s, xyz_m) -> SlotBatch:
        """Slots heard along a track: times (N,) nondecreasing, positions (N, 3) [m], one slot each.

        Calls for one vehicle must come in nondecreasing time (the shadowing has memory).
        """
        t = np.asarray(t_s, dtype=float).reshape(-1)
        xyz = np.asarray(xyz_m, dtype=float).reshape(-1, 3)
        if len(t) != len(xyz):
            raise ValueError(f"hear_track: {len(t)} times but {len(xyz)} positions")
        if len(t) == 0:
            return SlotBatch.empty()
        if not np.all(np.isfinite(t)) or not np.all(np.isfinite(xyz)):
            raise ValueError("hear_track: times and positions must be finite")
        state = self._state(int(vehicle))
        if np.any(np.diff(t) < 0) or t[0] < state.last_t_s:
            raise ValueError(f"vehicle {vehicle}: slot times must not go backwards "
                             f"(last {state.last_t_s:.3f} s, got {t.min():.3f} s)")
        people = self.tracks.positions(t)  # (N, S, 2)
        s = len(self)
        if s == 0:
            state.last_t_s = float(t[-1])
            return SlotBatch.empty()
        dxy = people - xyz[:, None, :2]
        d3 = np.sqrt(np.sum(dxy**2, axis=2) + xyz[:, 2:3] ** 2)  # (N, S)

        prev_xyz = xyz[0] if state.last_xyz_m is None else state.last_xyz_m
        prev_people = people[0] if state.last_people_xy_m is None else state.last_people_xy_m
        veh_step = np.linalg.norm(np.diff(np.vstack([prev_xyz, xyz]), axis=0), axis=1)  # (N,)
        ppl_step = np.linalg.norm(np.diff(np.concatenate([prev_people[None], people]), axis=0), axis=2)
        moved = veh_step[:, None] + ppl_step  # (N, S)

        psi = draw_shadowing_db(self.channel, state, moved)  # (N, K, S)
        rssi = self.channel.median_rssi_dbm(d3) + self.tx_offset_db + psi.mean(axis=1)
        state.last_t_s, state.last_xyz_m, state.last_people_xy_m = float(t[-1]), xyz[-1].copy(), people[-1].copy()

        slot, person = np.nonzero(d3 <= self.comm_range_m)  # slot-major, then person order
        k = self.channel.samples_per_slot
        return SlotBatch.from_columns(
            t[slot], np.full(len(slot), int(vehicle)), xyz[slot], self.emitter_ids[person].astype(np.int64),
            rssi[slot, person], np.full(len(slot), k),
        )

    def _state(self, vehicle: int) -> ShadowingState:
        st = self._vehicles.get(vehicle)
        if st is None:
            st = ShadowingState(self._rng(_VEHICLE, vehicle))
            self._vehicles[vehicle] = st
        return st

    def _rng(self, *key: int) -> np.random.Generator:
        return np.random.default_rng(np.random.SeedSequence(self.seed, spawn_key=key))


def _unique_ids(n: int, rng: np.random.Generator) -> np.ndarray:
    """n distinct random nonzero uint32 ids."""
    ids = np.zeros(0, dtype=np.uint32)
    while len(ids) < n:
        more = rng.integers(1, 2**32, size=n - len(ids), dtype=np.uint64).astype(np.uint32)
        ids = np.concatenate([ids, more])
        _, first = np.unique(ids, return_index=True)
        ids = ids[np.sort(first)]
    return ids
