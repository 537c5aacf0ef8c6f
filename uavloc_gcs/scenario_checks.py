"""The scenario's values checked and its places resolved (the second half of :mod:`.scenario`).

:func:`resolve` runs on every scenario loaded or replaced: it refuses what is impossible (a negative
speed, a range below the altitude, packs without energy, a look floor above the scan), names the
file and the dotted key, and resolves the area polygon (a rectangle, vertices or a file), the
launch point, the geofence and the terrain. What is possible but implausible (a 1e9 m range) is
:mod:`.scenario_limits`'.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .errors import ConfigError, UavlocError
from .geo import LocalFrame

if TYPE_CHECKING:
    from .scenario import Scenario


def _check(cond: bool, message: str, sc: Scenario, key: str) -> None:
    if not cond:
        raise ConfigError(message, source=sc.source, key=key)


def resolve(sc: Scenario, base_dir: Path | None = None) -> Scenario:
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
