"""``uavloc sim`` as a user runs it: ports printed, vehicles answering, Ctrl-C ends it cleanly."""

from __future__ import annotations

import signal
import socket
import subprocess
import sys
import time

import pytest

from uavloc_gcs.dialect import mavlink as mav

BASE = 24300


def test_sim_prints_ports_serves_and_stops_on_ctrl_c():
    proc = subprocess.Popen([sys.executable, "-m", "uavloc_gcs", "sim", "examples/small.toml", "--base-port",
                             str(BASE), "--speedup", "20", "--seed", "4", "--status-s", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        lines = []
        deadline = time.time() + 20
        while time.time() < deadline:
            line = proc.stdout.readline()
            lines.append(line)
            if "Ctrl-C" in line or not line:
                break
        text = "".join(lines)
        assert f"uav1: MAVLink system 1, UDP port {BASE + 1}" in text
        assert f"uav2: MAVLink system 2, UDP port {BASE + 2}  (connect: udpout:127.0.0.1:{BASE + 2})" in text
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.settimeout(3.0)
        codec = mav.MAVLink(None, 255, 190)
        s.sendto(codec.heartbeat_encode(6, 8, 0, 0, 0).pack(codec), ("127.0.0.1", BASE + 2))
        msg = codec.parse_buffer(s.recvfrom(4096)[0])[0]
        assert msg.get_srcSystem() == 2
        s.close()
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            out, err = proc.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()  # never leave it holding the ports for the rest of the suite
            proc.communicate()
            raise
    assert proc.returncode == 0, err
    assert "stopped" in out


def test_sim_bad_input_is_one_sentence_and_exit_2():
    r = subprocess.run([sys.executable, "-m", "uavloc_gcs", "sim", "examples/small.toml", "--signing-key", "abc"],
                       capture_output=True, text=True, timeout=30)
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0 and "--signing-key" in r.stderr and "64 hexadecimal" in r.stderr
    from uavloc_gcs.cli import build_parser
    from uavloc_gcs.errors import ConfigError

    r = subprocess.run([sys.executable, "-m", "uavloc_gcs", "sim", "examples/small.toml", "--loss", "1.5"],
                       capture_output=True, text=True, timeout=30)  # refused by the flag's own range check
    assert r.returncode == 2 and r.stderr.strip().count("\n") == 0 and "--loss" in r.stderr
    for argv, key in ((["--companion"], "--autopilot"),
                      (["--companion", "--autopilot", "serial:/dev/x"], "autopilot")):
        args = build_parser().parse_args(["sim", "examples/small.toml", *argv])
        with pytest.raises(ConfigError) as err:
            args.func(args)
        assert err.value.key == key


def test_sim_port_in_use_is_a_link_error():
    blocker = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    blocker.bind(("127.0.0.1", BASE + 51))
    try:
        r = subprocess.run([sys.executable, "-m", "uavloc_gcs", "sim", "examples/small.toml", "--base-port",
                            str(BASE + 50)], capture_output=True, text=True, timeout=30)
    finally:
        blocker.close()
    assert r.returncode == 3 and "uav1" in r.stderr and str(BASE + 51) in r.stderr
