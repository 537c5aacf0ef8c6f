"""``uavloc sense CAPTURE --mavlink URL``: real MAVLink 2 over UDP to a fake autopilot whose clock is
7 s ahead of the companion's and whose boot clock started long ago. The batches must carry the
autopilot's time (TIMESYNC + SYSTEM_TIME), its positions, and every frame of the capture."""

import socket
import threading
import time

import numpy as np
import pytest

from uavloc_gcs.cli import main
from uavloc_gcs.dialect import mavlink
from uavloc_gcs.dialect.rssi import COMPANION_COMPONENT_ID, decode_rssi_batch
from uavloc_gcs.geo import LocalFrame
from uavloc_gcs.sense import parse_capture_bytes
from uavloc_gcs.sense.synth import synthetic_capture

AHEAD_S = 7.0  # the autopilot's UNIX time minus the companion's
BOOT_AT_S = 500.0  # the autopilot's boot clock when the test starts
SPEED_E_M_S = 10.0
ORIGIN = (47.0, 8.0)


class FakeAutopilot(threading.Thread):
    """ArduCopter-like: HEARTBEAT and SYSTEM_TIME at 1 Hz, GLOBAL_POSITION_INT at 10 Hz (flying east
    at 10 m/s, 50 m up), TIMESYNC answered; records what the companion sends."""

    def __init__(self, key: bytes | None = None):
        super().__init__(daemon=True)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.02)
        self.port = self.sock.getsockname()[1]
        self.codec = mavlink.MAVLink(None, srcSystem=7, srcComponent=1)
        self.rx = mavlink.MAVLink(None)
        self.rx.robust_parsing = True
        if key is not None:  # sign what it sends, drop what is not signed with the key
            self.codec.signing.secret_key = key
            self.codec.signing.sign_outgoing = True
            self.codec.signing.timestamp = int((time.time() - 1420070400) * 1e5)
            self.rx.signing.secret_key = key
        self.mono0 = time.monotonic()
        self.unix0 = time.time() + AHEAD_S  # the autopilot's UNIX time when its boot clock read BOOT_AT_S
        self.frame = LocalFrame(*ORIGIN)
        self.got = []  # (message, autopilot unix time at receipt)
        self.timesyncs = 0
        self.stop = threading.Event()

    def boot_s(self):
        return time.monotonic() - self.mono0 + BOOT_AT_S

    def unix_s(self):
        return time.time() + AHEAD_S

    def _send(self, msg, peer):
        self.sock.sendto(msg.pack(self.codec), peer)
        self.codec.seq = (self.codec.seq + 1) % 256

    def run(self):
        peer, next_slow, next_pos = None, 0.0, 0.0
        while not self.stop.is_set():
            try:
                data, peer = self.sock.recvfrom(4096)
                for m in self.rx.parse_buffer(data) or []:
                    if m.get_type() == "TIMESYNC" and m.tc1 == 0:
                        self.timesyncs += 1
                        self._send(self.codec.timesync_encode(int(self.boot_s() * 1e9), m.ts1), peer)
                    elif m.get_type() == "UAVLOC_RSSI_BATCH2":
                        self.got.append((m, self.unix_s()))
            except socket.timeout:
                pass
            if peer is None:
                continue
            now = time.monotonic()
            if now >= next_slow:
                next_slow = now + 1.0
                self._send(self.codec.heartbeat_encode(2, 3, 0, 0, 4), peer)
                self._send(self.codec.system_time_encode(int(self.unix_s() * 1e6), int(self.boot_s() * 1e3)), peer)
            if now >= next_pos:
                next_pos = now + 0.1
                boot = self.boot_s()
                lat, lon = self.frame.to_wgs84(SPEED_E_M_S * (boot - BOOT_AT_S), 0.0)
                self._send(self.codec.global_position_int_encode(int(boot * 1e3), int(lat * 1e7), int(lon * 1e7),
                                                                 550000, 50000, 0, 1000, 0, 0), peer)


@pytest.mark.parametrize("signed", [False, True], ids=["unsigned", "signed"])
def test_replay_to_a_fake_autopilot_in_its_clock(tmp_path, signed):
    buf, truth = synthetic_capture(150, n_phones=4, rng=np.random.default_rng(2))
    (tmp_path / "c.pcap").write_bytes(buf)
    key = bytes(range(32)) if signed else None
    ap = FakeAutopilot(key)
    ap.start()
    try:
        rc = main(["sense", str(tmp_path / "c.pcap"), "--mavlink", f"udpout:127.0.0.1:{ap.port}"]
                  + (["--signing-key", key.hex()] if signed else []))
        time.sleep(0.3)
    finally:
        ap.stop.set()
        ap.join(timeout=5)
    assert rc == 0
    assert ap.got, "no UAVLOC_RSSI_BATCH2 arrived"
    assert ap.timesyncs >= 1
    msgs = [m for m, _ in ap.got]
    assert all(bool(getattr(m, "_signed", False)) == signed for m in msgs)
    assert {m.get_srcSystem() for m in msgs} == {7}  # the autopilot's system id
    assert {m.get_srcComponent() for m in msgs} == {COMPANION_COMPONENT_ID}
    slots = [decode_rssi_batch(m, ap.frame) for m in msgs]
    # every frame of the capture arrives, counted under its address
    frames, _ = parse_capture_bytes(buf)
    sent = {}
    for s in slots:
        for a, n in zip(s.address.tolist(), s.n_samples.tolist()):
            sent[a] = sent.get(a, 0) + n
    want = dict(zip(*np.unique(frames.address, return_counts=True)))
    assert sent == {int(k): int(v) for k, v in want.items()}
    # time_usec is the autopilot's UNIX time: each batch arrives shortly after its first slot
    # (a companion clock used as is would be 7 s off)
    lags = [t_rx - m.time_usec / 1e6 for m, t_rx in ap.got]
    assert min(lags) > -0.1 and max(lags) < 1.5, lags
    # and the positions are where the autopilot was then (east = 10 m/s * boot time)
    for s in slots:
        assert np.all(np.abs(s.xyz_m[:, 2] - 50.0) < 0.01) and np.all(np.abs(s.xyz_m[:, 1]) < 0.5)
        east_then = SPEED_E_M_S * (s.t_s - ap.unix0)
        assert np.all(np.abs(s.xyz_m[:, 0] - east_then) < 2.0), (s.xyz_m[:, 0], east_then)
