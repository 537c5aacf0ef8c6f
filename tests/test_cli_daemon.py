"""`uavloc daemon`: bad input and unreachable vehicles end in one clear sentence and a non-zero exit."""

import subprocess
import sys

import pytest

AREA = """name = "t"
[area]
origin_lat_deg = 42.625
origin_lon_deg = 13.283
width_m = 500
height_m = 300
[fleet]
vehicles = 2
"""


def _daemon(tmp_path, config_text, *extra):
    cfg = tmp_path / "mission.toml"
    cfg.write_text(config_text)
    return subprocess.run([sys.executable, "-m", "uavloc_gcs", "daemon", "--config", str(cfg),
                           "--out", str(tmp_path / "out"), *extra],
                          capture_output=True, text=True, timeout=60)


def _one_sentence(stderr):
    lines = [ln for ln in stderr.strip().splitlines() if ln.strip()]
    assert len(lines) == 1, stderr
    assert "Traceback" not in stderr
    return lines[0]


@pytest.mark.parametrize("body, words", [
    ("[area\n", ["mission.toml", "not valid TOML"]),
    ("", ["mission.toml", "link.connections", "no vehicle connections"]),
    ('[link]\nconnections = ["udpout:127.0.0.1:26801"]\n', ["link.connections", "1 connections for 2 vehicles"]),
    ('[link]\nconnections = ["udpout:127.0.0.1:26801", "carrier-pigeon:x"]\n', ["carrier-pigeon"]),
    ('[link]\nconnections = ["udpout:127.0.0.1:26801", "udpout:127.0.0.1:26802"]\nsigning_key_hex = "12"\n',
     ["link.signing_key_hex", "64 hexadecimal digits"]),
    ('[link]\nconnections = ["udpout:127.0.0.1:26801", "udpout:127.0.0.1:26802"]\nstart = "soon"\n',
     ["link.start", "'operator'"]),
])
def test_malformed_configs(tmp_path, body, words):
    text = ("[area\n" if body == "[area\n" else AREA + body)
    r = _daemon(tmp_path, text)
    assert r.returncode == 2, r.stderr
    line = _one_sentence(r.stderr)
    for w in words:
        assert w in line


def test_unreachable_vehicles_are_named(tmp_path):
    r = _daemon(tmp_path, AREA + '[link]\nconnections = ["udpout:127.0.0.1:26811", "udpout:127.0.0.1:26812"]\n',
                "--connect-timeout", "0.5")
    assert r.returncode == 3
    line = _one_sentence(r.stderr)
    assert "no heartbeat" in line and "1 (udpout:127.0.0.1:26811)" in line and "2 (udpout:127.0.0.1:26812)" in line


def test_missing_config_file(tmp_path):
    r = subprocess.run([sys.executable, "-m", "uavloc_gcs", "daemon", "--config", str(tmp_path / "nope.toml")],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "nope.toml" in _one_sentence(r.stderr) and "not found" in r.stderr
