"""Hypothesis strategies for mission plans (shared by the format round-trip tests)."""

import math

from hypothesis import strategies as st

from uavloc_gcs import mission as M

finite = st.floats(allow_nan=False, allow_infinity=False, width=64, min_value=-1e7, max_value=1e7)
param = st.one_of(finite, st.just(math.nan))
lat = st.floats(min_value=-89.999, max_value=89.999, allow_nan=False)
lon = st.floats(min_value=-180.0, max_value=180.0, allow_nan=False)
alt = st.floats(min_value=-500.0, max_value=10000.0, allow_nan=False)

positional = st.builds(
    M.MissionItem,
    command=st.sampled_from([M.NAV_WAYPOINT, M.NAV_TAKEOFF, M.NAV_LAND, M.NAV_LOITER_TIME]),
    frame=st.sampled_from([M.FRAME_GLOBAL, M.FRAME_GLOBAL_RELATIVE_ALT, M.FRAME_GLOBAL_TERRAIN_ALT]),
    params=st.tuples(param, param, param, param),
    lat_deg=lat, lon_deg=lon, alt_m=alt, autocontinue=st.booleans(),
)
non_positional = st.builds(
    M.MissionItem,
    command=st.sampled_from([M.DO_CHANGE_SPEED, M.NAV_RETURN_TO_LAUNCH, 183, 203]),
    frame=st.just(M.FRAME_MISSION),
    params=st.tuples(param, param, param, param),
    lat_deg=param, lon_deg=param, alt_m=param, autocontinue=st.booleans(),
)
items = st.lists(st.one_of(positional, non_positional), max_size=12).map(tuple)
radius = st.floats(min_value=0.5, max_value=1e5)
ring = st.lists(st.tuples(lat, lon), min_size=3, max_size=6).map(tuple)


@st.composite
def plans(draw, *, home_alt_finite=False, extras=True):
    has_home = draw(st.booleans())
    home = (draw(lat), draw(lon), draw(alt if home_alt_finite else st.one_of(alt, st.just(math.nan)))) \
        if has_home else (math.nan, math.nan, math.nan)
    if has_home and home[0] == 0.0 and home[1] == 0.0:
        home = (0.5, home[1], home[2])
    speed = st.one_of(st.none(), st.floats(min_value=0.5, max_value=60.0))
    return M.MissionPlan(
        draw(items), *home,
        autopilot=draw(st.sampled_from(["ardupilot", "px4"])),
        cruise_speed_m_s=draw(speed) if extras else None,
        hover_speed_m_s=draw(speed) if extras else None,
        geofence_polygons=draw(st.lists(st.tuples(st.booleans(), ring), max_size=2).map(tuple)) if extras else (),
        rally_points=draw(st.lists(st.tuples(lat, lon, alt), max_size=3).map(tuple)) if extras else (),
        geofence_circles=draw(st.lists(st.tuples(st.booleans(), st.tuples(lat, lon), radius), max_size=2)
                              .map(tuple)) if extras else (),
    )


def plans_equal(a: M.MissionPlan, b: M.MissionPlan) -> bool:
    """Exact equality with NaN == NaN."""
    def same(x, y):
        if isinstance(x, float) and isinstance(y, float):
            return (math.isnan(x) and math.isnan(y)) or x == y
        if isinstance(x, (tuple, list)) and isinstance(y, (tuple, list)):
            return len(x) == len(y) and all(same(u, v) for u, v in zip(x, y))
        if isinstance(x, M.MissionItem):
            return all(same(getattr(x, f), getattr(y, f)) for f in x.__dataclass_fields__)
        return x == y
    return all(same(getattr(a, f), getattr(b, f)) for f in a.__dataclass_fields__)
