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


@dataclass(frozen=True)
class LatencyResult:
    people: int
    runs: int
    planner_time_limit_s: float
    median_s: float
    max_s: float
    parts_median_s: dict  # estimate / plan / upload medians
    uploads_per_run: float


def measure_replan_latency(sc: Scenario, *, people: int = 50, runs: int = 5, planner_time_limit_s: float = 0.1,
                           seed: int = 1, base_port: int = 0) -> LatencyResult:
    """Time from the RSSI slot that changes the plan to every changed mission acknowledged.

    50 people are heard on the scan (the real scan lanes, the simulated world); then, ``runs``
    times, a person not heard before shows up in one UAVLOC_RSSI_BATCH message's worth of slots.
    Measured: ingest + re-estimate + replan (EPSO, ``planner_time_limit_s``) + upload with
    read-back verification of every mission whose looks changed, to fake vehicles over UDP.
    The daemon adds at most one tick (``DaemonOptions.tick_s`` = 50 ms) before it sees the slot.
    """
    from sim_link.world import World
    from uavloc_gcs.cli._fleet import start_fleet_process
    from uavloc_gcs.link import open_link
    from uavloc_gcs.mission import flight_mission, to_wire
    from uavloc_gcs.planning import VehicleState
    from uavloc_gcs.search import SearchPolicy

    sc = sc.replace(simulation={"people": people + runs, "seed": seed, "motion": "static"})
    world = World(sc, seed=seed)
    ids = [int(e) for e in world.emitter_ids]
    late = set(ids[people:])
    plan = plan_scan(sc)
    scan_slots = []
    for k, vs in enumerate(plan.vehicles):
        route = vs.route_xy_m()
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(route, axis=0), axis=1))])
        t = np.arange(0.0, cum[-1] / sc.fleet.speed_m_s, sc.channel.slot_s)
        s = t * sc.fleet.speed_m_s
        xyz = np.column_stack([np.interp(s, cum, route[:, 0]), np.interp(s, cum, route[:, 1]),
                               np.full(len(t), sc.fleet.altitude_m)])
        scan_slots.append(world.hear_track(k + 1, t, xyz))
    heard = SlotBatch.concat(scan_slots)
    early = heard.take(~np.isin(heard.emitter_id, list(late)))
    t_now = float(heard.t_s.max()) + 1.0
    policy = SearchPolicy(sc, seed=seed, time_limit_s=planner_time_limit_s)
    policy.ingest(early)
    policy.update(t_now)
    # the vehicles hover where their scan ended, with 80 % of the usable energy left
    ends = {str(k + 1): vs.waypoints_xy_m[-1] for k, vs in enumerate(plan.vehicles)}
    states = [VehicleState(v, (float(xy[0]), float(xy[1])), (0.0, 0.0), 0.8 * sc.usable_energy_j)
              for v, xy in ends.items()]
    policy.replan(t_now, states)

    fleet = start_fleet_process(sc, speedup=1.0, seed=seed, base_port=base_port)
    totals, parts, uploads = [], {"estimate": [], "plan": [], "upload": []}, []
    try:
        async def run() -> None:
            links = {}
            for i, (_n, conn) in enumerate(fleet.endpoints):
                link = await open_link(conn)
                await link.wait_heartbeat(i + 1, timeout_s=10)
                links[i + 1] = link
            agents = {v: VehicleAgent(v, link, sc.frame, autopilot=sc.fleet.autopilot, epoch_unix_s=lambda: 0.0)
                      for v, link in links.items()}
            uploaded: dict[str, tuple] = {}
            for k, eid in enumerate(sorted(late)):
                t = t_now + 5.0 * (k + 1)
                # one message's worth of slots of a person not heard before, from the scan
                mine = heard.for_emitter(eid)
                trigger = mine.take(np.arange(min(len(mine), 12)))
                if len(trigger) == 0:
                    continue
                trigger = SlotBatch.from_columns(np.full(len(trigger), t), trigger.vehicle, trigger.xyz_m,
                                                 trigger.emitter_id, trigger.rssi_dbm, trigger.n_samples)
                t0 = time.perf_counter()
                policy.ingest(trigger)
                changed = policy.update(t)
                t1 = time.perf_counter()
                if not policy.needs_replan(t, changed):
                    continue
                new = policy.replan(t, states)
                t2 = time.perf_counter()
                jobs = []
                for task in new.tasks:
                    key = (tuple(task.target_ids), np.round(np.asarray(task.waypoints_xy_m), 0).tobytes())
                    if uploaded.get(task.vehicle_id) == key or not task.target_ids:
                        continue
                    uploaded[task.vehicle_id] = key
                    latlon = sc.frame.to_wgs84_latlon(np.asarray(task.waypoints_xy_m)[:-1])
                    m = flight_mission(latlon.tolist(), alt_m=sc.fleet.altitude_m, speed_m_s=sc.fleet.speed_m_s,
                                       autopilot=sc.fleet.autopilot, home_latlon_deg=sc.launch_latlon_deg,
                                       include_takeoff=False)
                    jobs.append(agents[int(task.vehicle_id)].upload(to_wire(m, sc.fleet.autopilot)))
                await asyncio.gather(*jobs)
                t3 = time.perf_counter()
                totals.append(t3 - t0)
                parts["estimate"].append(t1 - t0)
                parts["plan"].append(t2 - t1)
                parts["upload"].append(t3 - t2)
                uploads.append(len(jobs))
            for a in agents.values():
                a.close()
            for link in links.values():
                await link.close()

        asyncio.run(run())
    finally:
        fleet.stop()
    if not totals:
        raise RuntimeError("no injected slot changed the plan")
    return LatencyResult(people, len(totals), planner_time_limit_s, float(np.median(totals)), float(np.max(totals)),
                         {k: float(np.median(v)) for k, v in parts.items()}, float(np.mean(uploads)))


@dataclass(frozen=True)
class LossWindowResult:
    kills: int
    commit_interval_s: float
    lost_rows_max: int
    loss_window_max_s: float  # wall time between the newest committed row and the newest handed-off row
    loss_window_median_s: float


_WRITER = """
import sys, time
from uavloc_gcs.observations import SlotBatch
from uavloc_gcs.service.store import Store
st = Store(sys.argv[1], commit_interval_s=float(sys.argv[2]))
i = 0
t0 = time.monotonic()
while True:
    t = time.monotonic() - t0
    st.add_slots(SlotBatch.from_columns([t], [1], [[0.0, 0.0, 100.0]], [7], [-70.0], [10]))
    sys.stdout.write(f"{i} {t:.6f}\\n")
    sys.stdout.flush()
    i += 1
    time.sleep(0.001)
"""


def measure_loss_window(*, kills: int = 5, commit_interval_s: float | None = None) -> LossWindowResult:
    """kill -9 a process that streams slots into a Store (~1 kHz), then compare what it had
    handed to the store (echoed on a pipe before the kill) with what is committed in the file."""
    import os
    import signal
    import subprocess
    import sys

    from uavloc_gcs.service.store import DEFAULT_COMMIT_INTERVAL_S

    interval = DEFAULT_COMMIT_INTERVAL_S if commit_interval_s is None else commit_interval_s
    rng = np.random.default_rng(0)
    windows, lost = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(kills):
            path = Path(tmp) / f"kill{k}.sqlite"
            proc = subprocess.Popen([sys.executable, "-c", _WRITER, str(path), str(interval)],
                                    stdout=subprocess.PIPE, text=True)
            proc.stdout.readline()
            time.sleep(0.5 + float(rng.uniform(0.0, 0.5)))
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait()
            handed = [ln.split() for ln in proc.stdout.read().splitlines() if len(ln.split()) == 2]
            last_i, last_t = int(handed[-1][0]), float(handed[-1][1])
            with StoreReader(path) as rd:
                t = rd.slots().t_s
            committed_t = float(t.max()) if len(t) else 0.0
            windows.append(last_t - committed_t)
            lost.append(last_i + 1 - len(t))
    return LossWindowResult(kills, interval, int(max(lost)), float(max(windows)), float(np.median(windows)))


def main() -> int:
    """``python -m benchmarks._service``: the service's numbers on the paper scenario."""
    from uavloc_gcs.scenario import load_scenario

    from uavloc_gcs.examples import example_path

    sc = load_scenario(example_path("paper.toml"))
    ing = measure_ingestion(sc)
    print(f"RSSI ingestion (parse + decode + store commit, one core): {ing.rate_slots_per_s:,.0f} slots/s = "
          f"{ing.ratio:,.0f}x the paper scenario's {ing.scenario_rate_slots_per_s:.1f} slots/s (target >= 20x); "
          f"longest commit delay under this load {ing.max_commit_delay_s * 1000:.0f} ms")
    lw = measure_loss_window()
    print(f"kill -9 loss window over {lw.kills} kills: worst {lw.loss_window_max_s * 1000:.0f} ms "
          f"(median {lw.loss_window_median_s * 1000:.0f} ms, at most {lw.lost_rows_max} rows), "
          f"commit interval {lw.commit_interval_s * 1000:.0f} ms")
    for limit in (sc.planner.time_limit_s, 1.0):  # the scenario's in-flight budget, and a generous one
        lat = measure_replan_latency(sc, people=50, runs=5, planner_time_limit_s=limit)
        p = lat.parts_median_s
        which = " (scenario default)" if limit == sc.planner.time_limit_s else ""
        print(f"replan latency, 50 people, planner limit {limit:g} s{which}: median {lat.median_s * 1000:.0f} ms, "
              f"max {lat.max_s * 1000:.0f} ms (estimate {p['estimate'] * 1000:.1f} ms, plan {p['plan'] * 1000:.0f} ms, "
              f"upload+verify {p['upload'] * 1000:.0f} ms for {lat.uploads_per_run:.1f} missions) "
              + (f"(target < 300 ms: {'met' if lat.median_s < 0.3 else 'missed'})" if which else
                 f"(no target: the planner alone may take its {limit:g} s)"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
