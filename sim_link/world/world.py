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

Two emission models (``scenario.emission.model``, docs/science/world.md): ``continuous`` (the paper:
every phone in every slot, under its emitter id, heard within ``fleet.comm_range_m``) and
``probe-bursts`` (the field: :mod:`.emission`'s bursts under changing addresses). With
``channel.receiver_sensitivity_dbm`` set, a frame is heard when its RSSI exceeds it (no range gate),
on the channels of ``channel.listen_channels`` (one radio each). ``channel.environment`` makes it
the air-to-ground channel of :mod:`uavloc_gcs.a2g` (line of sight by elevation, per burst; drawn by
:mod:`.airground`). ``person_of`` maps what was heard back to people (truth for tests and
benchmarks; a sensor has only the address).

Example::

    world = World(load_scenario("examples/paper.toml"), seed=3)
    t = np.arange(0, 20, sc.channel.slot_s)
    track = np.column_stack([25 * t, np.full_like(t, 80), np.full_like(t, 100)])
    slots = world.hear_track(1, t, track)      # SlotBatch, one row per (slot, phone in range)
"""

from __future__ import annotations

import numpy as np

from uavloc_gcs.a2g import LOS, A2GChannel
from uavloc_gcs.observations import SlotBatch
from uavloc_gcs.radios import RADIO_BLE
from uavloc_gcs.scenario import Scenario

from .airground import PathMemory, draw_rssi_dbm
from .beacons import BeaconParams, FindMyBeacons, fingerprint_of
from .channel import ChannelParams, ShadowingState, draw_frame_shadowing_db, draw_shadowing_db
from .emission import BurstParams, Frames, ProbeBursts
from .people import Tracks, constant_velocity_tracks, make_tracks

# spawn keys of the independent random streams derived from the seed
_PEOPLE, _IDS, _TX, _VEHICLE, _TRAITS, _BURSTS, _ELICIT = 0, 1, 2, 3, 4, 5, 6
_BLE = 10  # (7..9: sim_link/world/beacons.py)
_JOIN = 11  # which phones join the mimicked network (emission.mimicry_share)
# an association lapses when a vehicle's hearing calls are further apart than this [s]
_ASSOCIATION_TIMEOUT_S = 10.0


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
        # [channel] environment: the air-to-ground channel (uavloc_gcs/a2g.py, .airground); None: the
        # log-distance channel of .channel, i.i.d. or correlated shadowing per frame
        self.a2g = A2GChannel.from_scenario(scenario)
        self._paths: dict[int, PathMemory] = {}
        self.comm_range_m = scenario.fleet.comm_range_m
        if tracks is None:
            count = sim.people if people is None else int(people)
            tracks = make_tracks(scenario.area_xy_m(), count, self.motion, scenario.people.max_speed_m_s,
                                 self._rng(_PEOPLE), horizon_s=horizon_s)
        self.tracks = tracks
        self._horizon_s = float(horizon_s)
        n = len(tracks)
        self.emitter_ids = _unique_ids(n, self._rng(_IDS))
        spread = sim.tx_power_spread_db
        self.tx_offset_db = spread * self._rng(_TX).standard_normal(n) if spread > 0 else np.zeros(n)
        self._vehicles: dict[int, ShadowingState] = {}
        self._elicit_rngs: dict[int, np.random.Generator] = {}
        # per vehicle, the phones associated with its access point at the end of its last call
        self._joined: dict[int, np.ndarray] = {}
        ch = scenario.channel
        self.sensitivity_dbm = ch.receiver_sensitivity_dbm
        self.listen_channels = np.array(ch.listen_channel_list, dtype=int)
        self.emission_model = scenario.emission.model
        self.elicitation_rate_hz = scenario.emission.elicitation_rate_hz
        self.emission: ProbeBursts | None = None
        if self.emission_model == "probe-bursts":
            self.emission = ProbeBursts(BurstParams.from_scenario(scenario), n, self._rng(_TRAITS),
                                        lambda i: self._rng(_BURSTS, i))
        # the phones that know a network the on-board access point offers (their own stream: the
        # bursts are drawn exactly as without an access point)
        self.joins = self._rng(_JOIN).random(n) < scenario.emission.mimicry_share
        # Bluetooth LE beacons of a share of the phones (emission.findmy_share, issue 39): their own
        # link budget (uavloc_gcs.radios.ble_view), path memory and random streams, so the Wi-Fi
        # world is drawn exactly as without them (paired comparisons)
        self.beacons: FindMyBeacons | None = None
        self.ble_a2g: A2GChannel | None = None
        if self.emission is not None and scenario.emission.findmy_share > 0 and self.a2g is not None:
            from uavloc_gcs.radios import ble_view

            self.beacons = FindMyBeacons(BeaconParams.from_scenario(scenario), n, scenario.emission.findmy_share,
                                         self._rng, horizon_s)
            self.ble_a2g = A2GChannel.from_scenario(ble_view(scenario))
        self._ble_paths: dict[int, PathMemory] = {}
        self._ble_rngs: dict[int, np.random.Generator] = {}
        self._id_index = {int(e): i for i, e in enumerate(self.emitter_ids)}
        # People stand on the ground (terrain.dem): their height above the launch point, which the
        # vehicles' z is measured from. None: flat ground at the launch point's height (z = h).
        self.dem = scenario.dem
        self._home_ground_m = self.dem.height_at(0.0, 0.0) if self.dem is not None else 0.0

    def ground_above_launch_m(self, xy_m) -> np.ndarray:
        """The ground's height above the launch point [m] at local points (..., 2); 0 without a DEM."""
        a = np.asarray(xy_m, dtype=float)
        if self.dem is None:
            return np.zeros(a.shape[:-1])
        return self.dem.height_xy(a.reshape(-1, 2), clamp=True).reshape(a.shape[:-1]) - self._home_ground_m

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

    def person_of(self, addresses) -> np.ndarray:
        """Truth: the person index (row of ``positions``) behind each 802.11 address (or, in the
        continuous world, emitter id) heard; -1 for an address no person of this world has used."""
        table = self._id_index if self.emission is None else self.emission.owner
        if self.beacons is not None:
            table = {**table, **self.beacons.owner}
        a = np.asarray(addresses, dtype=np.int64).reshape(-1)
        if self.emission is not None and any(int(x) not in table for x in a):
            # the bursts (and their addresses) are drawn as hearing needs them: a world rebuilt
            # from the seed to judge a search draws them up to the tracks' horizon first (each
            # phone's bursts come from its own stream in a fixed order, so they are the same)
            self.emission.frames(0.0, self._horizon_s)
        return np.array([table.get(int(x), -1) for x in a], dtype=int)

    @property
    def fingerprints(self) -> np.ndarray:
        """Content fingerprint of every person's phone (S,); 0 (unknown) in the continuous world."""
        return np.zeros(len(self), dtype=np.int64) if self.emission is None else self.emission.fingerprint.copy()

    def hearing_range_m(self) -> float:
        """3-D distance [m] at which a frame of a phone with no transmit offset is heard with
        probability 1/2: where the median RSSI equals the sensitivity (fleet.comm_range_m without one).
        Under an air-to-ground environment, that of a frame in line of sight (the farthest any
        frame's median reaches; blocked paths fall short of it)."""
        if self.sensitivity_dbm is None:
            return float(self.comm_range_m)
        if self.a2g is not None:
            return float(self.a2g.state_range_m(LOS))
        ch = self.channel
        margin = ch.reference_power_dbm - self.sensitivity_dbm
        return float(ch.reference_distance_m * 10.0 ** (margin / (10.0 * ch.path_loss_exponent)))

    # -- hearing --------------------------------------------------------------------------
    def hear(self, vehicle: int, t_s: float, xyz_m) -> SlotBatch:
        """One slot heard by ``vehicle`` at local position ``xyz_m`` at time ``t_s``: one row per
        person within the 3-D communication range; rssi = mean of the slot's dBm samples."""
        return self.hear_track(vehicle, np.array([float(t_s)]), np.asarray(xyz_m, float).reshape(1, 3))

    def hear_track(self, vehicle: int, t_s, xyz_m) -> SlotBatch:
        """Slots heard along a track: times (N,) nondecreasing, positions (N, 3) [m], one slot each.

        Calls for one vehicle must come in nondecreasing time (the shadowing has memory).

        Continuous emission without a receiver sensitivity (the paper): one row per (slot, person
        within fleet.comm_range_m), ``samples_per_slot`` samples each. With a sensitivity: only the
        samples above it count, rssi = their mean. Probe bursts: one row per (slot, address) whose
        frames were heard in the slot -- rssi = mean dBm of the heard frames, ``n_samples`` = their
        number, ``emitter_id`` = ``address`` (a sensor knows no person), ``fingerprint`` and the
        ``channel`` of the slot's first heard frame filled. Slot k covers [t_k, t_k + slot_s).
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
        s = len(self)
        if s == 0:
            state.last_t_s = float(t[-1])
            return SlotBatch.empty()
        if self.emission is not None:
            return self._hear_frames(int(vehicle), state, t, xyz)
        people = self.tracks.positions(t)  # (N, S, 2)
        dxy = people - xyz[:, None, :2]
        if self.dem is None:
            d3 = np.sqrt(np.sum(dxy**2, axis=2) + xyz[:, 2:3] ** 2)  # (N, S)
        else:  # the vehicle's height above each person on the ground
            d3 = np.sqrt(np.sum(dxy**2, axis=2) + (xyz[:, 2:3] - self.ground_above_launch_m(people)) ** 2)

        prev_xyz = xyz[0] if state.last_xyz_m is None else state.last_xyz_m
        prev_people = people[0] if state.last_people_xy_m is None else state.last_people_xy_m
        veh_step = np.linalg.norm(np.diff(np.vstack([prev_xyz, xyz]), axis=0), axis=1)  # (N,)
        ppl_step = np.linalg.norm(np.diff(np.concatenate([prev_people[None], people]), axis=0), axis=2)
        moved = veh_step[:, None] + ppl_step  # (N, S)

        psi = draw_shadowing_db(self.channel, state, moved)  # (N, K, S)
        k = self.channel.samples_per_slot
        if self.sensitivity_dbm is None:
            rssi = self.channel.median_rssi_dbm(d3) + self.tx_offset_db + psi.mean(axis=1)
            n_heard = np.where(d3 <= self.comm_range_m, k, 0)
        else:  # every sample is a frame, heard when above the sensitivity; no range gate
            samples = (self.channel.median_rssi_dbm(d3) + self.tx_offset_db)[:, None, :] + psi  # (N, K, S)
            heard = samples > self.sensitivity_dbm
            n_heard = heard.sum(axis=1)
            rssi = np.where(heard, samples, 0.0).sum(axis=1) / np.maximum(n_heard, 1)
        state.last_t_s, state.last_xyz_m, state.last_people_xy_m = float(t[-1]), xyz[-1].copy(), people[-1].copy()

        slot, person = np.nonzero(n_heard > 0)  # slot-major, then person order
        return SlotBatch.from_columns(
            t[slot], np.full(len(slot), int(vehicle)), xyz[slot], self.emitter_ids[person].astype(np.int64),
            rssi[slot, person], n_heard[slot, person],
        )

    def _hear_frames(self, vehicle: int, state: ShadowingState, t: np.ndarray, xyz: np.ndarray) -> SlotBatch:
        """Probe bursts (and elicited frames) heard along a track; see :meth:`hear_track`."""
        slot_s = self.scenario.channel.slot_s
        prev = xyz[0] if state.last_xyz_m is None else state.last_xyz_m
        steps = np.linalg.norm(np.diff(np.vstack([prev, xyz]), axis=0), axis=1)
        odometer = np.cumsum(np.concatenate([[state.odometer_m], steps]))[1:]  # (N,) distance flown
        frames = self.emission.frames(float(t[0]), float(t[-1]) + slot_s)
        slot = np.searchsorted(t, frames.t_s, side="right") - 1
        sent = (slot >= 0) & (frames.t_s < t[np.maximum(slot, 0)] + slot_s)
        # a scan (a burst on any channel) is when a phone finds the access point's network
        scans = (frames.person[sent], slot[sent])
        inside = sent & np.isin(frames.channel, self.listen_channels)
        frames, slot = frames.take(inside), slot[inside]
        if self.elicitation_rate_hz > 0:
            frames, slot = self._add_elicited(vehicle, state, t, xyz, frames, slot, scans)
        state.last_t_s, state.last_xyz_m, state.odometer_m = float(t[-1]), xyz[-1].copy(), float(odometer[-1])
        wifi = self._frames_heard(vehicle, state, t, xyz, odometer, frames, slot)
        if self.beacons is None:
            return wifi
        ble = self._beacons_heard(vehicle, t, xyz, odometer)
        if len(ble) == 0:
            return wifi
        both = SlotBatch.concat([wifi, ble])
        return both.take(np.argsort(both.t_s, kind="stable"))

    def _frames_heard(self, vehicle: int, state: ShadowingState, t: np.ndarray, xyz: np.ndarray,
                      odometer: np.ndarray, frames: Frames, slot: np.ndarray) -> SlotBatch:
        """The Wi-Fi frames sent in the track's slots that the vehicle hears, as slots."""
        if len(frames) == 0:
            return SlotBatch.empty()

        # each sender at its frame's slot only: hearing costs what the frames cost
        pxy = self.tracks.positions_of(frames.person, t[slot])  # (F, 2)
        dz = xyz[slot, 2] if self.dem is None else xyz[slot, 2] - self.ground_above_launch_m(pxy)
        if self.a2g is not None:  # the elevation-angle channel: state and shadowing per burst
            paths = self._paths.get(vehicle)
            if paths is None:
                paths = self._paths[vehicle] = PathMemory.empty(len(self))
            horizontal = np.linalg.norm(pxy - xyz[slot, :2], axis=1)
            d3 = np.hypot(horizontal, dz)
            rssi = draw_rssi_dbm(self.a2g, paths, state.rng, frames.person, frames.burst, odometer[slot], pxy,
                                 horizontal, dz, self.tx_offset_db[frames.person])
        else:
            d3 = np.sqrt(np.sum((pxy - xyz[slot, :2]) ** 2, axis=1) + dz ** 2)
            psi = draw_frame_shadowing_db(self.channel, state, frames.person, odometer[slot], pxy, len(self))
            rssi = self.channel.median_rssi_dbm(d3) + self.tx_offset_db[frames.person] + psi
        heard = d3 <= self.comm_range_m if self.sensitivity_dbm is None else rssi > self.sensitivity_dbm
        frames, slot, rssi = frames.take(heard), slot[heard], rssi[heard]
        if len(frames) == 0:
            return SlotBatch.empty()

        order = np.lexsort((frames.address, frames.person, slot))  # slot-major, then person, address
        frames, slot, rssi = frames.take(order), slot[order], rssi[order]
        new = np.ones(len(slot), dtype=bool)
        new[1:] = (slot[1:] != slot[:-1]) | (frames.address[1:] != frames.address[:-1])
        first = np.nonzero(new)[0]
        count = np.diff(np.append(first, len(slot)))
        mean = np.add.reduceat(rssi, first) / count
        rows = slot[first]
        fingerprint = self.emission.fingerprint[frames.person[first]]
        address = frames.address[first]
        return SlotBatch.from_columns(
            t[rows], np.full(len(rows), vehicle), xyz[rows], address, mean, count,
            address=address, fingerprint=fingerprint, channel=frames.channel[first],
        )

    def _beacons_heard(self, vehicle: int, t: np.ndarray, xyz: np.ndarray, odometer: np.ndarray) -> SlotBatch:
        """The BLE beacons sent in the track's slots that the vehicle's scanner hears (every beacon
        its own unit of the air-to-ground channel, the BLE link budget), one slot row each."""
        slot_s = self.scenario.channel.slot_s
        frames = self.beacons.frames(float(t[0]), float(t[-1]) + slot_s)
        slot = np.searchsorted(t, frames.t_s, side="right") - 1
        inside = (slot >= 0) & (frames.t_s < t[np.maximum(slot, 0)] + slot_s)
        frames, slot = frames.take(inside), slot[inside]
        rng = self._ble_rngs.get(vehicle)
        if rng is None:
            rng = self._ble_rngs[vehicle] = self._rng(_BLE, vehicle)
        paths = self._ble_paths.get(vehicle)
        if paths is None:
            paths = self._ble_paths[vehicle] = PathMemory.empty(len(self))
        pxy = self.tracks.positions_of(frames.person, t[slot])
        dz = xyz[slot, 2] if self.dem is None else xyz[slot, 2] - self.ground_above_launch_m(pxy)
        horizontal = np.linalg.norm(pxy - xyz[slot, :2], axis=1)
        rssi = draw_rssi_dbm(self.ble_a2g, paths, rng, frames.person, frames.burst, odometer[slot], pxy,
                             horizontal, dz, self.tx_offset_db[frames.person])
        heard = rssi > self.ble_a2g.sensitivity_dbm
        frames, slot, rssi = frames.take(heard), slot[heard], rssi[heard]
        if len(frames) == 0:
            return SlotBatch.empty()
        return SlotBatch.from_columns(
            t[slot], np.full(len(slot), vehicle), xyz[slot], frames.address, rssi, np.ones(len(slot), dtype=int),
            address=frames.address, fingerprint=fingerprint_of(frames.address), channel=frames.channel,
            radio=np.full(len(slot), RADIO_BLE),
        )

    def elicitation_range_m(self) -> float:
        """3-D distance [m] within which a phone hears the on-board access point and answers: the
        link is taken as symmetric (AP and phone radiate alike, the phone hears like the sensor), so
        it is the 50 % hearing range of :meth:`hearing_range_m`."""
        return self.hearing_range_m()

    def _add_elicited(self, vehicle: int, state: ShadowingState, t: np.ndarray, xyz: np.ndarray, frames: Frames,
                      slot: np.ndarray, scans: tuple[np.ndarray, np.ndarray]):
        """Elicited frames: a Poisson stream at ``elicitation_rate_hz`` from every phone associated
        with the vehicle's access point, under the phone's per-network address, on the access
        point's channel (the first listened channel). A phone that knows the network (``joins``,
        the ``emission.mimicry_share``) associates at a scan (one of its bursts) sent within
        :meth:`elicitation_range_m` and stays associated while it remains within it."""
        rng = self._elicit_rngs.get(vehicle)
        if rng is None:
            rng = self._elicit_rngs[vehicle] = self._rng(_ELICIT, vehicle)
        slot_s = self.scenario.channel.slot_s
        people = self.tracks.positions(t)  # (N, S, 2)
        dz = xyz[:, 2:3] if self.dem is None else xyz[:, 2:3] - self.ground_above_launch_m(people)
        d3 = np.sqrt(np.sum((people - xyz[:, None, :2]) ** 2, axis=2) + dz ** 2)
        reach = d3 <= self.elicitation_range_m()
        before = self._joined.get(vehicle)
        if before is None or t[0] - state.last_t_s > _ASSOCIATION_TIMEOUT_S:
            before = np.zeros(len(self), dtype=bool)
        if self.scenario.emission.elicitation_join == "in-reach":
            joined = reach & self.joins[None, :]
        else:
            joined = associated(reach, scans, self.joins, before)
        self._joined[vehicle] = joined[-1]
        count = rng.poisson(self.elicitation_rate_hz * slot_s, size=d3.shape) * joined
        k, person = np.nonzero(count)
        reps = count[k, person]
        k, person = np.repeat(k, reps), np.repeat(person, reps)
        n = len(k)
        el = Frames(person, t[k].astype(float), np.full(n, int(self.listen_channels[0])),
                    self.emission.network_address[person].astype(np.int64), np.full(n, -1), np.full(n, -1))
        both = Frames.concat([frames, el])
        slots = np.concatenate([slot, k])
        order = np.lexsort((both.person, both.t_s))
        return both.take(order), slots[order]

    def _state(self, vehicle: int) -> ShadowingState:
        st = self._vehicles.get(vehicle)
        if st is None:
            st = ShadowingState(self._rng(_VEHICLE, vehicle))
            self._vehicles[vehicle] = st
        return st

    def _rng(self, *key: int) -> np.random.Generator:
        return np.random.default_rng(np.random.SeedSequence(self.seed, spawn_key=key))


def associated(reach: np.ndarray, scans: tuple[np.ndarray, np.ndarray], joins: np.ndarray,
               before: np.ndarray) -> np.ndarray:
    """Which phones are associated with an access point in each slot, (N, S) bool.

    ``reach`` (N, S): the phone is within the access point's reach; ``scans``: (person, slot) of
    the phone's bursts; ``joins`` (S,): the phone knows the network; ``before`` (S,): associated at
    the end of the previous slots. A phone associates at a scan within reach (if it joins) and stays
    associated until the first slot out of reach."""
    n = len(reach)
    seed = np.zeros_like(reach)
    person, slot = scans
    seed[slot, person] = True
    seed &= reach & joins[None, :]
    seed[0] |= before & reach[0]
    run_start = reach.copy()
    run_start[1:] &= ~reach[:-1]
    c = np.cumsum(seed, axis=0)
    base = np.maximum.accumulate(np.where(run_start, c - seed, 0), axis=0)
    return reach & (c - base > 0)


def _unique_ids(n: int, rng: np.random.Generator) -> np.ndarray:
    """n distinct random nonzero uint32 ids."""
    ids = np.zeros(0, dtype=np.uint32)
    while len(ids) < n:
        more = rng.integers(1, 2**32, size=n - len(ids), dtype=np.uint64).astype(np.uint32)
        ids = np.concatenate([ids, more])
        _, first = np.unique(ids, return_index=True)
        ids = ids[np.sort(first)]
    return ids
