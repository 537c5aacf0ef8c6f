"""Scenario / mission configuration: a TOML file with units in the key names.

A scenario says where to search (area), with what (fleet), how phones are heard (channel), what
the people do (people), how to scan and plan, and, for simulations, how the simulated world
behaves. Every section is a small frozen dataclass; :func:`load_scenario` reads a TOML file,
checks every key (unknown keys, wrong types, impossible values) and raises :class:`ConfigError`
naming the file and the dotted key.

Example (see ``examples/paper.toml``)::

    [area]
    origin_lat_deg = 47.397742
    origin_lon_deg = 8.545594
    width_m = 1120
    height_m = 640
    heading_deg = 90          # compass bearing of the width side from the origin corner

    [fleet]
    vehicles = 4
    altitude_m = 100
    ...
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Literal, get_args, get_origin, get_type_hints

import numpy as np

from .energy import RotorcraftPower
from .errors import ConfigError, UavlocError
from .geo import LocalFrame
from .terrain import TerrainSpec

import tomllib


# ---------------------------------------------------------------------------------------------
# Sections. Field names carry units; every field has a default unless the scenario must say it.


@dataclass(frozen=True)
class AreaSpec:
    """The search area: a rectangle (origin corner, size, heading) or a lat/lon polygon.

    Rectangle: ``origin_lat_deg``/``origin_lon_deg`` is one corner; the "width" side leaves it at
    compass bearing ``heading_deg`` (90 = due east) and the "height" side at ``heading_deg - 90``
    (i.e. to the left of the width side, due north for heading 90).
    Polygon: ``polygon_deg = [[lat, lon], ...]`` (3+ vertices, not closed) or ``polygon_file``
    (a GeoJSON Polygon/Feature or a QGroundControl ``.plan`` whose geofence has an inclusion polygon).
    """

    origin_lat_deg: float | None = None
    origin_lon_deg: float | None = None
    width_m: float | None = None
    height_m: float | None = None
    heading_deg: float = 90.0
    polygon_deg: list | None = None
    polygon_file: str | None = None
    # An inclusion geofence every planned flight stays inside (uavloc_gcs/geofence.py): the
    # airspace the team may use. ``geofence_deg = [[lat, lon], ...]`` or ``geofence_file`` (GeoJSON
    # or a QGroundControl .plan's inclusion polygon; it may be the same file as the area).
    # Planned points keep ``geofence_margin_m`` inside it, legs half of that.
    geofence_deg: list | None = None
    geofence_file: str | None = None
    geofence_margin_m: float = 30.0
    # Without geofence_deg / geofence_file the search area grown by this much (and the way to it from
    # a launch point beside it) is the fence every look and pass the daemon flies stays inside
    # (uavloc_gcs/geofence.py, default_for; issue 42: looks left the area by up to 111 m)
    default_geofence_m: float = 50.0


@dataclass(frozen=True)
class LaunchSpec:
    """Where every vehicle takes off and returns. Defaults to the area's first corner."""

    lat_deg: float | None = None
    lon_deg: float | None = None


@dataclass(frozen=True)
class FleetSpec:
    vehicles: int = 4
    altitude_m: float = 100.0
    speed_m_s: float = 25.0
    comm_range_m: float = 150.0
    autopilot: Literal["ardupilot", "px4"] = "ardupilot"
    energy_budget_j: float = 250_000.0  # per pack (issue 38: a vehicle flies one sortie per pack)
    energy_reserve_fraction: float = 0.15  # per pack
    max_acceleration_m_s2: float = 5.0
    # Sorties (issue 38): packs each vehicle has, and the time on the ground to swap one (landed
    # to ready to take off again). 1 pack: one sortie per vehicle, the behaviour before sorties.
    batteries: int = 1
    battery_swap_s: float = 120.0


@dataclass(frozen=True)
class ChannelSpec:
    """Log-distance path loss: P = P0 - 10 eta log10(d/d0) + N(0, sigma^2) [dBm]."""

    path_loss_exponent: float = 2.0
    shadowing_sigma_db: float = 4.0
    reference_power_dbm: float = -40.0
    reference_distance_m: float = 1.0
    slot_s: float = 0.025
    samples_per_slot: int = 10
    estimate_tx_power: bool = False
    # The receiver hears a frame only when its RSSI exceeds this [dBm] (SPEC 1.1; dongles about -90
    # to -95). None is the paper's world: every frame within fleet.comm_range_m is heard, none beyond.
    receiver_sensitivity_dbm: float | None = None
    # 802.11 channels the receiver listens on, one radio each (None: 1, 6 and 11, as the public
    # captures were made). Probe-request frames sent on other channels are not heard.
    listen_channels: list | None = None
    # The air-to-ground environment (uavloc_gcs/a2g.py): "suburban", "urban", "dense-urban" or
    # "high-rise". The chance of line of sight then rises with the elevation angle, blocked paths
    # lose more, frames of a burst share their shadowing and each has its own fast fading; the
    # log-distance law above is the free-space part of it. None: the i.i.d. log-normal channel with
    # shadowing_sigma_db per frame (the world before issue 41).
    environment: str | None = None
    # The Bluetooth LE scanner beside the Wi-Fi radios (issue 39): it hears an advertising frame
    # above this [dBm]. -95 dBm is the nRF52840's sensitivity in 1 Mbit/s BLE mode (Nordic
    # Semiconductor, nRF52840 Product Specification v1.7, "Radio: receiver sensitivity"), the chip of
    # the nRF Sniffer for Bluetooth LE. Used only when phones send beacons (emission.findmy_share).
    ble_receiver_sensitivity_dbm: float = -95.0

    @property
    def listen_channel_list(self) -> tuple:
        """The channels listened on (the default 1/6/11 when ``listen_channels`` is None)."""
        return (1, 6, 11) if self.listen_channels is None else tuple(int(c) for c in self.listen_channels)

    @property
    def log_range_sigma(self) -> float:
        """Std of ln(range) per sample: s = sigma ln10 / (10 eta) (0.4605 for the paper)."""
        return self.shadowing_sigma_db * math.log(10.0) / (10.0 * self.path_loss_exponent)


@dataclass(frozen=True)
class EmissionSpec:
    """How phones transmit (SPEC 1.1). ``continuous`` is the paper's world: every phone sends
    ``channel.samples_per_slot`` frames per slot, forever, under one address. ``probe-bursts`` is the
    field world: Wi-Fi probe-request bursts at random intervals under changing random addresses.
    ``elicitation_rate_hz`` > 0 models an on-board access point that mimics networks phones know:
    the ``mimicry_share`` of phones join it at their next probe burst within its reach and then
    answer at that rate while in reach.

    Burst parameters (used by ``probe-bursts`` only; defaults are the fit to public captures, see
    sim_link/world/emission.py and docs/science/world.md): every phone has a quantile u ~ U(0, 1)
    that places its median gap between bursts log-linearly in
    [``burst_gap_median_min_s``, ``burst_gap_median_max_s``] and its 90th percentile in
    [``burst_gap_p90_min_s``, ``burst_gap_p90_max_s``] (a log-normal gap distribution per phone);
    a gap is replaced by a silence of ``long_silence_min_s``..``long_silence_max_s`` with probability
    ``long_silence_per_gap``; a burst carries a per-phone median of
    ``frames_per_burst_median_min``..``frames_per_burst_median_max`` frames, at most
    ``frames_per_burst_max``, ``frame_spacing_s`` apart.
    """

    model: Literal["continuous", "probe-bursts"] = "continuous"
    elicitation_rate_hz: float = 0.0
    # Known-network mimicry (Wi2SAR, MobiCom '26): the on-board access point offers networks phones
    # know; a phone joins at its next scan (a probe burst) sent within the access point's reach,
    # then sends frames at elicitation_rate_hz while it stays within reach; leaving it drops the
    # association (a new scan in reach joins again). The share of phones that know a network the
    # vehicle offers: 1 is Wi2SAR's trials (every phone was discovered); no population share is
    # published, so a field result states the share it assumes (a team that knows a missing
    # person's home network has 1; phones of unknown people fewer).
    mimicry_share: float = 1.0
    # "scan" (the above: a phone associates at a burst sent within reach) or "in-reach": every
    # phone of the share answers from the moment it is within reach (the model before issue 39's
    # two mechanisms; also how the BLE view, uavloc_gcs/radios.py, models a beacon's advertising).
    elicitation_join: Literal["scan", "in-reach"] = "scan"
    # The same numbers as sim_link/world/emission.py's fitted constants (a test keeps them equal).
    burst_gap_median_min_s: float = 20.0
    burst_gap_median_max_s: float = 135.0
    burst_gap_p90_min_s: float = 60.0
    burst_gap_p90_max_s: float = 270.0
    long_silence_per_gap: float = 0.0094
    long_silence_min_s: float = 1800.0
    long_silence_max_s: float = 5400.0
    frames_per_burst_median_min: int = 4
    frames_per_burst_median_max: int = 27
    frames_per_burst_max: int = 80
    frame_spacing_s: float = 0.040
    # Bluetooth LE beacons (issue 39; uavloc_gcs/radios.py, sim_link/world/beacons.py). The share of
    # phones that send Apple Find My offline-finding beacons: an iPhone (iOS 13+, Find My on) with no
    # internet connection advertises every ble_interval_s (2 s: seemoo-lab/openhaystack's firmware,
    # after Heinrich et al., PETS 2021) under an address made of its current public key, which
    # rotates every ble_key_rotation_s (15 min: public reverse engineering, furiousMAC/continuity
    # and open firmware; stated as such). 0: no phone sends beacons (the world before issue 39).
    findmy_share: float = 0.0
    ble_interval_s: float = 2.0
    ble_key_rotation_s: float = 900.0
    # A beacon's RSSI at channel.reference_distance_m relative to a Wi-Fi frame's
    # (channel.reference_power_dbm) [dB]: an iBeacon at 0 dBm transmit power reads -59 dBm at 1 m
    # (Blue Charm Beacons' calibration chart; Apple's iBeacon "measured power" convention) where the
    # field world's Wi-Fi frames read -40 dBm: -19 dB. Phones advertise at up to +12 dBm
    # (kCBAdvDataTxPowerLevel reports, Apple developer forums thread 747391): 0 dBm is the cautious end.
    ble_power_offset_db: float = -19.0


@dataclass(frozen=True)
class PeopleSpec:
    max_speed_m_s: float = 1.5
    required_accuracy_m: float = 15.0
    # People expected per km² of the area (optional): the results then state how many are expected
    # to have been missed where the achieved POD fell short (search/coverage.py).
    density_per_km2: float | None = None
    # Prior share of the people who cannot move (trapped), for the field world's estimate: a person
    # who may walk is only bounded by max_speed_m_s since each burst (estimation/burst_grid.py). 0
    # (default): anyone may walk; with max_speed_m_s 0 everyone stands still whatever this says.
    static_share: float = 0.0


@dataclass(frozen=True)
class ScanSpec:
    """Initial scan. ``lane_spacing_m`` None means the documented default (double coverage)."""

    lane_spacing_m: float | None = None
    coverage: Literal["double", "single"] = "double"


@dataclass(frozen=True)
class SearchSpec:
    """What the search must achieve. ``pod_target``: the probability of detection (0-1) the scan is
    planned for, for one and for two heard bursts (``uavloc plan --pod``; search/pod_plan.py).
    None: the scan as ``[scan]`` lays it out. ``max_orbit_looks``: the most orbit looks flown for
    one person (burst world) before they are given up even though their phone was heard on the last
    one; None (the default): no such cap, a heard person is looked at again until no vehicle has
    the energy (search/orbit.py ``judge_orbit``)."""

    # The lowest a look flies [m above the ground plus terrain.obstacle_height_m] (issue 41;
    # uavloc_gcs/heights.py): 30 m clears a residential building of five storeys (23 m by the CTBUH
    # height calculator: 3.1 m per residential floor, 1.5 floors for the ground floor, 2 for the roof
    # and parapet) with 7 m to spare for the altitude held, and is the lowest altitude of issue 41's
    # table. Looks at the survey altitude (the default) never come near it.
    look_min_height_m: float = 30.0
    # The height [m above the ground] the policy's orbit looks fly at (search/orbit.py plan_orbit):
    # the vehicle goes down to it at the look's entry and climbs back after (heights.py). None (the
    # default): the survey altitude fleet.altitude_m, the looks of before issue 41, so scenarios that
    # do not ask for it (the paper's among them) plan, fly and estimate exactly as before.
    look_height_m: float | None = None
    pod_target: float | None = None
    max_orbit_looks: int | None = None
    # The longest the search may take [s], swaps on the ground included (None: as long as the packs
    # last); the POD planner plans within it (issue 38).
    time_limit_s: float | None = None


@dataclass(frozen=True)
class PlannerSpec:
    optimizer: Literal["epso", "pso", "ga"] = "epso"
    particles: int = 40
    iterations: int = 200
    # In-flight replanning budget. Measured on the paper scenario with 50 people (2 cores):
    # EPSO at 0.2 s is within 0-3 % of its 1 s makespan (identical for 10 people), and the
    # latency from a new slot to the new missions acknowledged is 220 ms instead of 0.9 s.
    time_limit_s: float = 0.2
    local_search: bool = True
    warm_start: bool = True
    seed: int = 0


@dataclass(frozen=True)
class SimulationSpec:
    """The simulated world (fake vehicles, demo, experiments); ignored against real vehicles."""

    people: int = 10
    seed: int = 1
    motion: Literal["static", "constant_velocity", "random_waypoint"] = "random_waypoint"
    correlated_shadowing: bool = False
    shadowing_decorrelation_m: float = 20.0
    tx_power_spread_db: float = 0.0
    speedup: float = 20.0


@dataclass(frozen=True)
class LinkSpec:
    """How ``uavloc daemon`` reaches the fleet; ignored by offline commands.

    ``connections[i]`` is the MAVLink connection of vehicle i+1 (its system id), e.g.
    ``"udpout:127.0.0.1:14561"``, ``"udpin:127.0.0.1:14550"``, ``"tcp:127.0.0.1:5760"`` or
    ``"/dev/ttyUSB0:57600"``. ``signing_key_hex`` is the fleet's 32-byte MAVLink 2 signing key as
    64 hex digits (empty = no signing). ``start = "operator"`` uploads the scan and waits for the
    operator to start each vehicle by hand. A vehicle silent for ``lost_timeout_s`` is lost.
    ``rssi_connections[i]`` (optional, "" = none) is a second connection of vehicle i+1 that carries
    only its companion's RSSI, beside the autopilot (a router on the companion, a second radio):
    PX4 does not forward the RSSI message. ``set_speed_params = true`` is the operator's consent
    to set the vehicles' speed parameters (WPNAV_SPEED, MPC_XY_CRUISE, ...) to ``fleet.speed_m_s``;
    without it the daemon plans with the speed the vehicles will really fly and says so.
    ``source_system`` is the daemon's own MAVLink system id: 245 by default, not 255, so that a
    QGroundControl (255) on the same vehicles is a different ground station to the autopilot.
    ``on_stop`` is what the airborne vehicles do when the daemon is stopped (Ctrl-C, SIGTERM):
    ``"rtl"`` commands them home, ``"continue"`` lets them finish their missions (which end in RTL).
    """

    connections: list | None = None
    signing_key_hex: str = ""
    tlog_path: str = ""
    start: Literal["auto", "operator"] = "auto"
    lost_timeout_s: float = 5.0
    rssi_connections: list | None = None
    set_speed_params: bool = False
    source_system: int = 245  # QGroundControl is 255; see docs/guide/daemon.md
    on_stop: Literal["rtl", "continue"] = "rtl"


@dataclass(frozen=True)
class Scenario:
    area: AreaSpec
    launch: LaunchSpec = field(default_factory=LaunchSpec)
    fleet: FleetSpec = field(default_factory=FleetSpec)
    channel: ChannelSpec = field(default_factory=ChannelSpec)
    emission: EmissionSpec = field(default_factory=EmissionSpec)
    people: PeopleSpec = field(default_factory=PeopleSpec)
    scan: ScanSpec = field(default_factory=ScanSpec)
    planner: PlannerSpec = field(default_factory=PlannerSpec)
    search: SearchSpec = field(default_factory=SearchSpec)
    simulation: SimulationSpec = field(default_factory=SimulationSpec)
    link: LinkSpec = field(default_factory=LinkSpec)
    terrain: TerrainSpec = field(default_factory=TerrainSpec)
    name: str = "scenario"
    source: str = "<string>"
    # Resolved geometry (filled by load/validate): polygon vertices as [[lat, lon], ...].
    polygon_latlon_deg: tuple = ()
    launch_latlon_deg: tuple = ()
    geofence_latlon_deg: tuple = ()  # the resolved area.geofence_deg / geofence_file, or ()

    # -- derived geometry -----------------------------------------------------------------
    @property
    def frame(self) -> LocalFrame:
        """The local ENU frame, centred on the launch point."""
        return _frame_cache(self.launch_latlon_deg[0], self.launch_latlon_deg[1])

    def area_xy_m(self) -> np.ndarray:
        """Area polygon vertices (N, 2) in local metres, counter-clockwise, not closed."""
        xy = self.frame.to_local_xy(np.array(self.polygon_latlon_deg))
        return _ccw(xy)

    def launch_xy_m(self) -> np.ndarray:
        return np.zeros(2)

    @property
    def dem(self):
        """The terrain (uavloc_gcs.terrain.Terrain) from ``terrain.dem``, or None: flat ground."""
        if not self.terrain.dem:
            return None
        from .terrain import load_dem

        return load_dem(self.terrain.dem, self.frame, source=self.source)

    @property
    def horizontal_range_m(self) -> float:
        """R = sqrt(D^2 - h^2): ground radius within which a phone is heard."""
        d, h = self.fleet.comm_range_m, self.fleet.altitude_m
        return math.sqrt(d * d - h * h)

    @property
    def power_model(self) -> RotorcraftPower:
        return RotorcraftPower()

    @property
    def usable_energy_j(self) -> float:
        return self.fleet.energy_budget_j * (1.0 - self.fleet.energy_reserve_fraction)

    def replace(self, **sections: Any) -> "Scenario":
        """A copy with whole sections or section fields replaced, re-validated.

        ``sc.replace(fleet={"vehicles": 2})`` or ``sc.replace(fleet=FleetSpec(...))``.
        """
        changes = {}
        for name, value in sections.items():
            if isinstance(value, dict):
                value = dataclasses.replace(getattr(self, name), **value)
            changes[name] = value
        return _resolve(dataclasses.replace(self, **changes))


_FRAMES: dict = {}


def _frame_cache(lat: float, lon: float) -> LocalFrame:
    key = (lat, lon)
    if key not in _FRAMES:
        _FRAMES[key] = LocalFrame(lat, lon)
    return _FRAMES[key]


def _ccw(xy: np.ndarray) -> np.ndarray:
    x, y = xy[:, 0], xy[:, 1]
    area2 = np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
    return xy if area2 > 0 else xy[::-1].copy()


# ---------------------------------------------------------------------------------------------
# Loading and validation

_SECTIONS = {
    "area": AreaSpec,
    "launch": LaunchSpec,
    "fleet": FleetSpec,
    "channel": ChannelSpec,
    "emission": EmissionSpec,
    "people": PeopleSpec,
    "scan": ScanSpec,
    "planner": PlannerSpec,
    "search": SearchSpec,
    "simulation": SimulationSpec,
    "link": LinkSpec,
    "terrain": TerrainSpec,
}


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario TOML file, or a shipped one by name (``paper``, ``small``: see
    :mod:`uavloc_gcs.examples`). Raises ConfigError naming the file and key."""
    from .examples import scenario_names, scenario_path

    p = scenario_path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"file not found (shipped scenarios, usable by name: {', '.join(scenario_names())})",
                          source=str(p)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read file ({exc})", source=str(p)) from None
    return loads_scenario(text, source=str(p), base_dir=p.parent)


def loads_scenario(text: str, *, source: str = "<string>", base_dir: Path | None = None) -> Scenario:
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"not valid TOML ({exc})", source=source) from None
    return scenario_from_dict(raw, source=source, base_dir=base_dir)


def scenario_from_dict(raw: dict, *, source: str = "<string>", base_dir: Path | None = None) -> Scenario:
    unknown = set(raw) - set(_SECTIONS) - {"name"}
    if unknown:
        k = sorted(unknown)[0]
        raise ConfigError(
            f"unknown section or key (expected one of: name, {', '.join(_SECTIONS)})", source=source, key=k
        )
    if "area" not in raw:
        raise ConfigError("missing [area] section", source=source, key="area")
    kwargs: dict[str, Any] = {}
    for sec_name, cls in _SECTIONS.items():
        sec_raw = raw.get(sec_name, {})
        if not isinstance(sec_raw, dict):
            raise ConfigError("must be a table", source=source, key=sec_name)
        kwargs[sec_name] = _build_section(cls, sec_raw, sec_name, source)
    name = raw.get("name", Path(source).stem if source != "<string>" else "scenario")
    if not isinstance(name, str):
        raise ConfigError("must be a string", source=source, key="name")
    sc = _resolve(Scenario(name=name, source=source, **kwargs), base_dir=base_dir)
    from .scenario_limits import check_plausible  # values no field, fleet or radio has (issue 40)

    check_plausible(sc)
    return sc


def _build_section(cls, sec_raw: dict, sec_name: str, source: str):
    hints = get_type_hints(cls)
    names = {f.name for f in fields(cls)}
    values = {}
    for key, value in sec_raw.items():
        dotted = f"{sec_name}.{key}"
        if key not in names:
            raise ConfigError(
                f"unknown key (known keys: {', '.join(sorted(names))})", source=source, key=dotted
            )
        values[key] = _coerce(value, hints[key], dotted, source)
    return cls(**values)


def _coerce(value: Any, hint: Any, dotted: str, source: str) -> Any:
    origin = get_origin(hint)
    args = get_args(hint)
    if origin is Literal:
        if value not in args:
            raise ConfigError(
                f"is {value!r}; expected one of {', '.join(repr(a) for a in args)}", source=source, key=dotted
            )
        return value
    if type(None) in args:  # Optional[...]
        inner = [a for a in args if a is not type(None)]
        return _coerce(value, inner[0], dotted, source)
    if hint is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"must be true or false, got {value!r}", source=source, key=dotted)
        return value
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"must be a whole number, got {value!r}", source=source, key=dotted)
        return value
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"must be a number, got {value!r}", source=source, key=dotted)
        if not math.isfinite(value):
            raise ConfigError(f"must be finite, got {value!r}", source=source, key=dotted)
        return float(value)
    if hint is str:
        if not isinstance(value, str):
            raise ConfigError(f"must be a string, got {value!r}", source=source, key=dotted)
        return value
    if hint is list or origin is list:
        if not isinstance(value, list):
            raise ConfigError(f"must be a list, got {value!r}", source=source, key=dotted)
        return value
    return value


def _check(cond: bool, message: str, sc: Scenario, key: str) -> None:
    if not cond:
        raise ConfigError(message, source=sc.source, key=key)


def _resolve(sc: Scenario, base_dir: Path | None = None) -> Scenario:
    """Validate values and resolve the area polygon and launch point."""
    f, ch, pe, sim, pl, scan = sc.fleet, sc.channel, sc.people, sc.simulation, sc.planner, sc.scan
    _check(f.vehicles >= 1, f"must be at least 1, got {f.vehicles}", sc, "fleet.vehicles")
    _check(f.vehicles <= 64, f"at most 64 vehicles are supported, got {f.vehicles}", sc, "fleet.vehicles")
    _check(f.altitude_m > 0, f"must be positive, got {f.altitude_m} m", sc, "fleet.altitude_m")
    _check(f.speed_m_s > 0, f"must be positive, got {f.speed_m_s} m/s", sc, "fleet.speed_m_s")
    _check(f.speed_m_s <= 60, f"{f.speed_m_s} m/s is beyond any multirotor (max 60)", sc, "fleet.speed_m_s")
    _check(
        f.comm_range_m > f.altitude_m,
        f"communication range {f.comm_range_m} m must exceed the altitude {f.altitude_m} m, "
        "or no phone on the ground is ever heard",
        sc,
        "fleet.comm_range_m",
    )
    _check(f.energy_budget_j > 0, f"must be positive, got {f.energy_budget_j} J", sc, "fleet.energy_budget_j")
    _check(
        0.0 <= f.energy_reserve_fraction < 1.0,
        f"must be in [0, 1), got {f.energy_reserve_fraction}",
        sc,
        "fleet.energy_reserve_fraction",
    )
    _check(f.max_acceleration_m_s2 > 0, "must be positive", sc, "fleet.max_acceleration_m_s2")
    _check(ch.path_loss_exponent > 0, "must be positive", sc, "channel.path_loss_exponent")
    _check(ch.shadowing_sigma_db > 0, "must be positive", sc, "channel.shadowing_sigma_db")
    _check(ch.reference_distance_m > 0, "must be positive", sc, "channel.reference_distance_m")
    _check(ch.slot_s > 0, "must be positive", sc, "channel.slot_s")
    _check(ch.samples_per_slot >= 1, "must be at least 1", sc, "channel.samples_per_slot")
    if ch.receiver_sensitivity_dbm is not None:
        _check(
            ch.receiver_sensitivity_dbm < ch.reference_power_dbm,
            f"{ch.receiver_sensitivity_dbm} dBm is not below the reference power {ch.reference_power_dbm} dBm, "
            "so no phone would ever be heard",
            sc,
            "channel.receiver_sensitivity_dbm",
        )
    _check_sorties(sc)
    _check_channels(sc)
    _check_emission(sc)
    _check_environment(sc)
    _check(pe.max_speed_m_s >= 0, "must not be negative", sc, "people.max_speed_m_s")
    _check(
        pe.max_speed_m_s < f.speed_m_s,
        f"people ({pe.max_speed_m_s} m/s) must be slower than the vehicles ({f.speed_m_s} m/s)",
        sc,
        "people.max_speed_m_s",
    )
    _check(pe.required_accuracy_m > 0, "must be positive", sc, "people.required_accuracy_m")
    _check(0.0 <= pe.static_share <= 1.0, "must be a share between 0 and 1", sc, "people.static_share")
    _check(pe.density_per_km2 is None or (math.isfinite(pe.density_per_km2) and pe.density_per_km2 >= 0),
           "must be a number of people per km², 0 or more", sc, "people.density_per_km2")
    if scan.lane_spacing_m is not None:
        _check(scan.lane_spacing_m > 0, "must be positive", sc, "scan.lane_spacing_m")
    if sc.search.pod_target is not None:
        _check(0.0 < sc.search.pod_target < 1.0, f"must be a probability between 0 and 1 (exclusive), got "
               f"{sc.search.pod_target}", sc, "search.pod_target")
    if sc.search.max_orbit_looks is not None:
        _check(sc.search.max_orbit_looks >= 1, f"must be 1 or more orbit looks per person, got "
               f"{sc.search.max_orbit_looks}", sc, "search.max_orbit_looks")
    _check_look_floor(sc)
    _check(pl.particles >= 2, "must be at least 2", sc, "planner.particles")
    _check(pl.iterations >= 1, "must be at least 1", sc, "planner.iterations")
    _check(pl.time_limit_s > 0, "must be positive", sc, "planner.time_limit_s")
    _check(sim.people >= 0, "must not be negative", sc, "simulation.people")
    _check(sim.shadowing_decorrelation_m > 0, "must be positive", sc, "simulation.shadowing_decorrelation_m")
    _check(sim.tx_power_spread_db >= 0, "must not be negative", sc, "simulation.tx_power_spread_db")
    _check(sim.speedup > 0, "must be positive", sc, "simulation.speedup")
    _check_link(sc)

    poly = _resolve_polygon(sc, base_dir)
    if sc.launch.lat_deg is None and sc.launch.lon_deg is None:
        launch = (float(poly[0][0]), float(poly[0][1]))
    else:
        _check(
            sc.launch.lat_deg is not None and sc.launch.lon_deg is not None,
            "give both lat_deg and lon_deg",
            sc,
            "launch",
        )
        _check_latlon(sc, sc.launch.lat_deg, sc.launch.lon_deg, "launch")
        launch = (sc.launch.lat_deg, sc.launch.lon_deg)
    sc = dataclasses.replace(
        sc, polygon_latlon_deg=tuple(tuple(map(float, v)) for v in poly), launch_latlon_deg=launch
    )
    xy = sc.area_xy_m()
    _check_polygon_simple(sc, xy)
    sc = _resolve_geofence(sc, xy, base_dir)
    return _resolve_terrain(sc, xy, base_dir)


def _resolve_geofence(sc: Scenario, area_xy: np.ndarray, base_dir: Path | None) -> Scenario:
    """[area] geofence_deg / geofence_file: read, checked to be a simple polygon around the launch
    point with room inside its margin for part of the area, and resolved to lat/lon vertices."""
    from shapely.geometry import Point, Polygon

    a = sc.area
    _check(math.isfinite(a.geofence_margin_m) and 0.0 <= a.geofence_margin_m <= 1000.0,
           f"must be 0-1000 m, got {a.geofence_margin_m}", sc, "area.geofence_margin_m")
    _check(math.isfinite(a.default_geofence_m) and a.geofence_margin_m < a.default_geofence_m <= 5000.0,
           f"must be more than area.geofence_margin_m ({a.geofence_margin_m:g} m) and at most 5000 m, got "
           f"{a.default_geofence_m}", sc, "area.default_geofence_m")
    if a.geofence_deg is None and a.geofence_file is None:
        return dataclasses.replace(sc, geofence_latlon_deg=()) if sc.geofence_latlon_deg else sc
    _check(a.geofence_deg is None or a.geofence_file is None, "give geofence_deg or geofence_file, not both",
           sc, "area.geofence_deg")
    if a.geofence_deg is not None:
        key = "area.geofence_deg"
        _check(isinstance(a.geofence_deg, list), f"must be a list of [lat, lon] vertices, got {a.geofence_deg!r}",
               sc, key)
        poly = _vertices_deg(sc, a.geofence_deg, key)
    else:
        key = "area.geofence_file"
        poly, path = _polygon_from_file(sc, a.geofence_file, base_dir, key, "geofence")
        sc = dataclasses.replace(sc, area=dataclasses.replace(a, geofence_file=str(path.resolve())))
    _check(len(poly) >= 3, f"needs at least 3 distinct vertices, got {len(poly)}", sc, key)
    ll = tuple((float(v[0]), float(v[1])) for v in poly)
    fxy = sc.frame.to_local_xy(np.asarray(ll))
    fence = Polygon(fxy)
    _check(fence.is_valid and fence.area > 1.0, "the geofence polygon crosses itself or has no area", sc, key)
    _check(fence.buffer(0.5).covers(Point(0.0, 0.0)),
           f"the launch point ({sc.launch_latlon_deg[0]:.6f}, {sc.launch_latlon_deg[1]:.6f}) lies outside "
           "the geofence; every vehicle must take off inside it", sc, key)
    inner = fence.buffer(-sc.area.geofence_margin_m, join_style="mitre")
    _check(not inner.is_empty and inner.intersects(Polygon(area_xy)),
           f"no part of the search area lies {sc.area.geofence_margin_m:g} m inside the geofence "
           "(area.geofence_margin_m); nothing could be searched", sc, key)
    return dataclasses.replace(sc, geofence_latlon_deg=ll)


def _resolve_terrain(sc: Scenario, area_xy: np.ndarray, base_dir: Path | None) -> Scenario:
    """[terrain]: the keys checked, the DEM's path made absolute, and the DEM read and checked to
    cover the area and the launch point (uavloc_gcs/terrain.py)."""
    from .terrain import check_covers, check_spec

    path = check_spec(sc, base_dir)
    if not path:
        return sc
    sc = dataclasses.replace(sc, terrain=dataclasses.replace(sc.terrain, dem=path))
    check_covers(sc.dem, np.vstack([area_xy, np.zeros((1, 2))]), "the area or the launch point", source=sc.source)
    return sc


MAX_BATTERIES = 50  # packs per vehicle accepted (a team carries a few; this catches a typo)


def _check_sorties(sc: Scenario) -> None:
    """[fleet] batteries / battery_swap_s and [search] time_limit_s (issue 38), each refused in one
    sentence naming its key."""
    f, limit = sc.fleet, sc.search.time_limit_s
    _check(1 <= f.batteries <= MAX_BATTERIES, f"must be 1-{MAX_BATTERIES} packs per vehicle, got {f.batteries}",
           sc, "fleet.batteries")
    _check(0.0 <= f.battery_swap_s <= 3600.0, f"must be 0-3600 s on the ground per swap, got {f.battery_swap_s}",
           sc, "fleet.battery_swap_s")
    if limit is not None:
        _check(limit > 0.0, f"must be a positive number of seconds, got {limit}", sc, "search.time_limit_s")
        _check(limit <= 7 * 24 * 3600.0, f"{limit:g} s is more than a week; give the search's limit in seconds",
               sc, "search.time_limit_s")


def _check_look_floor(sc: Scenario) -> None:
    """[search] look_min_height_m and [terrain] obstacle_height_m (uavloc_gcs/heights.py), each
    refused in one sentence naming its key."""
    low, obst = sc.search.look_min_height_m, sc.terrain.obstacle_height_m
    _check(math.isfinite(low) and low > 0.0, f"must be a positive height in metres, got {low}", sc,
           "search.look_min_height_m")
    _check(math.isfinite(obst) and obst >= 0.0, f"must be a height in metres, 0 or more, got {obst}", sc,
           "terrain.obstacle_height_m")
    _check(low + obst < sc.fleet.comm_range_m,
           f"a look floor of {low:g} m + terrain.obstacle_height_m = {obst:g} m is beyond the communication range "
           f"fleet.comm_range_m = {sc.fleet.comm_range_m:g} m, so no look could hear a phone", sc,
           "search.look_min_height_m")
    h = sc.search.look_height_m
    if h is not None:
        from .heights import look_floor_m  # noqa: PLC0415

        floor = look_floor_m(sc)
        _check(math.isfinite(h) and floor - 1e-9 <= h <= sc.fleet.altitude_m,
               f"must be a height in metres between the look floor of {floor:g} m (search.look_min_height_m"
               f" + terrain.obstacle_height_m) and the survey altitude fleet.altitude_m = {sc.fleet.altitude_m:g} m,"
               f" got {h}", sc, "search.look_height_m")


def _check_channels(sc: Scenario) -> None:
    chans = sc.channel.listen_channels
    if chans is None:
        return
    _check(len(chans) >= 1, "must list at least one channel, for example [1, 6, 11]", sc, "channel.listen_channels")
    for c in chans:
        _check(isinstance(c, int) and not isinstance(c, bool) and 1 <= c <= 14,
               f"entries must be 2.4 GHz channel numbers 1..14, got {c!r}", sc, "channel.listen_channels")
    _check(len(set(chans)) == len(chans), "lists a channel twice", sc, "channel.listen_channels")


def _check_environment(sc: Scenario) -> None:
    """[channel] environment: a known name, in a world it is built for (bursts above a threshold)."""
    from .a2g import ENVIRONMENTS

    env = sc.channel.environment
    if env is None:
        return
    key = "channel.environment"
    _check(env in ENVIRONMENTS, f"unknown environment {env!r}; choose one of {', '.join(ENVIRONMENTS)}", sc, key)
    _check(sc.channel.receiver_sensitivity_dbm is not None,
           f"the {env!r} air-to-ground channel hears frames above a threshold: set "
           "channel.receiver_sensitivity_dbm (dongles: about -90 to -95 dBm)", sc, key)
    _check(sc.emission.model == "probe-bursts",
           f"the {env!r} air-to-ground channel is built for phones that send probe bursts: set "
           "[emission] model = \"probe-bursts\", or remove channel.environment for the paper's world", sc, key)
    _check(not sc.simulation.correlated_shadowing,
           f"the {env!r} air-to-ground channel draws its own shadowing, shared within a burst and "
           "correlated between bursts: remove simulation.correlated_shadowing, or channel.environment", sc,
           "simulation.correlated_shadowing")


def _check_emission(sc: Scenario) -> None:
    """Values of [emission] that no phone could have, each refused in one sentence naming its key."""
    em = sc.emission
    _check(0.0 <= em.findmy_share <= 1.0, f"is a share of the phones, between 0 and 1, got {em.findmy_share}", sc,
           "emission.findmy_share")
    _check(em.ble_interval_s >= 0.02, f"{em.ble_interval_s} s is shorter than any BLE advertising interval "
           "(at least 0.02 s, Bluetooth Core 5.x)", sc, "emission.ble_interval_s")
    _check(em.ble_key_rotation_s > em.ble_interval_s, f"{em.ble_key_rotation_s} s is not longer than the "
           f"advertising interval ({em.ble_interval_s} s)", sc, "emission.ble_key_rotation_s")
    _check(-60.0 <= em.ble_power_offset_db <= 20.0, f"{em.ble_power_offset_db} dB is not a phone's BLE power "
           "against its Wi-Fi (between -60 and +20 dB)", sc, "emission.ble_power_offset_db")
    _check(-130.0 <= sc.channel.ble_receiver_sensitivity_dbm <= -30.0,
           f"{sc.channel.ble_receiver_sensitivity_dbm} dBm is no BLE receiver's sensitivity (between -130 and -30)",
           sc, "channel.ble_receiver_sensitivity_dbm")
    if em.findmy_share > 0:
        _check(em.model == "probe-bursts" and sc.channel.environment is not None,
               "phones that send BLE beacons live in the field world: set [emission] model = \"probe-bursts\" "
               "and [channel] environment", sc, "emission.findmy_share")
    _check(em.elicitation_rate_hz >= 0, f"must not be negative, got {em.elicitation_rate_hz} Hz", sc,
           "emission.elicitation_rate_hz")
    _check(em.elicitation_join in ("scan", "in-reach"), f"is \"scan\" or \"in-reach\", got {em.elicitation_join!r}",
           sc, "emission.elicitation_join")
    _check(0.0 <= em.mimicry_share <= 1.0, f"is a share of the phones, between 0 and 1, got {em.mimicry_share}", sc,
           "emission.mimicry_share")
    _check(em.elicitation_rate_hz <= 1000, f"{em.elicitation_rate_hz} Hz is more than any phone answers "
           "(at most 1000)", sc, "emission.elicitation_rate_hz")
    for key in ("burst_gap_median_min_s", "burst_gap_median_max_s", "burst_gap_p90_min_s", "burst_gap_p90_max_s",
                "long_silence_min_s", "long_silence_max_s", "frame_spacing_s"):
        value = getattr(em, key)
        _check(value > 0, f"must be positive, got {value} s", sc, f"emission.{key}")
    for low, high in (("burst_gap_median_min_s", "burst_gap_median_max_s"),
                      ("burst_gap_p90_min_s", "burst_gap_p90_max_s"),
                      ("long_silence_min_s", "long_silence_max_s"),
                      ("frames_per_burst_median_min", "frames_per_burst_median_max"),
                      ("frames_per_burst_median_max", "frames_per_burst_max")):
        _check(getattr(em, low) <= getattr(em, high),
               f"{getattr(em, high)} is below emission.{low} = {getattr(em, low)}", sc, f"emission.{high}")
    for med, p90 in (("burst_gap_median_min_s", "burst_gap_p90_min_s"),
                     ("burst_gap_median_max_s", "burst_gap_p90_max_s")):
        _check(getattr(em, p90) > getattr(em, med),
               f"a 90th percentile of {getattr(em, p90)} s must exceed the median emission.{med} = "
               f"{getattr(em, med)} s", sc, f"emission.{p90}")
    longest = em.frames_per_burst_max * em.frame_spacing_s
    _check(longest < em.burst_gap_median_min_s,
           f"bursts of up to {longest:g} s (frames_per_burst_max x frame_spacing_s) would overlap gaps of "
           f"{em.burst_gap_median_min_s} s (emission.burst_gap_median_min_s)", sc, "emission.frame_spacing_s")
    _check(0.0 <= em.long_silence_per_gap < 1.0, f"must be in [0, 1), got {em.long_silence_per_gap}", sc,
           "emission.long_silence_per_gap")
    _check(em.frames_per_burst_median_min >= 1, f"must be at least 1, got {em.frames_per_burst_median_min}",
           sc, "emission.frames_per_burst_median_min")
    _check(em.frames_per_burst_max <= 1000, f"{em.frames_per_burst_max} frames in one burst is beyond any "
           "phone (at most 1000)", sc, "emission.frames_per_burst_max")


def _check_link(sc: Scenario) -> None:
    lk = sc.link
    if lk.connections is not None:
        for i, c in enumerate(lk.connections):
            _check(isinstance(c, str) and c.strip() != "",
                   f"entry {i} must be a connection string such as \"udpout:127.0.0.1:14561\", got {c!r}",
                   sc, "link.connections")
        _check(len(lk.connections) == sc.fleet.vehicles,
               f"lists {len(lk.connections)} connections for {sc.fleet.vehicles} vehicles (fleet.vehicles); "
               "give one per vehicle", sc, "link.connections")
    if lk.rssi_connections is not None:
        for i, c in enumerate(lk.rssi_connections):
            _check(isinstance(c, str),
                   f"entry {i} must be a connection string (or \"\" for none), got {c!r}", sc, "link.rssi_connections")
        _check(len(lk.rssi_connections) == sc.fleet.vehicles,
               f"lists {len(lk.rssi_connections)} connections for {sc.fleet.vehicles} vehicles (fleet.vehicles); "
               "give one per vehicle (\"\" for a vehicle whose RSSI comes through its autopilot)",
               sc, "link.rssi_connections")
    _check(isinstance(lk.set_speed_params, bool), f"must be true or false, got {lk.set_speed_params!r}",
           sc, "link.set_speed_params")
    if lk.signing_key_hex:
        try:
            ok = len(bytes.fromhex(lk.signing_key_hex)) == 32
        except ValueError:
            ok = False
        _check(ok, "must be 64 hexadecimal digits (a 32-byte key)", sc, "link.signing_key_hex")
    _check(lk.lost_timeout_s > 0, f"must be positive, got {lk.lost_timeout_s}", sc, "link.lost_timeout_s")
    _check(1 <= lk.source_system <= 255, f"must be 1..255, got {lk.source_system}", sc, "link.source_system")


def _check_latlon(sc: Scenario, lat: float, lon: float, key: str) -> None:
    _check(-90.0 < lat < 90.0, f"latitude {lat} is outside -90..90 degrees", sc, key)
    _check(-180.0 <= lon <= 180.0, f"longitude {lon} is outside -180..180 degrees", sc, key)


def _resolve_polygon(sc: Scenario, base_dir: Path | None) -> list:
    a = sc.area
    given = [
        name
        for name, present in (
            ("rectangle (origin_lat_deg, origin_lon_deg, width_m, height_m)", a.origin_lat_deg is not None),
            ("polygon_deg", a.polygon_deg is not None),
            ("polygon_file", a.polygon_file is not None),
        )
        if present
    ]
    _check(len(given) == 1, "give exactly one of: a rectangle (origin_lat_deg, origin_lon_deg, width_m, "
           f"height_m), polygon_deg, or polygon_file; got {len(given)}", sc, "area")
    if a.origin_lat_deg is not None:
        for k in ("origin_lon_deg", "width_m", "height_m"):
            _check(getattr(a, k) is not None, "is required for a rectangular area", sc, f"area.{k}")
        _check_latlon(sc, a.origin_lat_deg, a.origin_lon_deg, "area.origin_lat_deg")
        _check(a.width_m > 0, f"must be positive, got {a.width_m}", sc, "area.width_m")
        _check(a.height_m > 0, f"must be positive, got {a.height_m}", sc, "area.height_m")
        _check(a.width_m <= 50_000 and a.height_m <= 50_000, "areas larger than 50 km are not supported",
               sc, "area.width_m")
        return rectangle_latlon(a.origin_lat_deg, a.origin_lon_deg, a.width_m, a.height_m, a.heading_deg)
    if a.polygon_deg is not None:
        poly = _vertices_deg(sc, a.polygon_deg, "area.polygon_deg")
        _check(len(poly) >= 3, f"needs at least 3 distinct vertices, got {len(poly)}", sc, "area.polygon_deg")
        return [[float(v[0]), float(v[1])] for v in poly]
    poly, _ = _polygon_from_file(sc, a.polygon_file, base_dir, "area.polygon_file", "area")
    _check(len(poly) >= 3, "the area file's polygon has fewer than 3 vertices", sc, "area.polygon_file")
    return [[float(v[0]), float(v[1])] for v in poly]


def _vertices_deg(sc: Scenario, poly: list, key: str) -> list:
    """``[[lat, lon], ...]`` from the scenario checked vertex by vertex (one sentence naming
    ``key`` and the vertex), a closing vertex equal to the first dropped."""
    for i, v in enumerate(poly):
        ok = (isinstance(v, list) and len(v) == 2
              and all(isinstance(c, (int, float)) and not isinstance(c, bool) for c in v))
        _check(ok, f"vertex {i} must be [lat, lon] numbers, got {v!r}", sc, key)
        _check_latlon(sc, float(v[0]), float(v[1]), f"{key}[{i}]")
    return poly[:-1] if len(poly) >= 2 and poly[0] == poly[-1] else poly


def _polygon_from_file(sc: Scenario, name: str, base_dir: Path | None, key: str, what: str) -> tuple[list, Path]:
    """The polygon of a GeoJSON or ``.plan`` file named by ``key`` (relative to the scenario's
    folder) and its path; a file that cannot be used is one sentence naming ``key``."""
    from mission_io.area import read_area_polygon  # file formats live in mission_io

    path = Path(name)
    if not path.is_absolute() and base_dir is not None:
        path = base_dir / path
    try:
        return read_area_polygon(path), path
    except UavlocError as exc:
        raise ConfigError(f"cannot use the {what} file: {exc}", source=sc.source, key=key) from None


def rectangle_latlon(lat0: float, lon0: float, width_m: float, height_m: float, heading_deg: float) -> list:
    """Corners [[lat, lon]] x4 of a rectangle whose width side leaves (lat0, lon0) at ``heading_deg``."""
    frame = LocalFrame(lat0, lon0)
    th = math.radians(heading_deg)
    u = np.array([math.sin(th), math.cos(th)])  # along width (compass bearing -> east/north)
    w = np.array([-u[1], u[0]])  # 90 degrees to the left of u
    corners = np.array([[0.0, 0.0], width_m * u, width_m * u + height_m * w, height_m * w])
    return frame.to_wgs84_latlon(corners).tolist()


def _check_polygon_simple(sc: Scenario, xy: np.ndarray) -> None:
    from shapely.geometry import Polygon

    poly = Polygon(xy)
    _check(poly.is_valid, "the area polygon crosses itself", sc, "area")
    _check(poly.area > 1.0, "the area polygon has no area", sc, "area")
