"""Parameters over real MAVLink (the fake vehicles answer PARAM_REQUEST_READ / PARAM_SET), and the
speed limits the daemon plans with."""

from pathlib import Path

import pytest

from sim_link.vehicles.fleet import FakeFleet
from uavloc_gcs.link import flavour_named, open_link
from uavloc_gcs.link.params import SpeedLimits, raise_speed_limits, read_param, speed_limits

from .conftest import run

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"


def _scenario(autopilot, speed):
    from uavloc_gcs.scenario import load_scenario

    return load_scenario(EXAMPLES / "small.toml").replace(fleet={"autopilot": autopilot, "vehicles": 1,
                                                                  "speed_m_s": speed})


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_speed_limits_are_read_and_raised_with_consent(autopilot):
    sc = _scenario(autopilot, 8.0)

    async def go():
        async with FakeFleet(sc, speedup=1, seed=3, base_port=0) as fleet:
            async with await open_link(fleet.endpoints[0][1], source_system=245) as link:
                await link.wait_heartbeat(1, timeout_s=10)
                flavour = flavour_named(autopilot)
                before = await speed_limits(link, 1, flavour)
                unknown = await read_param(link, 1, 1, "NO_SUCH_PARAM", timeout_s=0.3, retries=1)
                after = await raise_speed_limits(link, 1, flavour, 14.0)
                return before, unknown, after, fleet.vehicle(1).speed_m_s

    before, unknown, after, flown = run(go(), timeout_s=60)
    assert before.max_m_s == pytest.approx(8.0 if autopilot == "ardupilot" else 12.0)
    assert before.rtl_m_s == pytest.approx(8.0)  # RTL_SPEED 0 = WPNAV_SPEED; PX4 returns at cruise
    assert unknown is None
    assert after.mission_speed(25.0) == pytest.approx(14.0) and after.return_speed(25.0) == pytest.approx(14.0)
    assert flown == pytest.approx(14.0)  # the fake flies the new value


def test_speed_limits_cap_the_wanted_speed():
    lim = SpeedLimits(10.0, 7.0, "")
    assert lim.mission_speed(25.0) == 10.0 and lim.mission_speed(6.0) == 6.0 and lim.return_speed(25.0) == 7.0
    unknown = SpeedLimits(None, None, "")
    assert unknown.mission_speed(25.0) == 25.0 and unknown.return_speed(25.0) == 25.0
