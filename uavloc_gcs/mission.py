"""Mission model and its MAVLink encoding, with the ArduPilot/PX4 differences in one place.

Two levels:

* :class:`MissionPlan` -- what the operator means: an optional planned home and a list of
  :class:`MissionItem` (command, frame, params, lat/lon in degrees, alt in metres). This is what
  ``mission_io`` reads and writes (``.plan`` keeps home separately; ``.waypoints`` puts it on line 0).
* :class:`WireItem` -- exactly the fields of MISSION_ITEM_INT as sent to a given autopilot
  (seq, current, degE7 integers). :func:`to_wire` / :func:`from_wire` convert, applying the
  autopilot flavour rules:

  - ArduPilot: seq 0 is home (a NAV_WAYPOINT at the planned home, frame GLOBAL); real items from 1.
  - PX4: no home item; items start at seq 0; non-positional items (DO_CHANGE_SPEED, RTL, ...)
    must use MAV_FRAME_MISSION or PX4 answers MAV_MISSION_UNSUPPORTED.
  - Both: non-positional items use MAV_FRAME_MISSION with zero x/y/z; the first sent item has
    current = 1 (MAVSDK and QGC do the same).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, Literal, Sequence

from .errors import UavlocError

Autopilot = Literal["ardupilot", "px4"]

# MAV_CMD
NAV_WAYPOINT = 16
NAV_LOITER_TIME = 19
NAV_RETURN_TO_LAUNCH = 20
NAV_LAND = 21
NAV_TAKEOFF = 22
DO_JUMP = 177
DO_CHANGE_SPEED = 178
DO_SET_MISSION_CURRENT = 224

# MAV_FRAME
FRAME_GLOBAL = 0
FRAME_MISSION = 2
FRAME_GLOBAL_RELATIVE_ALT = 3
FRAME_GLOBAL_INT = 5
FRAME_GLOBAL_RELATIVE_ALT_INT = 6
FRAME_GLOBAL_TERRAIN_ALT = 10
FRAME_GLOBAL_TERRAIN_ALT_INT = 11
GLOBAL_FRAMES = frozenset(
    {FRAME_GLOBAL, FRAME_GLOBAL_RELATIVE_ALT, FRAME_GLOBAL_INT, FRAME_GLOBAL_RELATIVE_ALT_INT,
     FRAME_GLOBAL_TERRAIN_ALT, FRAME_GLOBAL_TERRAIN_ALT_INT}
)

# Commands without a position: PX4 accepts them only with MAV_FRAME_MISSION.
FRAMELESS_COMMANDS = frozenset({NAV_RETURN_TO_LAUNCH, DO_JUMP, DO_CHANGE_SPEED, DO_SET_MISSION_CURRENT})
# Commands whose params 5-7 are a location (common.xml ``hasLocation``); every other command is
# frameless to PX4, whatever frame a Mission Planner file gives it (DO_* items in frame 3).
LOCATION_COMMANDS = frozenset({16, 17, 18, 19, 21, 22, 23, 24, 25, 31, 34, 35, 36, 80, 81, 82, 84, 85, 94, 179, 188,
                               189, 192, 195, 201, 252, 4001, 4501, 5000, 5001, 5002, 5003, 5004, 5100, 30001,
                               31000, 31001, 31002, 31003, 31004, 31005, 31006, 31007, 31008, 31009, 43003})

# MAV_MISSION_TYPE
MISSION_TYPE_MISSION = 0

# Commands whose x/y/z are a position (encoded as degE7 lat/lon).
POSITIONAL_COMMANDS = frozenset({NAV_WAYPOINT, NAV_LOITER_TIME, NAV_LAND, NAV_TAKEOFF, 17, 18, 31, 82})
# Commands the vehicle flies to (a point of the route): waypoints, loiters, land, spline and VTOL
# land, payload place. Takeoff climbs where the vehicle is (at home).
ROUTE_COMMANDS = frozenset({NAV_WAYPOINT, 17, 18, NAV_LOITER_TIME, NAV_LAND, 31, 82, 85, 94})
TAKEOFF_COMMANDS = frozenset({NAV_TAKEOFF, 84})
# Geofence vertices/circles/return point and rally points: their own mission types, never a mission.
FENCE_COMMANDS = frozenset({5000, 5001, 5002, 5003, 5004})
RALLY_COMMANDS = frozenset({5100})

# MAV_AUTOPILOT values used in .plan files
AUTOPILOT_ARDUPILOTMEGA = 3
AUTOPILOT_PX4 = 12
MAV_TYPE_QUADROTOR = 2

SPEED_TYPE_GROUNDSPEED = 1


@dataclass(frozen=True)
class MissionItem:
    """One mission item in operator units. ``params`` is param1..param4 (NaN allowed where the
    autopilot allows it); ``lat_deg``/``lon_deg``/``alt_m`` are param5..7 (zero for
    non-positional items)."""

    command: int
    frame: int = FRAME_GLOBAL_RELATIVE_ALT
    params: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    lat_deg: float = 0.0
    lon_deg: float = 0.0
    alt_m: float = 0.0
    autocontinue: bool = True

    @property
    def is_positional(self) -> bool:
        return self.frame in GLOBAL_FRAMES

    @property
    def has_position(self) -> bool:
        """Whether lat/lon is a real place: a global frame, finite, and not the 0, 0 placeholder
        Mission Planner and ArduPilot write for "here" (takeoff, DO_* and RTL items)."""
        return (self.frame in GLOBAL_FRAMES and math.isfinite(self.lat_deg) and math.isfinite(self.lon_deg)
                and not (self.lat_deg == 0.0 and self.lon_deg == 0.0))

    def same_as(self, other: "MissionItem", *, latlon_tol_deg: float = 1.5e-7, tol: float = 1e-4) -> bool:
        """Equal to the precision of the wire/file encodings (degE7, float32 params)."""
        if (self.command, self.frame, self.autocontinue) != (other.command, other.frame, other.autocontinue):
            return False
        for a, b in zip(self.params, other.params):
            if math.isnan(a) != math.isnan(b):
                return False
            if not math.isnan(a) and abs(a - b) > tol * max(1.0, abs(a)):
                return False
        return (
            abs(self.lat_deg - other.lat_deg) <= latlon_tol_deg
            and abs(self.lon_deg - other.lon_deg) <= latlon_tol_deg
            and abs(self.alt_m - other.alt_m) <= tol * max(1.0, abs(self.alt_m))
        )


@dataclass(frozen=True)
class MissionPlan:
    """A mission as the operator sees it: planned home (lat, lon, alt AMSL or NaN) and items."""

    items: tuple[MissionItem, ...]
    home_lat_deg: float = math.nan
    home_lon_deg: float = math.nan
    home_alt_m: float = math.nan
    autopilot: Autopilot = "ardupilot"
    cruise_speed_m_s: float | None = None
    hover_speed_m_s: float | None = None
    geofence_polygons: tuple = ()  # tuple of (inclusion: bool, ((lat, lon), ...))
    rally_points: tuple = ()  # tuple of (lat, lon, alt_rel_m)
    geofence_circles: tuple = ()  # tuple of (inclusion: bool, (lat, lon), radius_m)
    # The DEM's ground height [m] under each item (NaN where none), set by terrain.terrain_safe; a
    # .plan export writes QGroundControl's terrain fields from it. Ignored unless one per item.
    terrain_alt_m: tuple = ()

    def waypoints(self) -> list[MissionItem]:
        return [it for it in self.items if it.command == NAV_WAYPOINT]

    def same_as(self, other: "MissionPlan") -> bool:
        return len(self.items) == len(other.items) and all(
            a.same_as(b) for a, b in zip(self.items, other.items)
        )


@dataclass(frozen=True)
class WireItem:
    """The fields of MISSION_ITEM_INT exactly as on the wire (x/y degE7 for global frames)."""

    seq: int
    frame: int
    command: int
    current: int
    autocontinue: int
    param1: float
    param2: float
    param3: float
    param4: float
    x: int
    y: int
    z: float
    mission_type: int = MISSION_TYPE_MISSION

    def same_as(self, other: "WireItem") -> bool:
        """Equal as the autopilot stores it (float32 params, NaN == NaN; seq and current ignored
        because autopilots renumber and reset them)."""
        def feq(a: float, b: float) -> bool:
            if math.isnan(a) or math.isnan(b):
                return math.isnan(a) and math.isnan(b)
            return abs(a - b) <= 1e-5 * max(1.0, abs(a))

        frames_equal = self.frame == other.frame or {self.frame, other.frame} in (
            {FRAME_GLOBAL, FRAME_GLOBAL_INT},
            {FRAME_GLOBAL_RELATIVE_ALT, FRAME_GLOBAL_RELATIVE_ALT_INT},
            {FRAME_GLOBAL_TERRAIN_ALT, FRAME_GLOBAL_TERRAIN_ALT_INT},
        )
        return (
            frames_equal
            and self.command == other.command
            and self.autocontinue == other.autocontinue
            and all(feq(a, b) for a, b in zip(
                (self.param1, self.param2, self.param3, self.param4, self.z),
                (other.param1, other.param2, other.param3, other.param4, other.z)))
            and self.x == other.x
            and self.y == other.y
        )


class MissionEncodingError(UavlocError):
    """A mission cannot be encoded for the chosen autopilot."""


def deg_to_e7(value_deg: float) -> int:
    return int(round(value_deg * 1e7))


def e7_to_deg(value: int) -> float:
    return value / 1e7


def to_wire(plan: MissionPlan, autopilot: Autopilot | None = None) -> list[WireItem]:
    """Encode ``plan`` as the MISSION_ITEM_INT list to upload to ``autopilot``.

    A DO_JUMP's param1 is the target's 1-based item number in the model (= its ArduPilot seq,
    home being seq 0); for PX4, which has no home item, it is sent one lower, as QGroundControl's
    plan manager does when it drops home.
    """
    ap = autopilot or plan.autopilot
    out: list[WireItem] = []
    if ap == "ardupilot":
        if math.isnan(plan.home_lat_deg) or math.isnan(plan.home_lon_deg):
            # ArduPilot overwrites item 0 with its own home; a zero placeholder is what MAVProxy sends.
            hx, hy, hz = 0, 0, 0.0
        else:
            hx, hy = deg_to_e7(plan.home_lat_deg), deg_to_e7(plan.home_lon_deg)
            hz = 0.0 if math.isnan(plan.home_alt_m) else float(plan.home_alt_m)
        out.append(WireItem(0, FRAME_GLOBAL, NAV_WAYPOINT, 0, 1, 0.0, 0.0, 0.0, 0.0, hx, hy, hz))
    elif ap != "px4":
        raise MissionEncodingError(f"unknown autopilot {ap!r} (expected 'ardupilot' or 'px4')")
    for i, it in enumerate(plan.items):
        seq = len(out)
        out.append(_item_to_wire(it, seq, ap, index=i, n_items=len(plan.items),
                                 home=(plan.home_lat_deg, plan.home_lon_deg)))
    if out:
        first = out[0]
        out[0] = WireItem(**{**first.__dict__, "current": 1})
    return out


def _item_to_wire(it: MissionItem, seq: int, ap: Autopilot, *, index: int, n_items: int,
                  home: tuple[float, float]) -> WireItem:
    for k, p in enumerate(it.params, start=1):
        if math.isinf(p):
            raise MissionEncodingError(f"item {index + 1}: param{k} is infinite")
    p = it.params
    if it.command == DO_JUMP:
        target = float(p[0])
        if not (math.isfinite(target) and target.is_integer() and 1 <= target <= n_items):
            raise MissionEncodingError(f"item {index + 1}: DO_JUMP target {target:g} is not an item of the mission "
                                       f"(items are 1..{n_items})")
        if ap == "px4":
            p = (target - 1.0, *p[1:])
    # Mission Planner files give every item the plan's altitude frame (RTL and DO_CHANGE_SPEED with
    # frame 3); PX4 rejects those commands unless they use MAV_FRAME_MISSION, so they are frameless.
    if it.is_positional and not (ap == "px4" and (it.command in FRAMELESS_COMMANDS
                                                  or it.command not in LOCATION_COMMANDS)):
        if math.isnan(it.lat_deg) or math.isnan(it.lon_deg):
            if ap == "px4":
                raise MissionEncodingError(
                    f"item {index + 1}: the position is unset (null); PX4 needs a latitude and longitude here")
            lat, lon = 0.0, 0.0  # ArduPilot: 0, 0 means "where the vehicle is"
        else:
            lat, lon = it.lat_deg, it.lon_deg
        if ap == "px4" and deg_to_e7(lat) == 0 and deg_to_e7(lon) == 0:
            # Mission Planner's 0, 0 "here": ArduPilot's convention, a real place to PX4. A takeoff
            # climbs at home (QGroundControl puts it there); anything else needs a position.
            if it.command in TAKEOFF_COMMANDS and not any(math.isnan(v) or v == 0.0 for v in home):
                lat, lon = home
            else:
                raise MissionEncodingError(
                    f"item {index + 1}: lat/lon 0, 0 means \"here\" to ArduPilot, but PX4 would fly to 0 N 0 E; "
                    "give the item a position or upload to an ArduPilot vehicle")
        if not (-90.0 <= lat <= 90.0) or not (-180.0 <= lon <= 180.0):
            raise MissionEncodingError(f"item {index + 1}: position ({lat}, {lon}) is not a valid lat/lon")
        if not math.isfinite(it.alt_m):
            raise MissionEncodingError(f"item {index + 1}: altitude {it.alt_m} is not finite")
        x, y, z = deg_to_e7(lat), deg_to_e7(lon), float(it.alt_m)
        frame = it.frame
    elif it.is_positional:
        # A position-framed item sent frameless (PX4): its x/y/z were a position, not parameters.
        frame, x, y, z = FRAME_MISSION, 0, 0, 0.0
    else:
        frame = FRAME_MISSION if ap == "px4" or it.frame == FRAME_MISSION else it.frame
        # MISSION_ITEM_INT x/y are integers: an unset (NaN, QGC's null) parameter goes as 0, as MAVSDK
        # sends it and as both autopilots store an unused field; an unset z likewise.
        x, y = (_int_param(v, index, k) for k, v in ((5, it.lat_deg), (6, it.lon_deg)))
        z = 0.0 if math.isnan(it.alt_m) else float(it.alt_m)
        if math.isinf(z):
            raise MissionEncodingError(f"item {index + 1}: param7 is infinite")
    return WireItem(seq, frame, it.command, 0, int(bool(it.autocontinue)), p[0], p[1], p[2], p[3], x, y, z)


def _int_param(value: float, index: int, k: int) -> int:
    if math.isnan(value):
        return 0
    if math.isinf(value) or not -2**31 <= round(value) < 2**31:
        raise MissionEncodingError(f"item {index + 1}: param{k} {value} does not fit MISSION_ITEM_INT's 32-bit field")
    return int(round(value))


def from_wire(items: Sequence[WireItem], autopilot: Autopilot) -> MissionPlan:
    """Decode a downloaded MISSION_ITEM_INT list back into a :class:`MissionPlan` (a PX4
    DO_JUMP target is made 1-based again, as in files)."""
    items = list(items)
    home = (math.nan, math.nan, math.nan)
    if autopilot == "ardupilot" and items:
        h = items[0]
        home = (e7_to_deg(h.x), e7_to_deg(h.y), float(h.z))
        items = items[1:]
    out = []
    for w in items:
        positional = w.frame in GLOBAL_FRAMES
        if positional:
            lat, lon = e7_to_deg(w.x), e7_to_deg(w.y)
        else:
            lat, lon = float(w.x), float(w.y)
        p1 = w.param1 + 1.0 if autopilot == "px4" and w.command == DO_JUMP else w.param1
        out.append(
            MissionItem(
                command=w.command,
                frame=w.frame,
                params=(p1, w.param2, w.param3, w.param4),
                lat_deg=lat,
                lon_deg=lon,
                alt_m=float(w.z),
                autocontinue=bool(w.autocontinue),
            )
        )
    return MissionPlan(tuple(out), *home, autopilot=autopilot)


# ---------------------------------------------------------------------------------------------
# Building the missions uavloc flies


def takeoff(alt_m: float, lat_deg: float = 0.0, lon_deg: float = 0.0) -> MissionItem:
    """NAV_TAKEOFF to ``alt_m`` above home (yaw NaN = keep)."""
    return MissionItem(NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, (0.0, 0.0, 0.0, math.nan), lat_deg, lon_deg, alt_m)


def change_speed(speed_m_s: float) -> MissionItem:
    """DO_CHANGE_SPEED: ground speed ``speed_m_s``, throttle unchanged (-1)."""
    return MissionItem(DO_CHANGE_SPEED, FRAME_MISSION, (float(SPEED_TYPE_GROUNDSPEED), speed_m_s, -1.0, 0.0))


def pass_through_waypoint(lat_deg: float, lon_deg: float, alt_m: float) -> MissionItem:
    """NAV_WAYPOINT with hold 0 (fly through, no stop), default acceptance radius, yaw unchanged."""
    return MissionItem(NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT, (0.0, 0.0, 0.0, math.nan), lat_deg, lon_deg, alt_m)


def return_to_launch() -> MissionItem:
    return MissionItem(NAV_RETURN_TO_LAUNCH, FRAME_MISSION)


def at_look_height(lat_deg: float, lon_deg: float, look_alt_m: float | None, transit_alt_m: float) -> list[MissionItem]:
    """The items that fly one point at its own height: the point at the transit altitude, then straight
    down (or up) to ``look_alt_m`` there; a single pass-through waypoint when the look flies at the
    transit altitude (None, or within half a metre). The climb back is :func:`climb_back`."""
    if look_alt_m is None or abs(float(look_alt_m) - transit_alt_m) <= 0.5:
        return [pass_through_waypoint(lat_deg, lon_deg, transit_alt_m)]
    return [pass_through_waypoint(lat_deg, lon_deg, transit_alt_m),
            pass_through_waypoint(lat_deg, lon_deg, float(look_alt_m))]


def climb_back(lat_deg: float, lon_deg: float, look_alt_m: float | None, transit_alt_m: float) -> list[MissionItem]:
    """Straight back up (or down) to the transit altitude where a look at ``look_alt_m`` ended
    (nothing when it flew at the transit altitude)."""
    if look_alt_m is None or abs(float(look_alt_m) - transit_alt_m) <= 0.5:
        return []
    return [pass_through_waypoint(lat_deg, lon_deg, transit_alt_m)]


def check_point_alts(point_alts_m, n_points: int, transit_alt_m: float, floor_m: float | None) -> list:
    """``point_alts_m`` as a list of n_points heights (None where a point flies at the transit
    altitude), refused (MissionEncodingError, one sentence) where one is not a number, the count
    differs, or one is below ``floor_m`` -- or, with no floor given, below the transit altitude
    (a caller that sends a vehicle lower must say how low it may go)."""
    if point_alts_m is None:
        return [None] * n_points
    alts = list(point_alts_m)
    if len(alts) != n_points:
        raise MissionEncodingError(f"{len(alts)} look heights for {n_points} points; give one per point (None: the "
                                   "transit altitude)")
    for k, a in enumerate(alts):
        if a is None:
            continue
        if not math.isfinite(float(a)):
            raise MissionEncodingError(f"point {k + 1}: look height {a} is not a number of metres")
        lowest = transit_alt_m - 0.5 if floor_m is None else floor_m
        if float(a) < lowest - 1e-9:
            why = (f"the look floor of {floor_m:g} m" if floor_m is not None
                   else f"the transit altitude {transit_alt_m:g} m and no look floor was given")
            raise MissionEncodingError(f"point {k + 1}: a look at {float(a):g} m is below {why}; not flown")
    return alts


def flight_mission(
    waypoints_latlon_deg: Iterable[Sequence[float]],
    *,
    alt_m: float,
    speed_m_s: float,
    autopilot: Autopilot,
    home_latlon_deg: Sequence[float] | None = None,
    home_alt_amsl_m: float = math.nan,
    include_takeoff: bool = True,
    return_home: bool = True,
    cruise_speed_m_s: float | None = None,
    point_alts_m: Sequence[float | None] | None = None,
    floor_m: float | None = None,
) -> MissionPlan:
    """Takeoff (when on the ground), speed change to ``speed_m_s``, pass-through waypoints, RTL.

    ``alt_m`` is the transit altitude. ``point_alts_m`` (one per waypoint, None = ``alt_m``) flies a
    point at its own height: the vehicle arrives at the transit altitude, goes straight down to the
    point's height, and straight back up before the next point (:func:`at_look_height`,
    :func:`climb_back`); below ``floor_m`` [m] is refused (without a floor, below ``alt_m``)."""
    pts = [(float(lat), float(lon)) for lat, lon in waypoints_latlon_deg]
    alts = check_point_alts(point_alts_m, len(pts), alt_m, floor_m)
    items: list[MissionItem] = []
    if include_takeoff:
        lat, lon = (home_latlon_deg if home_latlon_deg is not None else (0.0, 0.0))
        items.append(takeoff(alt_m, lat, lon))
    items.append(change_speed(speed_m_s))
    for (lat, lon), a in zip(pts, alts):
        items += at_look_height(lat, lon, a, alt_m) + climb_back(lat, lon, a, alt_m)
    if return_home:
        items.append(return_to_launch())
    hl = home_latlon_deg if home_latlon_deg is not None else (math.nan, math.nan)
    return MissionPlan(
        tuple(items),
        float(hl[0]),
        float(hl[1]),
        home_alt_amsl_m,
        autopilot=autopilot,
        cruise_speed_m_s=cruise_speed_m_s if cruise_speed_m_s is not None else speed_m_s,
        hover_speed_m_s=5.0,
    )
