"""``uavloc bench sense``: the sensor's capture parser vs library dissectors, frames per second.

A synthetic capture (:mod:`uavloc_gcs.sense.synth`: radiotap headers of a two-chain monitor-mode
adapter with three present words, probe requests of four phone families, random addresses per
burst, FCS) is parsed from memory by:

- ``uavloc``: :func:`uavloc_gcs.sense.parse_capture_bytes` (struct over the file buffer, cached
  radiotap layouts, element walk and SHA-256 fingerprint per frame);
- ``dpkt``: ``dpkt.pcap.Reader`` + ``dpkt.radiotap.Radiotap`` (which decodes the 802.11 frame
  behind it), reading the same fields (address, signal, channel);
- ``scapy``: ``scapy.utils.RawPcapReader`` + ``RadioTap(...)`` dissection, the same fields, on the
  first ``--scapy-frames`` frames (it is two orders slower).

The process is pinned to one core (``os.sched_setaffinity``) for the whole run. Printed per parser:
frames read, probe requests found, how many agree with the truth the generator kept (address,
signal, channel), the best of ``--repeats`` wall times and frames per second, and the ratio to
``uavloc``'s rate. The issue's bar: at least 20,000 frames/s for ``uavloc``.

Then the same for Bluetooth LE (issue 39): a synthetic Ubertooth-style capture (link type 256,
:mod:`uavloc_gcs.sense.synth_ble`: offline iPhones sending Find My every 2 s, other Apple and
non-Apple devices every 0.1-1 s) parsed by ``uavloc`` and, on the first ``--scapy-frames``, by
scapy's ``BTLE_RF`` dissector; its frames/s is printed beside the Wi-Fi figure (the same 20,000
frames/s bar). For both captures the telemetry cost is printed as UAVLOC_RSSI_BATCH2 bytes at the
busiest second, which must stay within half of a 57.6 kbit/s radio.
"""

from __future__ import annotations

import argparse
import io
import os
import time

import numpy as np

from uavloc_gcs.cli._inputs import number

TARGET_FPS = 20_000
RADIO_SHARE_MAX = 0.5  # of a 57.6 kbit/s telemetry radio, at the busiest second


def add_arguments(parser: argparse.ArgumentParser) -> None:
    # at most 2 million frames: the synthetic capture is held in memory (about 300 MB then)
    parser.add_argument("--frames", type=number(int, min=1, max=2_000_000), default=100_000,
                        help="frames in the capture, 1-2000000 (default 100000)")
    parser.add_argument("--scapy-frames", type=number(int, min=1, max=2_000_000), default=3_000,
                        help="frames scapy parses (default 3000)")
    parser.add_argument("--repeats", type=number(int, min=1, max=100), default=3, help="timed repeats, best kept (default 3)")
    parser.add_argument("--seed", type=number(int, min=0, max=2**32 - 1), default=0, help="seed (default 0)")


def _uavloc(buf: bytes):
    from uavloc_gcs.sense import parse_capture_bytes

    f, _ = parse_capture_bytes(buf)
    return f.address, f.rssi_dbm, f.channel


def _dpkt(buf: bytes):
    import dpkt

    addr, rssi, chan = [], [], []
    for _, raw in dpkt.pcap.Reader(io.BytesIO(buf)):
        try:
            rt = dpkt.radiotap.Radiotap(raw)
            w = rt.data
            if w.type != 0 or w.subtype != 4:
                continue
            addr.append(int.from_bytes(w.mgmt.src, "big"))
            rssi.append(rt.ant_sig.db - 256 if rt.ant_sig.db > 127 else rt.ant_sig.db)
            f = rt.channel.freq
            chan.append((f - 2407) // 5 if f < 2484 else 14)
        except (dpkt.dpkt.UnpackError, AttributeError, IndexError):
            continue
    return np.array(addr, dtype=np.int64), np.array(rssi), np.array(chan)


def _scapy(buf: bytes, limit: int):
    from scapy.layers.dot11 import Dot11, Dot11ProbeReq, RadioTap
    from scapy.utils import RawPcapReader

    addr, rssi, chan = [], [], []
    for k, (raw, _) in enumerate(RawPcapReader(io.BytesIO(buf))):
        if k >= limit:
            break
        p = RadioTap(raw)
        if not p.haslayer(Dot11ProbeReq):
            continue
        addr.append(int(p[Dot11].addr2.replace(":", ""), 16))
        rssi.append(p.dBm_AntSignal)
        f = p.ChannelFrequency
        chan.append((f - 2407) // 5 if f < 2484 else 14)
    return np.array(addr, dtype=np.int64), np.array(rssi), np.array(chan)


def _agree(got, truth, n: int) -> int:
    a, r, c = got
    k = min(len(a), n)
    return int(np.sum((a[:k] == truth.address[:k]) & (r[:k] == truth.rssi_dbm[:k]) & (c[:k] == truth.channel[:k])))


def _scapy_ble(buf: bytes, limit: int):
    from scapy.layers.bluetooth4LE import BTLE, BTLE_RF
    from scapy.utils import RawPcapReader

    addr, rssi, chan = [], [], []
    for k, (raw, _) in enumerate(RawPcapReader(io.BytesIO(buf))):
        if k >= limit:
            break
        p = BTLE_RF(raw)
        addr.append(int(p[BTLE].payload.payload.AdvA.replace(":", ""), 16))
        rssi.append(p.signal)
        chan.append({0: 37, 12: 38, 39: 39}.get(p.rf_channel, 0))
    return np.array(addr, dtype=np.int64), np.array(rssi), np.array(chan)


def _radio_budget(buf: bytes) -> float:
    """What the capture costs on the telemetry radio as UAVLOC_RSSI_BATCH2 (25 ms slots, the
    dialect's 12-entry / 200 ms batching, MAVLink 2 framing, signed), per second of capture."""
    from uavloc_gcs.dialect import mavlink
    from uavloc_gcs.dialect.rssi import BATCH2, encode_rssi_batches
    from uavloc_gcs.geo import LocalFrame
    from uavloc_gcs.observations import SlotBatch
    from uavloc_gcs.sense import parse_capture_bytes
    from uavloc_gcs.sense.aggregate import slot_entries

    frames, _ = parse_capture_bytes(buf)
    e = slot_entries(frames, 0.025)
    t = e.t_s - e.t_s[0]
    xyz = np.column_stack([10.0 * t, np.zeros_like(t), np.full_like(t, 100.0)])  # 10 m/s at 100 m
    slots = SlotBatch.from_columns(t, np.ones(len(t), dtype=int), xyz, e.address, e.rssi_dbm, e.n_frames,
                                   address=e.address, fingerprint=e.fingerprint, channel=e.channel, radio=e.radio)
    msgs = encode_rssi_batches(slots, LocalFrame(47.0, 8.0), slot_s=0.025, message=BATCH2)
    codec = mavlink.MAVLink(None, srcSystem=1, srcComponent=191)
    sizes = np.array([len(m.pack(codec)) + 13 for m in msgs])  # + the 13-byte signature
    sec = np.floor(np.array([m.time_usec / 1e6 for m in msgs])).astype(int)
    per_s = np.bincount(sec - sec.min(), weights=sizes)
    span = max(float(t[-1]), 1.0)
    budget = 57_600 / 8
    print(f"  radio: {len(frames) / span:,.0f} frames/s heard -> {len(e) / span:,.0f} entries/s, {len(msgs) / span:,.1f} "
          f"UAVLOC_RSSI_BATCH2/s ({len(e) / len(msgs):.1f} entries each), {sizes.sum() / span:,.0f} B/s signed on average, "
          f"busiest second {per_s.max():,.0f} B/s = {100 * per_s.max() / budget:.0f} % of a 57.6 kbit/s radio")
    return float(per_s.max() / budget)


def _time(fn, repeats: int):
    best, out = float("inf"), None
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def _table(rows, own_fps: float) -> None:
    print(f"{'parser':<8} {'frames':>8} {'used':>8} {'agree':>8} {'time s':>8} {'frames/s':>10} {'vs uavloc':>10}")
    for name, n, used, agree, t in rows:
        fps = n / t
        print(f"{name:<8} {n:>8} {used:>8} {agree:>8} {t:>8.3f} {fps:>10,.0f} {fps / own_fps:>10.3f}")


def _ble(args) -> tuple[float, bool, float]:
    """The BLE run: (uavloc frames/s, all fields agree, busiest-second radio share)."""
    from uavloc_gcs.sense.synth_ble import synthetic_ble_capture

    buf, truth = synthetic_ble_capture(args.frames, rng=np.random.default_rng(args.seed))
    span = truth.t_s[-1] - truth.t_s[0]
    print(f"\nBLE capture: {args.frames} advertisements (link type 256), {len(buf) / 1e6:.1f} MB, "
          f"{args.frames / max(span, 1e-9):,.0f} frames/s over {span:,.0f} s, "
          f"{int(np.sum(truth.apple == 0x12))} Find My")
    rows = []
    t_own, got = _time(lambda: _uavloc(buf), args.repeats)
    rows.append(("uavloc", args.frames, len(got[0]), _agree(got, truth, args.frames), t_own))
    try:
        import scapy  # noqa: F401

        n = min(args.scapy_frames, args.frames)
        t, got = _time(lambda: _scapy_ble(buf, n), 1)
        rows.append(("scapy", n, len(got[0]), _agree(got, truth, n), t))
    except ImportError:
        print("scapy not installed (pip install scapy): skipped")
    own_fps = args.frames / t_own
    _table(rows, own_fps)
    share = _radio_budget(buf)
    return own_fps, rows[0][3] == args.frames, share


def main(args: argparse.Namespace) -> int:
    from uavloc_gcs.sense.synth import synthetic_capture

    cpu = sorted(os.sched_getaffinity(0))[-1]
    os.sched_setaffinity(0, {cpu})
    buf, truth = synthetic_capture(args.frames, rng=np.random.default_rng(args.seed))
    print(f"capture: {args.frames} radiotap probe requests, {len(buf) / 1e6:.1f} MB, pinned to cpu {cpu}")
    rows = []
    t_own, got = _time(lambda: _uavloc(buf), args.repeats)
    rows.append(("uavloc", args.frames, len(got[0]), _agree(got, truth, args.frames), t_own))
    try:
        import dpkt  # noqa: F401

        t, got = _time(lambda: _dpkt(buf), args.repeats)
        rows.append(("dpkt", args.frames, len(got[0]), _agree(got, truth, args.frames), t))
    except ImportError:
        print("dpkt not installed (pip install dpkt): skipped")
    try:
        import scapy  # noqa: F401

        n = min(args.scapy_frames, args.frames)
        t, got = _time(lambda: _scapy(buf, n), 1)
        rows.append(("scapy", n, len(got[0]), _agree(got, truth, n), t))
    except ImportError:
        print("scapy not installed (pip install scapy): skipped")
    own_fps = args.frames / t_own
    _table(rows, own_fps)
    share = _radio_budget(buf)
    ble_fps, ble_agree, ble_share = _ble(args)
    print()
    ok = True
    for radio, fps, agree, sh in (("Wi-Fi", own_fps, rows[0][3] == args.frames, share),
                                  ("BLE", ble_fps, ble_agree, ble_share)):
        good = fps >= TARGET_FPS and agree and sh <= RADIO_SHARE_MAX
        ok &= good
        print(f"uavloc {radio:<5}: {fps:>9,.0f} frames/s on one core, busiest second {100 * sh:.0f} % of the radio "
              f"({'meets' if good else 'MISSES'} {TARGET_FPS:,} frames/s and {100 * RADIO_SHARE_MAX:.0f} %"
              f"{'' if agree else '; fields disagree with the truth'})")
    return 0 if ok else 1
