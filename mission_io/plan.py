"""QGroundControl ``.plan`` files (JSON), read and written as :class:`MissionPlan`.

Written files carry everything current QGroundControl requires to load them
(``PlanMasterController::loadFromFile``): ``fileType``/``version``/``groundStation``, a
``mission`` (version 2, ``firmwareType``, ``vehicleType``, ``cruiseSpeed``/``hoverSpeed``,
``globalPlanAltitudeMode``, ``plannedHomePosition``, ``items``), a ``geoFence`` and
``rallyPoints``. Items are ``SimpleItem`` with ``doJumpId`` = their 1-based position;
positional items also carry the ``Altitude``/``AltitudeMode``/``AMSLAltAboveTerrain`` UI keys.
NaN is written as ``null``. Keys are sorted and indented like QGroundControl's own output, and
floats are written with full (round-trip) precision, so output is deterministic and lossless.

Reading accepts the same plus QGC survey/corridor ``ComplexItem``s (their pre-expanded
``TransectStyleComplexItem.Items``), the older item forms QGroundControl converts (4 ``params`` +
``coordinate``; ``param1``..``param4`` keys), null positions, and geofence circles. A legacy
``.mission`` file and unresolved above-terrain altitudes are refused with what to do. A
``DO_JUMP``'s param1 refers to a ``doJumpId`` in the file and is converted to the target's
1-based item position (= the ArduPilot seq) in the model.
Errors name the file, the item (1-based position in ``mission.items``) and the field.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from uavloc_gcs.errors import FileFormatError
from uavloc_gcs.mission import (
    AUTOPILOT_ARDUPILOTMEGA,
    AUTOPILOT_PX4,
    DO_JUMP,
    FRAME_GLOBAL,
    FRAME_GLOBAL_INT,
    FRAME_GLOBAL_RELATIVE_ALT,
    FRAME_GLOBAL_RELATIVE_ALT_INT,
    FRAME_GLOBAL_TERRAIN_ALT,
    FRAME_GLOBAL_TERRAIN_ALT_INT,
    MAV_TYPE_QUADROTOR,
    POSITIONAL_COMMANDS,
    MissionItem,
    MissionPlan,
)

from ._common import json_number, read_text, write_text


__all__ = ["loads", "dumps", "read", "write"]

GROUND_STATION = "uavloc"
_FIRMWARE = {"ardupilot": AUTOPILOT_ARDUPILOTMEGA, "px4": AUTOPILOT_PX4}
_FIRMWARE_NAMES = {v: k for k, v in _FIRMWARE.items()}
# QGroundControlQmlGlobal::AltMode for each frame: 1 Relative, 2 Absolute, 4 TerrainFrame.
_ALT_MODE = {
    FRAME_GLOBAL: 2, FRAME_GLOBAL_INT: 2,
    FRAME_GLOBAL_RELATIVE_ALT: 1, FRAME_GLOBAL_RELATIVE_ALT_INT: 1,
    FRAME_GLOBAL_TERRAIN_ALT: 4, FRAME_GLOBAL_TERRAIN_ALT_INT: 4,
}
_ALT_MODE_CALC_ABOVE_TERRAIN = 3  # frame 0 with the AMSL altitude QGC computed from terrain data


# ---------------------------------------------------------------------------------------------
# Writing


def dumps(plan: MissionPlan) -> str:
    """The ``.plan`` JSON text of ``plan`` (deterministic; ends with a newline)."""
    items = [_item_json(it, k + 1) for k, it in enumerate(plan.items)]
    if len(plan.terrain_alt_m) == len(plan.items) and plan.items:
        _terrain_fields(items, plan)
    mission: dict[str, Any] = {
        "firmwareType": _FIRMWARE[plan.autopilot],
        "globalPlanAltitudeMode": _plan_alt_mode(plan),
        "items": items,
        "plannedHomePosition": [json_number(plan.home_lat_deg), json_number(plan.home_lon_deg),
                                json_number(plan.home_alt_m)],
        "vehicleType": MAV_TYPE_QUADROTOR,
        "version": 2,
    }
    if plan.cruise_speed_m_s is not None:
        mission["cruiseSpeed"] = json_number(plan.cruise_speed_m_s)
    if plan.hover_speed_m_s is not None:
        mission["hoverSpeed"] = json_number(plan.hover_speed_m_s)
    doc = {
        "fileType": "Plan",
        "geoFence": {
            "circles": [
                {"circle": {"center": [json_number(lat), json_number(lon)], "radius": json_number(r)},
                 "inclusion": bool(inc), "version": 1}
                for inc, (lat, lon), r in plan.geofence_circles
            ],
            "polygons": [
                {"inclusion": bool(inc), "polygon": [[json_number(a), json_number(b)] for a, b in ring], "version": 1}
                for inc, ring in plan.geofence_polygons
            ],
            "version": 2,
        },
        "groundStation": GROUND_STATION,
        "mission": mission,
        "rallyPoints": {"points": [[json_number(v) for v in p] for p in plan.rally_points], "version": 2},
        "version": 1,
    }
    return json.dumps(doc, indent=4, sort_keys=True, allow_nan=False) + "\n"


def _terrain_fields(items: list, plan: MissionPlan) -> None:
    """QGroundControl's terrain fields on items whose ground height uavloc knows (a terrain-safe
    plan): an absolute altitude is "calculated above terrain" (AltitudeMode 3): ``Altitude`` the
    height above the ground, ``AMSLAltAboveTerrain`` and params[6] the AMSL altitude QGC sends."""
    for raw, it, ground in zip(items, plan.items, plan.terrain_alt_m):
        if it.frame in (FRAME_GLOBAL, FRAME_GLOBAL_INT) and "AltitudeMode" in raw and math.isfinite(ground):
            raw["AltitudeMode"] = _ALT_MODE_CALC_ABOVE_TERRAIN
            raw["Altitude"] = json_number(round(it.alt_m - ground, 2))
            raw["AMSLAltAboveTerrain"] = json_number(it.alt_m)


def _plan_alt_mode(plan: MissionPlan) -> int:
    modes = {_ALT_MODE[it.frame] for it in plan.items if it.frame in _ALT_MODE}
    return modes.pop() if len(modes) == 1 else (1 if not modes else 0)  # 0 = Mixed


def _item_json(it: MissionItem, number: int) -> dict:
    params = [json_number(p) for p in it.params] + [json_number(it.lat_deg), json_number(it.lon_deg),
                                                     json_number(it.alt_m)]
    out: dict[str, Any] = {
        "autoContinue": bool(it.autocontinue),
        "command": int(it.command),
        "doJumpId": number,
        "frame": int(it.frame),
        "params": params,
        "type": "SimpleItem",
    }
    if it.frame in _ALT_MODE:
        out["AMSLAltAboveTerrain"] = None
        out["Altitude"] = json_number(it.alt_m)
        out["AltitudeMode"] = _ALT_MODE[it.frame]
    return out


def write(path: str | Path, plan: MissionPlan) -> Path:
    """Write ``plan`` to ``path`` atomically."""
    return write_text(path, dumps(plan))


# ---------------------------------------------------------------------------------------------
# Reading


def read(path: str | Path) -> MissionPlan:
    """Read a ``.plan`` file. Raises FileFormatError naming the file, item and field."""
    return loads(read_text(path), path=str(path))


def loads(text: str, *, path: str = "<string>") -> MissionPlan:
    """Parse ``.plan`` JSON text."""
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise FileFormatError(f"not valid JSON ({exc.msg}, column {exc.colno})", path=path, line=exc.lineno) from None
    if not isinstance(doc, dict):
        raise FileFormatError("expected a JSON object at the top level", path=path)
    if doc.get("fileType") == "Mission" or ("fileType" not in doc and "items" in doc):
        raise FileFormatError(
            "this is a legacy QGroundControl .mission file (mission only, before .plan files existed), which "
            "uavloc does not read; open it in QGroundControl and save it again, which writes a .plan", path=path,
            field="fileType")
    _expect(doc.get("fileType") == "Plan", f"must be \"Plan\", got {doc.get('fileType')!r}", path, "fileType")
    _expect(doc.get("version") == 1, f"must be 1, got {doc.get('version')!r}", path, "version")
    _expect(isinstance(doc.get("groundStation"), str), "missing or not a string", path, "groundStation")
    mission = doc.get("mission")
    _expect(isinstance(mission, dict), "missing or not an object", path, "mission")
    _expect(mission.get("version") == 2, f"must be 2, got {mission.get('version')!r}", path, "mission.version")
    fw = mission.get("firmwareType")
    _expect(fw in _FIRMWARE_NAMES,
            f"is {fw!r}; expected {AUTOPILOT_ARDUPILOTMEGA} (ArduPilot) or {AUTOPILOT_PX4} (PX4)",
            path, "mission.firmwareType")
    home = mission.get("plannedHomePosition")
    _expect(isinstance(home, list) and len(home) == 3, "must be [lat, lon, alt] (3 entries, null allowed)",
            path, "mission.plannedHomePosition")
    home_v = [_num(v, path, "mission.plannedHomePosition", None) for v in home]
    if home_v[0] == 0.0 and home_v[1] == 0.0:
        home_v = [math.nan] * 3  # [0, 0, 0]: QGroundControl's "no home yet", not a place
    raw_items = mission.get("items")
    _expect(isinstance(raw_items, list), "missing or not a list", path, "mission.items")
    flat: list[tuple[int, dict]] = []  # (1-based item number in the file, SimpleItem json)
    for k, raw in enumerate(raw_items, start=1):
        _expect(isinstance(raw, dict), "must be an object", path, "mission.items", item=k)
        kind = raw.get("type")
        if kind == "SimpleItem":
            flat.append((k, raw))
        elif kind == "ComplexItem":
            flat += [(k, sub) for sub in _complex_items(raw, path, k)]
        else:
            raise FileFormatError(f"is {kind!r}; expected \"SimpleItem\" or \"ComplexItem\"", path=path,
                                  item=k, field="type")
    items = [_simple_item(raw, path, k) for k, raw in flat]
    items = _resolve_jumps(items, [raw.get("doJumpId") for _, raw in flat], [k for k, _ in flat], path)
    return MissionPlan(
        tuple(items), *home_v,
        autopilot=_FIRMWARE_NAMES[fw],
        cruise_speed_m_s=_opt_speed(mission, "cruiseSpeed", path),
        hover_speed_m_s=_opt_speed(mission, "hoverSpeed", path),
        geofence_polygons=_geofence(doc.get("geoFence"), path),
        rally_points=_rally(doc.get("rallyPoints"), path),
        geofence_circles=_circles(doc.get("geoFence"), path),
    )


# MISSION_ITEM_INT.command is a uint16, .frame a uint8
_WIRE_MAX = {"command": 65535, "frame": 255}


def _expect(cond: bool, message: str, path: str, field: str, *, item: int | None = None) -> None:
    if not cond:
        raise FileFormatError(message, path=path, item=item, field=field)


def _num(v: Any, path: str, field: str, item: int | None, *, allow_null: bool = True) -> float:
    if v is None and allow_null:
        return math.nan
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise FileFormatError(f"must be a number{' or null' if allow_null else ''}, got {v!r}", path=path,
                              item=item, field=field)
    return float(v)


def _opt_speed(mission: dict, key: str, path: str) -> float | None:
    if key not in mission:
        return None
    v = _num(mission[key], path, f"mission.{key}", None, allow_null=False)
    _expect(v > 0, f"must be positive, got {v}", path, f"mission.{key}")
    return v


def _complex_items(raw: dict, path: str, k: int) -> list[dict]:
    kind = raw.get("complexItemType")
    transect = raw.get("TransectStyleComplexItem")
    if kind in ("survey", "CorridorScan"):
        if isinstance(transect, dict) and isinstance(transect.get("Items"), list):
            return transect["Items"]
        raise FileFormatError(
            f"this {kind} has no pre-expanded waypoints (TransectStyleComplexItem.Items, which QGroundControl "
            "writes since 3.4); open the plan in a current QGroundControl and save it again",
            path=path, item=k, field="TransectStyleComplexItem")
    raise FileFormatError(
        f"complex item {kind!r} is not supported (uavloc reads survey and CorridorScan items); convert it to "
        "simple waypoints in QGroundControl", path=path, item=k, field="complexItemType",
    )


def _item_params(raw: dict, path: str, k: int) -> list:
    """The 7 params of a SimpleItem, converting the older forms QGroundControl still loads:
    ``params`` of 4 plus ``coordinate`` [lat, lon, alt], and ``param1``..``param4`` keys."""
    params = raw.get("params")
    if params is None and all(f"param{i}" in raw for i in range(1, 5)):
        params = [raw[f"param{i}"] for i in range(1, 5)]
    if isinstance(params, list) and len(params) == 4 and "coordinate" in raw:
        coord = raw["coordinate"]
        _expect(isinstance(coord, list) and len(coord) == 3, "must be [lat, lon, alt] (3 entries, null allowed)",
                path, "coordinate", item=k)
        return params + coord
    _expect(isinstance(params, list) and len(params) == 7, "must be a list of exactly 7 numbers or nulls",
            path, "params", item=k)
    return params


def _simple_item(raw: dict, path: str, k: int) -> MissionItem:
    for key in ("command", "frame"):
        v = raw.get(key)
        _expect(isinstance(v, int) and not isinstance(v, bool) and v >= 0, f"must be a whole number, got {v!r}",
                path, key, item=k)
        top = _WIRE_MAX[key]
        _expect(v <= top, f"{v} does not fit MAVLink's {key} field (0..{top})", path, key, item=k)
    ac = raw.get("autoContinue")
    _expect(isinstance(ac, bool), f"must be true or false, got {ac!r}", path, "autoContinue", item=k)
    params = _item_params(raw, path, k)
    p = [_num(v, path, f"params[{i}]", k) for i, v in enumerate(params)]
    frame, command = raw["frame"], raw["command"]
    if frame in _ALT_MODE:
        # null lat/lon (both) is "where the vehicle is"; a half-set position is a mistake.
        _expect(math.isnan(p[4]) == math.isnan(p[5]), "latitude and longitude must both be numbers or both null",
                path, "params[4]", item=k)
        if not math.isnan(p[4]):
            _expect(-90.0 <= p[4] <= 90.0, f"latitude {p[4]} is outside -90..90 degrees", path, "params[4]", item=k)
            _expect(-180.0 <= p[5] <= 180.0, f"longitude {p[5]} is outside -180..180 degrees", path, "params[5]",
                    item=k)
        if command in POSITIONAL_COMMANDS and not math.isfinite(p[6]):
            if raw.get("AltitudeMode") == _ALT_MODE_CALC_ABOVE_TERRAIN:
                raise FileFormatError(
                    "the altitude is QGroundControl's 'calculated above terrain' and was never resolved to an "
                    "AMSL altitude (no terrain data when the plan was saved); open the plan in QGroundControl "
                    "with terrain data available and save it again, or use relative altitudes",
                    path=path, item=k, field="params[6]")
            raise FileFormatError(f"altitude must be a finite number, got {params[6]!r}", path=path, item=k,
                                  field="params[6]")
    for i in range(7):
        _expect(not math.isinf(p[i]), "must be finite", path, f"params[{i}]", item=k)
    return MissionItem(command, frame, (p[0], p[1], p[2], p[3]), p[4], p[5], p[6], ac)


def _resolve_jumps(items: list[MissionItem], jump_ids: list, numbers: list[int], path: str) -> list[MissionItem]:
    ids = {}
    for pos, jid in enumerate(jump_ids, start=1):
        if jid is not None:
            _expect(isinstance(jid, int) and not isinstance(jid, bool), f"must be a whole number, got {jid!r}",
                    path, "doJumpId", item=numbers[pos - 1])
            ids.setdefault(jid, pos)
    out = []
    for pos, it in enumerate(items, start=1):
        if it.command == DO_JUMP:
            target = it.params[0]
            if not (math.isfinite(target) and target.is_integer() and int(target) in ids):
                raise FileFormatError(f"DO_JUMP target {target!r} is not the doJumpId of any item", path=path,
                                      item=numbers[pos - 1], field="params[0]")
            it = MissionItem(it.command, it.frame, (float(ids[int(target)]), *it.params[1:]), it.lat_deg,
                             it.lon_deg, it.alt_m, it.autocontinue)
        out.append(it)
    return out


def _geofence(fence: Any, path: str) -> tuple:
    _expect(isinstance(fence, dict), "missing or not an object (QGroundControl requires it)", path, "geoFence")
    polys = fence.get("polygons", [])
    _expect(isinstance(polys, list), "must be a list", path, "geoFence.polygons")
    out = []
    for i, entry in enumerate(polys):
        field = f"geoFence.polygons[{i}]"
        _expect(isinstance(entry, dict), "must be an object", path, field)
        inc = entry.get("inclusion", True)
        _expect(isinstance(inc, bool), "must be true or false", path, f"{field}.inclusion")
        ring = entry.get("polygon")
        _expect(isinstance(ring, list) and len(ring) >= 3, "must be a list of at least 3 [lat, lon]", path,
                f"{field}.polygon")
        pts = []
        for j, v in enumerate(ring):
            _expect(isinstance(v, list) and len(v) == 2, f"vertex {j} must be [lat, lon]", path, f"{field}.polygon")
            lat = _num(v[0], path, f"{field}.polygon[{j}]", None, allow_null=False)
            lon = _num(v[1], path, f"{field}.polygon[{j}]", None, allow_null=False)
            _expect(-90 <= lat <= 90 and -180 <= lon <= 180, f"vertex {j} ({lat}, {lon}) is not a valid lat/lon",
                    path, f"{field}.polygon")
            pts.append((lat, lon))
        out.append((inc, tuple(pts)))
    return tuple(out)


def _circles(fence: dict, path: str) -> tuple:
    """``geoFence.circles``: ``{"circle": {"center": [lat, lon], "radius": m}, "inclusion": bool}``."""
    circles = fence.get("circles", [])
    _expect(isinstance(circles, list), "must be a list", path, "geoFence.circles")
    out = []
    for i, entry in enumerate(circles):
        field = f"geoFence.circles[{i}]"
        _expect(isinstance(entry, dict) and isinstance(entry.get("circle"), dict),
                'must be {"circle": {"center": [lat, lon], "radius": m}, "inclusion": true|false}', path, field)
        inc = entry.get("inclusion", True)
        _expect(isinstance(inc, bool), "must be true or false", path, f"{field}.inclusion")
        centre, radius = entry["circle"].get("center"), entry["circle"].get("radius")
        _expect(isinstance(centre, list) and len(centre) == 2, "must be [lat, lon]", path, f"{field}.circle.center")
        lat = _num(centre[0], path, f"{field}.circle.center", None, allow_null=False)
        lon = _num(centre[1], path, f"{field}.circle.center", None, allow_null=False)
        _expect(-90 <= lat <= 90 and -180 <= lon <= 180, f"({lat}, {lon}) is not a valid lat/lon", path,
                f"{field}.circle.center")
        r = _num(radius, path, f"{field}.circle.radius", None, allow_null=False)
        _expect(r > 0 and math.isfinite(r), f"must be a positive number of metres, got {radius!r}", path,
                f"{field}.circle.radius")
        out.append((inc, (lat, lon), r))
    return tuple(out)


def _rally(rally: Any, path: str) -> tuple:
    _expect(isinstance(rally, dict), "missing or not an object (QGroundControl requires it)", path, "rallyPoints")
    pts = rally.get("points", [])
    _expect(isinstance(pts, list), "must be a list", path, "rallyPoints.points")
    out = []
    for i, v in enumerate(pts):
        field = f"rallyPoints.points[{i}]"
        _expect(isinstance(v, list) and len(v) == 3, "must be [lat, lon, alt]", path, field)
        out.append(tuple(_num(x, path, field, None, allow_null=False) for x in v))
    return tuple(out)
