import asyncio
import math

import pytest

from uavloc_gcs.mission import flight_mission, to_wire


def run(coro, timeout_s: float = 60.0):
    """Run ``coro`` on a fresh event loop with an overall deadline."""
    async def bounded():
        async with asyncio.timeout(timeout_s):
            return await coro
    return asyncio.run(bounded())


def survey_items(n_waypoints: int, autopilot: str, *, seed: int = 0):
    """A realistic uavloc mission (takeoff, speed, n pass-through waypoints, RTL) as WireItems."""
    pts = [(47.3977 + 0.0001 * ((i * 7 + seed) % 50), 8.5456 + 0.0001 * (i // 50) + 1e-7 * i) for i in range(n_waypoints)]
    plan = flight_mission(pts, alt_m=30.0, speed_m_s=8.0, autopilot=autopilot, home_latlon_deg=(47.3977, 8.5456),
                          home_alt_amsl_m=488.0)
    return to_wire(plan, autopilot)


@pytest.fixture
def items_px4():
    return survey_items(20, "px4")


def identical(a, b) -> bool:
    """Field-by-field equality of WireItem lists, NaN equal to NaN, floats compared as float32."""
    import dataclasses
    import struct

    def norm(v):
        if isinstance(v, float):
            return "nan" if math.isnan(v) else struct.unpack("<f", struct.pack("<f", v))[0]
        return v
    return len(a) == len(b) and all(
        tuple(map(norm, dataclasses.astuple(x))) == tuple(map(norm, dataclasses.astuple(y))) for x, y in zip(a, b))
