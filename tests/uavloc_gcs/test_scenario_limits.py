"""Issue 40 item 4: absurd scenario values are refused with the key and the plausible range; every
shipped scenario is plausible; scenarios built in code (a notional unlimited budget) are not
checked."""

from pathlib import Path

import pytest

from uavloc_gcs.errors import ConfigError
from uavloc_gcs.scenario import load_scenario, loads_scenario
from uavloc_gcs.scenario_limits import LIMITS

BASE = "[area]\norigin_lat_deg = 47.0\norigin_lon_deg = 8.0\nwidth_m = 400\nheight_m = 300\n"


def _with(key: str, value) -> str:
    section, name = key.split(".")
    return BASE + f"[{section}]\n{name} = {value}\n"


@pytest.mark.parametrize("key, value, needles", [
    ("fleet.comm_range_m", "1e9", ["1e+09 m is not plausible (give at most 5000 m)", "Wi2SAR"]),
    ("fleet.energy_budget_j", "1e308", ["1e+308 J is not plausible (give at most 20,000,000 J)", "168 W", "33 h"]),
    ("fleet.altitude_m", "1e-9", ["give 5-1000 m"]),
    ("channel.path_loss_exponent", "0.5", ["give 1-8", "Rappaport"]),
    ("channel.slot_s", "0.1", ["give at most 0.065535 s", "16-bit count of microseconds"]),
    ("channel.samples_per_slot", "1000", ["give at most 255", "one byte"]),
    ("simulation.people", "100000000", ["give at most 1000"]),
    ("simulation.seed", "-5", ["give 0-4,294,967,295"]),
    ("planner.time_limit_s", "1e300", ["give at most 600 s"]),
])
def test_absurd_values_name_the_key_and_the_plausible_range(key, value, needles):
    with pytest.raises(ConfigError) as caught:
        loads_scenario(_with(key, value), source="s.toml")
    msg = str(caught.value)
    assert msg.startswith(f"s.toml, key '{key}': "), msg
    for n in needles:
        assert n in msg, (n, msg)
    assert len(msg) < 400 and "\n" not in msg


def _doc(key: str, value) -> str:
    text = _with(key, value)
    if key == "fleet.altitude_m":
        text = text.replace("[fleet]\n", "[fleet]\ncomm_range_m = 2000\n")  # the range must exceed the altitude
    return text


@pytest.mark.parametrize("lim", LIMITS, ids=lambda lim: lim.key)
def test_each_limit_takes_its_edges_and_refuses_a_step_beyond(lim):
    """So each limit is really applied, and where it says."""
    from typing import get_type_hints

    from uavloc_gcs import scenario as scenario_module

    section, name = lim.key.split(".")
    whole = get_type_hints(scenario_module._SECTIONS[section])[name] is int
    for edge, outward in ((lim.low, -1), (lim.high, +1)):
        if edge is None:
            continue
        loads_scenario(_doc(lim.key, int(edge) if whole else float(edge)))
        beyond = int(edge) + outward if whole else float(edge) * (1 + 1e-3 * outward) + 1e-9 * outward
        with pytest.raises(ConfigError, match=f"key '{lim.key}': .* is not plausible"):
            loads_scenario(_doc(lim.key, beyond))


def test_every_shipped_scenario_is_plausible():
    from uavloc_gcs.examples import scenario_names

    for name in scenario_names():
        load_scenario(name)
    for path in (Path(__file__).resolve().parents[2] / "benchmarks" / "scenarios").glob("*.toml"):
        load_scenario(path)


def test_code_may_build_a_notional_unlimited_budget():
    """search/pod_plan lays out lanes with energy_budget_j = 1e12 (no energy limit): replace() is
    not a file and is not checked for plausibility."""
    sc = load_scenario("paper").replace(fleet={"energy_budget_j": 1e12})
    assert sc.fleet.energy_budget_j == 1e12
