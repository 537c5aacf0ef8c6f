"""The [link] section of a mission config: connections per vehicle, signing key, start mode."""

import pytest

from uavloc_gcs.errors import ConfigError
from uavloc_gcs.scenario import loads_scenario

AREA = """
[area]
origin_lat_deg = 42.625
origin_lon_deg = 13.283
width_m = 500
height_m = 300
[fleet]
vehicles = 2
"""


def test_link_section_is_read():
    sc = loads_scenario(AREA + """
[link]
connections = ["udpout:127.0.0.1:26001", "udpout:127.0.0.1:26002"]
signing_key_hex = "%s"
start = "operator"
lost_timeout_s = 3.0
""" % ("ab" * 32))
    assert sc.link.connections == ["udpout:127.0.0.1:26001", "udpout:127.0.0.1:26002"]
    assert sc.link.start == "operator" and sc.link.lost_timeout_s == 3.0
    assert bytes.fromhex(sc.link.signing_key_hex) == b"\xab" * 32


def test_default_link_section():
    sc = loads_scenario(AREA)
    assert sc.link.connections is None and sc.link.signing_key_hex == "" and sc.link.start == "auto"
    assert sc.link.source_system == 245  # not QGroundControl's 255: both can talk to the vehicles
    assert sc.link.rssi_connections is None and sc.link.set_speed_params is False


def test_rssi_connections_and_speed_consent_are_read():
    sc = loads_scenario(AREA + """
[link]
rssi_connections = ["udpin:127.0.0.1:26101", ""]
set_speed_params = true
""")
    assert sc.link.rssi_connections == ["udpin:127.0.0.1:26101", ""] and sc.link.set_speed_params is True


@pytest.mark.parametrize("body, key", [
    ('connections = ["udpout:127.0.0.1:26001"]', "link.connections"),
    ('connections = ["udpout:127.0.0.1:26001", 5]', "link.connections"),
    ('signing_key_hex = "xyz"', "link.signing_key_hex"),
    ('signing_key_hex = "abcd"', "link.signing_key_hex"),
    ('start = "now"', "link.start"),
    ('lost_timeout_s = 0', "link.lost_timeout_s"),
    ('bogus = 1', "link.bogus"),
    ('rssi_connections = ["udpin:127.0.0.1:26101"]', "link.rssi_connections"),
    ('rssi_connections = ["", 3]', "link.rssi_connections"),
    ('set_speed_params = "yes"', "link.set_speed_params"),
])
def test_bad_link_values_name_the_key(body, key):
    with pytest.raises(ConfigError) as err:
        loads_scenario(AREA + "[link]\n" + body + "\n", source="mission.toml")
    assert f"'{key}'" in str(err.value) and "mission.toml" in str(err.value)
