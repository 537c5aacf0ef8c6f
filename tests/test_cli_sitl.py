"""``uavloc sitl`` without autopilots: bad input answered in one sentence naming the flag (exit 2),
nothing started and nothing written; the mission file it writes is a scenario the daemon reads.
(Starting real autopilots: tests/sitl/test_sitl_command.py.)"""

from __future__ import annotations

import socket
import tomllib
from pathlib import Path

import pytest

from uavloc_gcs.cli import main
from uavloc_gcs.scenario import load_scenario, loads_scenario
from uavloc_gcs.service import sitl, sitl_fleet

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = str(ROOT / "examples" / "sitl_arducopter.toml")


@pytest.mark.parametrize("argv, flag, words", [
    (["-n", "0"], "--vehicles", "out of range"),
    (["-n", "11"], "--vehicles", "out of range"),
    (["--speedup", "nan"], "--speedup", "speed-up"),
    (["--speedup", "-1"], "--speedup", "speed-up"),
    (["--base-port", "80"], "--base-port", "no room"),
    (["--home-alt", "inf"], "--home-alt", "altitude"),
    (["--ready-timeout", "0"], "--ready-timeout", "> 0"),
    (["--out", "/nonexistent-dir/m.toml"], "--out", "does not exist"),
    (["--sitl-dir", "/nonexistent-dir"], "--sitl-dir", "holds no ArduCopter SITL binary"),
    (["--autopilot", "px4", "--sitl-dir", "/nonexistent-dir"], "--sitl-dir", "holds no PX4 SITL build"),
])
def test_bad_input_is_one_sentence_naming_the_flag(argv, flag, words, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code = main(["sitl", SCENARIO, *argv])
    err = capsys.readouterr().err
    assert code == 2, err
    assert flag in err and words in err, err
    assert "Traceback" not in err and err.count("\n") == 1, err
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_no_build_anywhere_says_where_it_looked(capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("UAVLOC_SITL_DIR", str(tmp_path / "none"))
    monkeypatch.setattr(sitl, "checkout_sitl_dir", lambda: tmp_path / "none2")
    monkeypatch.chdir(tmp_path)
    assert main(["sitl", SCENARIO, "--autopilot", "px4"]) == 2
    err = capsys.readouterr().err
    assert "--sitl-dir" in err and str(tmp_path / "none") in err and "no PX4 SITL build" in err


def test_a_busy_base_port_is_named_and_nothing_is_started(capsys):
    if sitl.arducopter_in(sitl.checkout_sitl_dir()) is None:
        pytest.skip("needs the ArduCopter build at ../shared/sitl to get past the build check")
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        busy = s.getsockname()[1]
        code = main(["sitl", SCENARIO, "-n", "2", "--base-port", str(busy - 1)])
    err = capsys.readouterr().err
    assert code == 2 and "on 127.0.0.1 is busy" in err and "--base-port" in err, err  # busy (or busy - 1)
    assert not sitl._LIVE


class _Fake:
    def __init__(self, sysid, kind, conn, rssi=""):
        self.sysid, self.connection, self.daemon_rssi = sysid, conn, rssi
        self.sitl = type("S", (), {"kind": kind, "instance": sysid + 4})()


def test_the_mission_file_is_the_scenario_with_fleet_and_link_set(tmp_path):
    src = ROOT / "examples" / "field.toml"
    vs = [_Fake(1, "px4", "udpin:127.0.0.1:40001", "udpin:127.0.0.1:40011"),
          _Fake(2, "px4", "udpin:127.0.0.1:40002", "udpin:127.0.0.1:40012")]
    text = sitl_fleet.mission_text(src.read_text(), vs, autopilot="px4", source=str(src), base_dir=src.parent)
    (tmp_path / "m.toml").write_text(text)
    sc = load_scenario(tmp_path / "m.toml")
    orig = load_scenario(src)
    assert sc.fleet.vehicles == 2 and sc.fleet.autopilot == "px4"
    assert sc.link.connections == ["udpin:127.0.0.1:40001", "udpin:127.0.0.1:40002"]
    assert sc.link.rssi_connections == ["udpin:127.0.0.1:40011", "udpin:127.0.0.1:40012"]
    # everything else as the scenario says: the same world, area and launch point
    assert tomllib.loads(text)["emission"] == tomllib.loads(src.read_text())["emission"]
    assert sc.launch_latlon_deg == orig.launch_latlon_deg and sc.simulation == orig.simulation
    block = sitl_fleet.link_block(vs)
    assert loads_scenario(src.read_text().replace("[fleet]\nvehicles = 4", "[fleet]\nvehicles = 2") + "\n" + block
                          ).link.connections == sc.link.connections
