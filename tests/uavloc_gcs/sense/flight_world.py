"""A recorded flight and what its sensor heard, built independently of the sensor's code.

The flight: a lawnmower over the small scenario's area (lanes 100 m apart, its altitude and speed),
logged as a ``.tlog`` of HEARTBEAT, SYSTEM_TIME (1 Hz) and GLOBAL_POSITION_INT (5 Hz) with the
autopilot's boot clock ``clock_offset_s`` behind UNIX time. The phones: fixed positions, bursts of
probe requests every ``burst_every_s`` (5 frames 20 ms apart) on channel 1, 6 or 11, heard when
within the scenario's range, with the RSSI of the scenario's channel (log-distance, shadowing).
The capture is built with scapy (radiotap: flags, channel, antenna signal): the sensor's own
``synth`` writer is not used here, so the test does not check the parser against itself.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uavloc_gcs.dialect import mavlink

T0_UNIX_S = 1_780_000_000.0


@dataclass
class FlightWorld:
    tlog: bytes
    packets: list  # scapy packets with .time
    phones_xy_m: np.ndarray
    randomizes: list[bool]


def lawnmower(sc, spacing_m=100.0):
    area = sc.area_xy_m()
    x0, y0 = area.min(axis=0)
    x1, y1 = area.max(axis=0)
    pts = []
    for k, y in enumerate(np.arange(y0 + spacing_m / 2, y1, spacing_m)):
        xs = (x0, x1) if k % 2 == 0 else (x1, x0)
        pts += [(xs[0], y), (xs[1], y)]
    return np.array(pts)


def flight_tlog(sc, t0_unix_s: float = T0_UNIX_S) -> bytes:
    """Only the flight's .tlog (no phones), starting at ``t0_unix_s``."""
    return build(sc, [], [], t0_unix_s=t0_unix_s).tlog


def build(sc, phones_xy_m, randomizes, *, seed=0, burst_every_s=1.0, t0_unix_s: float = T0_UNIX_S) -> FlightWorld:
    from scapy.all import Dot11, Dot11Elt, Dot11ProbeReq, RadioTap

    rng = np.random.default_rng(seed)
    alt, speed = sc.fleet.altitude_m, sc.fleet.speed_m_s
    way = lawnmower(sc)
    seg = np.linalg.norm(np.diff(way, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    duration = cum[-1] / speed
    codec = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    boot0 = 123.456  # the autopilot booted this long before the log starts
    recs = []

    def log(t_unix, msg):
        recs.append(int(t_unix * 1e6).to_bytes(8, "big") + msg.pack(codec))
        codec.seq = (codec.seq + 1) % 256

    def pos(t):
        d = np.clip(t * speed, 0, cum[-1])
        return np.array([np.interp(d, cum, way[:, 0]), np.interp(d, cum, way[:, 1]), alt])

    for k in range(int(duration * 5) + 1):
        t = k / 5
        boot_ms = int((boot0 + t) * 1000)
        if k % 5 == 0:
            log(t0_unix_s + t, codec.heartbeat_encode(2, 3, 0, 0, 4))
            log(t0_unix_s + t, codec.system_time_encode(int((t0_unix_s + t) * 1e6), boot_ms))
        p = pos(t)
        lat, lon = sc.frame.to_wgs84(p[0], p[1])
        log(t0_unix_s + t, codec.global_position_int_encode(boot_ms, int(lat * 1e7), int(lon * 1e7),
                                                            int((alt + 400) * 1000), int(alt * 1000),
                                                            0, 0, 0, 0))
    ch = sc.channel
    packets = []
    model_ies = [[(1, b"\x02\x04\x0b\x16"), (45, b"\x2d\x11" + bytes(24)), (127, b"\x04\x00\x0a\x02\x01")],
                 [(1, b"\x82\x84\x8b\x96"), (50, b"\x0c\x12\x18\x24"), (221, b"\x00\x50\xf2\x08\x00\x10\x00")]]
    for i, xy in enumerate(np.asarray(phones_xy_m)):
        base_mac = 0x00_1A_11_00_00_00 + i  # a burned-in address (first octet 0x00: global)
        t = float(rng.uniform(0, burst_every_s))
        seq = int(rng.integers(4096))
        while t < duration:
            mac = (int(rng.integers(2**48)) & ~(0x03 << 40)) | (0x02 << 40) if randomizes[i] else base_mac
            chan = int(rng.choice([1, 6, 11]))
            for j in range(5):
                tf = t + 0.02 * j
                d = np.linalg.norm(pos(tf) - np.array([xy[0], xy[1], 0.0]))
                seq = (seq + 1) % 4096
                if d > sc.fleet.comm_range_m:
                    continue
                rssi = ch.reference_power_dbm - 10 * ch.path_loss_exponent * np.log10(d) + rng.normal(0, ch.shadowing_sigma_db)
                p = (RadioTap(present="Flags+Channel+dBm_AntSignal", Flags=0, ChannelFrequency=2407 + 5 * chan,
                              ChannelFlags=0xa0, dBm_AntSignal=int(round(rssi)))
                     / Dot11(type=0, subtype=4, addr1="ff:ff:ff:ff:ff:ff",
                             addr2=":".join(f"{mac:012x}"[k:k + 2] for k in range(0, 12, 2)),
                             addr3="ff:ff:ff:ff:ff:ff", SC=seq << 4)
                     / Dot11ProbeReq() / Dot11Elt(ID=0, info=b"") / Dot11Elt(ID=3, info=bytes([chan])))
                for eid, info in model_ies[i % 2]:
                    p = p / Dot11Elt(ID=eid, info=info)
                p.time = t0_unix_s + tf
                packets.append(p)
            t += burst_every_s * float(rng.uniform(0.8, 1.2))
    packets.sort(key=lambda p: p.time)
    return FlightWorld(b"".join(recs), packets, np.asarray(phones_xy_m, dtype=float), list(randomizes))
