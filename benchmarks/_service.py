"""Service measurements for ``uavloc bench link``: RSSI ingestion rate and replanning latency.

``measure_ingestion`` pushes the paper scenario's real RSSI telemetry (the simulated world heard
along the real scan lanes, encoded as UAVLOC_RSSI_BATCH packets) through the daemon's receive path
-- MAVLink parsing, dispatch, decoding to slots, the store's batched SQLite commits -- as fast as
one core can, and compares the sustained rate with the rate the scenario produces in real time.

``measure_replan_latency`` runs the daemon against one fake vehicle with N people already
estimated, injects a slot that changes the plan, and times the path slot -> re-estimate ->
replan -> upload -> MISSION_ACK (verified read-back included).
"""

from __future__ import annotations

import asyncio
import math
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from uavloc_gcs.dialect import mavlink
from uavloc_gcs.dialect.rssi import COMPANION_COMPONENT_ID, encode_rssi_batches
from uavloc_gcs.link.connection import Link
from uavloc_gcs.observations import SlotBatch
from uavloc_gcs.scan import plan_scan
from uavloc_gcs.scenario import Scenario
from uavloc_gcs.service.store import Store, StoreReader
from uavloc_gcs.service.vehicle import VehicleAgent


@dataclass(frozen=True)
class IngestionResult:
    slots: int
    packets: int
    wall_s: float
    rate_slots_per_s: float
    scenario_rate_slots_per_s: float  # the paper scenario's real-time rate, whole fleet
    ratio: float  # rate / scenario rate (target >= 20)
    max_commit_delay_s: float  # the store's bounded delay, observed under this load


def _scan_telemetry(sc: Scenario, seed: int) -> tuple[list[bytes], int, float]:
    """Every vehicle's scan as heard by the simulated world: (packets, slot rows, mission seconds)."""
    from sim_link.world import World

    world = World(sc, seed=seed)
    plan = plan_scan(sc)
    packets: list[bytes] = []
    rows = 0
    duration = 0.0
    for k, vs in enumerate(plan.vehicles):
        vid = k + 1
        route = vs.route_xy_m()
        seg = np.linalg.norm(np.diff(route, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        t = np.arange(0.0, cum[-1] / sc.fleet.speed_m_s, sc.channel.slot_s)
        s = t * sc.fleet.speed_m_s
        xyz = np.column_stack([np.interp(s, cum, route[:, 0]), np.interp(s, cum, route[:, 1]),
                               np.full(len(t), sc.fleet.altitude_m)])
        slots = world.hear_track(vid, t, xyz)
        rows += len(slots)
        duration = max(duration, float(t[-1]) if len(t) else 0.0)
        enc = mavlink.MAVLink(None, srcSystem=vid, srcComponent=COMPANION_COMPONENT_ID)
        for msg in encode_rssi_batches(slots, sc.frame, epoch_unix_s=1.7e9, slot_s=sc.channel.slot_s):
            packets.append(bytes(msg.pack(enc)))
            enc.seq = (enc.seq + 1) % 256
    return packets, rows, duration


def measure_ingestion(sc: Scenario, *, seed: int = 1, repeat: int = 3) -> IngestionResult:
    """Sustained RSSI ingestion (parse + decode + store commit) on one core, vs the scenario's rate."""
    packets, rows, duration_s = _scan_telemetry(sc, seed)
    scenario_rate = rows / duration_s if duration_s > 0 else math.nan
    with tempfile.TemporaryDirectory() as tmp:
        store = Store(Path(tmp) / "bench.sqlite")
        link = Link("bench", source_system=255, source_component=190, signing_key=None, tlog=None)
        agents = [VehicleAgent(v + 1, link, sc.frame, autopilot=sc.fleet.autopilot, epoch_unix_s=lambda: 1.7e9,
                               on_slots=store.add_slots) for v in range(sc.fleet.vehicles)]
        stream = b"".join(packets)
        chunk = 4096
        t0 = time.perf_counter()
        for _ in range(repeat):
            for i in range(0, len(stream), chunk):
                link._on_bytes(stream[i:i + chunk], "bench")
        store.flush()
        wall = time.perf_counter() - t0
        stats = store.stats()
        store.close()
        with StoreReader(Path(tmp) / "bench.sqlite") as rd:
            stored = rd.slot_count()
        for a in agents:
            a.close()
    if stored != rows * repeat:
        raise RuntimeError(f"ingestion lost slots: {stored} stored of {rows * repeat} sent")
    rate = stored / wall
    return IngestionResult(stored, len(packets) * repeat, wall, rate, scenario_rate, rate / scenario_rate,
                           stats.max_commit_delay_s)
