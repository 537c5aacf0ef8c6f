"""Signing against the real autopilots: a signed uavloc link to a vehicle that does not sign says
"heard only unsigned packets" (both autopilots, fresh; the PX4 build has no signing), and an
ArduCopter given the key with SETUP_SIGNING on serial1 is heard through a signed link there.
(ArduPilot always accepts unsigned packets on its channel 0, so signing is tested on serial1.)"""

from __future__ import annotations

import asyncio
import time

import pytest

from uavloc_gcs.link import open_link

from . import harness
from .test_flight import uavloc

KEY_HEX = "5a" * 32
SIGNING_EPOCH_UNIX_S = 1420070400


@pytest.mark.parametrize("kind", ["ardupilot", "px4"])
def test_signed_link_to_unsigned_vehicle_says_so(kind, sitl, tmp_path):
    proc = sitl(kind)
    r = uavloc("download", "--from", proc.connection, "--out", str(tmp_path / "m.plan"), "--signing-key", KEY_HEX,
               "--timeout", "4")
    assert r.returncode == 3, r.stderr
    assert "heard only unsigned packets" in r.stderr, r.stderr
    assert not (tmp_path / "m.plan").exists()


def test_ardupilot_signing_on_serial1(sitl):
    import socket
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    proc = sitl("ardupilot", serial1=f"udpclient:127.0.0.1:{port}")
    key = bytes.fromhex(KEY_HEX)

    async def go():
        async with await open_link(f"udpin:127.0.0.1:{port}") as plain:
            await plain.wait_heartbeat(proc.sysid, timeout_s=20)
            stamp = int((time.time() - SIGNING_EPOCH_UNIX_S) * 1e5)
            for _ in range(3):
                await plain.send(plain.mav.setup_signing_encode(proc.sysid, 1, key, stamp))
                await asyncio.sleep(0.3)
        await asyncio.sleep(0.5)  # let the closed socket go before binding its port again
        async with await open_link(f"udpin:127.0.0.1:{port}", signing_key=key) as signed:
            hb = await signed.wait_heartbeat(proc.sysid, timeout_s=20)
            return hb._signed, signed.stats
    signed_hb, stats = harness.run(go(), 90)
    assert signed_hb and stats.rx_packets > 0
