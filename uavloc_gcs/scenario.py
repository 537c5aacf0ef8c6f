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
from .errors import ConfigError
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
        from .scenario_checks import resolve

        return resolve(dataclasses.replace(self, **changes))


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
    from .scenario_checks import resolve  # below the sections: it checks values and resolves places

    sc = resolve(Scenario(name=name, source=source, **kwargs), base_dir=base_dir)
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
