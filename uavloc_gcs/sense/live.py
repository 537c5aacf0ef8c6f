"""Where frames come from while the sensor runs: live monitor-mode interfaces or a paced replay.

Live capture uses libpcap through pcapy-ng (a maintained fork of pcapy: releases through 2026,
wheels with libpcap inside), imported only when an interface is given. Each interface is read by
its own thread (libpcap's read blocks) with the BPF filter ``type mgt subtype probe-req`` so the
kernel drops everything else; records are stamped by the kernel (UNIX time). Channel hopping, when
asked, runs ``iw dev IFACE set channel CH`` on the one given interface every dwell time: the
sensor never touches an interface it was not given.

Every failure to open (binding missing, no such device, no permission, not in monitor mode) is a
:class:`~uavloc_gcs.errors.ConfigError` of one sentence naming the interface.
"""

from __future__ import annotations

import logging
import shutil
import subprocess
import threading
import time
from collections import deque

from ..errors import ConfigError
from .capture import ReadStats, Record, read_capture_file, read_records

log = logging.getLogger(__name__)

BPF_FILTER = "type mgt subtype probe-req"
SNAPLEN = 2048
READ_TIMEOUT_MS = 100
MONITOR_LINKTYPES = (105, 127, 192)  # bare 802.11, radiotap, PPI


def _import_pcapy():
    try:
        import pcapy  # pcapy-ng
    except ImportError:
        raise ConfigError("live capture needs the libpcap binding pcapy-ng, which is not installed: "
                          "pip install 'uavloc[sense]'", key="--interface") from None
    return pcapy


class LiveInterface:
    """One monitor-mode interface read by a thread; :meth:`poll` hands over what arrived."""

    def __init__(self, name: str):
        pcapy = _import_pcapy()
        self.name = name
        try:
            self._pcap = pcapy.open_live(name, SNAPLEN, 1, READ_TIMEOUT_MS)
        except pcapy.PcapError as err:
            text = str(err)
            if "ermission" in text or "not permitted" in text:
                why = "permission denied (run as root, or give the interpreter cap_net_raw,cap_net_admin with setcap)"
            elif "No such device" in text or "doesn't exist" in text:
                why = "no such interface (see 'iw dev')"
            else:
                why = text.strip().rstrip(".")
            raise ConfigError(f"cannot capture on {name}: {why}", key="--interface") from None
        self.linktype = self._pcap.datalink()
        if self.linktype not in MONITOR_LINKTYPES:
            self._pcap.close() if hasattr(self._pcap, "close") else None
            raise ConfigError(f"{name} is not in monitor mode (link type {self.linktype}, expected radiotap 127): "
                              f"'iw dev {name} set type monitor' while it is down", key="--interface")
        try:
            self._pcap.setfilter(BPF_FILTER)
        except pcapy.PcapError:
            log.warning("%s: the BPF filter '%s' was refused; every frame is read", name, BPF_FILTER)
        self._queue: deque[Record] = deque()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read, name=f"pcap {name}", daemon=True)
        self._thread.start()

    def _read(self) -> None:
        lt = self.linktype
        q = self._queue

        def on_packet(header, data):
            sec, usec = header.getts()
            q.append((lt, sec + usec * 1e-6, bytes(data), header.getcaplen() < header.getlen()))

        while not self._stop.is_set():
            try:
                self._pcap.dispatch(64, on_packet)
            except Exception as err:  # the interface went away: report once and stop reading
                log.error("capture on %s stopped: %s", self.name, err)
                return

    def poll(self) -> list[Record]:
        out = []
        q = self._queue
        while q:
            out.append(q.popleft())
        return out

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=1.0)


class ChannelHopper:
    """Moves ONE interface over ``plan`` [(channel, dwell_s), ...] in turn, with ``iw`` (a thread)."""

    def __init__(self, iface: str, plan: list[tuple[int, float]]):
        self.iw = shutil.which("iw")
        if self.iw is None:
            raise ConfigError("--channels needs the 'iw' tool (apt install iw)", key="--channels")
        self.iface, self.plan = iface, plan
        self._stop = threading.Event()
        self._set(plan[0][0], check=True)
        self._thread = threading.Thread(target=self._hop, name=f"hop {iface}", daemon=True)
        self._thread.start()

    def _set(self, ch: int, *, check: bool = False) -> None:
        r = subprocess.run([self.iw, "dev", self.iface, "set", "channel", str(ch)], capture_output=True, text=True)
        if r.returncode and check:
            raise ConfigError(f"cannot set {self.iface} to channel {ch}: {r.stderr.strip() or r.returncode}",
                              key="--channels")

    def _hop(self) -> None:
        k = 0
        while not self._stop.wait(self.plan[k][1]):
            k = (k + 1) % len(self.plan)
            self._set(self.plan[k][0])

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=1.0)


class ReplaySource:
    """A capture file replayed at its own pace, its times moved to now (for tests and demos)."""

    def __init__(self, path: str, stats: ReadStats, *, speed: float = 1.0):
        self.records = list(read_records(read_capture_file(path), stats, path=path))
        self.speed = speed
        self._k = 0
        self._start = time.time()
        self._t0 = self.records[0][1] if self.records else 0.0

    def restart(self) -> None:
        self._k = 0
        self._start = time.time()

    @property
    def done(self) -> bool:
        return self._k >= len(self.records)

    def poll(self) -> list[Record]:
        now = time.time()
        horizon = (now - self._start) * self.speed
        out = []
        recs = self.records
        while self._k < len(recs) and recs[self._k][1] - self._t0 <= horizon:
            lt, t, data, snapped = recs[self._k]
            out.append((lt, self._start + (t - self._t0) / self.speed, data, snapped))
            self._k += 1
        return out

    def close(self) -> None:
        pass


def parse_channels(text: str, default_dwell_s: float) -> list[tuple[int, float]]:
    """``1,6,11`` (each ``default_dwell_s``) or ``1:400,6:200,11:200`` (dwell in ms per channel)."""
    plan = []
    for item in text.split(","):
        ch, _, dwell = item.strip().partition(":")
        try:
            plan.append((int(ch), float(dwell) / 1000.0 if dwell else default_dwell_s))
        except ValueError:
            plan = []
            break
    if not plan or any(not 1 <= c <= 233 or not 0 < d <= 60 for c, d in plan):
        raise ConfigError(f"--channels must be channel numbers 1-233, each optionally with a dwell of up to 60000 ms "
                          f"(1,6,11 or 1:400,6:200,11:200), got {text!r}", key="--channels")
    return plan
