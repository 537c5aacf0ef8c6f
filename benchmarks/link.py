"""``uavloc bench link``: mission upload against MAVSDK, and (from ``benchmarks._service``) the
service's replanning latency and RSSI ingestion rate.

Upload part: one fake vehicle (``sim_link.FakeFleet``, ArduPilot- or PX4-like) on loopback UDP,
its link losing ``--loss`` of the datagrams in each direction. For each loss rate and run, the same
``--items``-item mission is uploaded to the same vehicle by

* uavloc (``uavloc_gcs.link.upload_mission``; "upload" is until the vehicle's final ACK, "+verify"
  adds the read-back download and comparison uavloc always does), and
* MAVSDK's ``mission_raw.upload_mission`` (MAVSDK 4, C++ core; default 0.5 s timeout, 5 retries),

with the vehicle's mission cleared before each upload and checked item by item afterwards; the two
clients take turns on the same vehicle (one per loss rate), so both see the same machine load. Success means
the call returned without error *and* the vehicle holds exactly the mission. The ratio is MAVSDK's
median upload time over uavloc's (> 1: uavloc is faster), over runs where both succeeded.
Target (issue 6): not slower than MAVSDK, 100 % success at 0 % and 20 % loss.
"""

from __future__ import annotations

from uavloc_gcs.cli._inputs import number, number_list
import argparse
import asyncio
import logging
import math
import statistics
import struct
import time
from dataclasses import dataclass, field

from ._progress import Progress

HEARTBEAT_WAIT_S = 15.0
CLEAR_ATTEMPTS = 4
VEHICLE_TRANSFER_TIMEOUT_S = 8.0  # ArduPilot's upload timeout (PX4: 5 s)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--items", type=number(int, min=1, max=65535), default=500, help="mission items (default 500)")
    p.add_argument("--loss", type=number_list(float, min=0, max=0.9), default="0,0.2",
                   help="comma-separated loss rates per direction, 0-0.9 each (default 0,0.2)")
    p.add_argument("--runs", type=number(int, min=1), default=1, help="uploads per client on a lossy link (default 1; ~4 min)")
    p.add_argument("--runs-clean", type=number(int, min=0), default=5, help="uploads per client at 0 %% loss (default 5)")
    p.add_argument("--autopilot", choices=("px4", "ardupilot"), default="px4", help="fake vehicle flavour")
    p.add_argument("--seed", type=number(int, min=0), default=1)
    p.add_argument("--scenario", default="small", metavar="FILE.toml",
                   help="scenario of the fake vehicle (or a shipped one: small, paper; default small)")
    p.add_argument("--no-mavsdk", action="store_true", help="measure uavloc only")
    p.add_argument("--no-upload", action="store_true", help="skip the upload comparison")
    p.add_argument("--no-service", action="store_true",
                   help="skip the replanning latency, ingestion rate and kill -9 loss window")


@dataclass
class Row:
    loss: float
    ours_s: list = field(default_factory=list)  # upload time of successful runs
    ours_verified_s: list = field(default_factory=list)
    ours_ok: int = 0
    mavsdk_s: list = field(default_factory=list)
    mavsdk_ok: int = 0
    runs: int = 0
    pairs: list = field(default_factory=list)  # (ours, mavsdk) of runs where both succeeded
    notes: list = field(default_factory=list)


def _mission(n: int, autopilot: str):
    from uavloc_gcs.mission import flight_mission, to_wire

    pts = [(47.3977 + 0.00005 * (i % 40), 8.5456 + 0.00008 * (i // 40)) for i in range(n - 3)]
    plan = flight_mission(pts, alt_m=40.0, speed_m_s=10.0, autopilot=autopilot, home_latlon_deg=(47.3977, 8.5456),
                          home_alt_amsl_m=488.0)
    items = to_wire(plan, autopilot)
    return items[:n]


def _holds(vehicle_items, items, autopilot: str) -> bool:
    """The vehicle holds ``items`` (float32 fields; ArduPilot's seq 0 is its own home)."""
    def norm(w):
        f = lambda v: "nan" if math.isnan(v) else struct.unpack("<f", struct.pack("<f", v))[0]  # noqa: E731
        return (w.seq, w.frame, w.command, w.autocontinue, f(w.param1), f(w.param2), f(w.param3), f(w.param4),
                w.x, w.y, f(w.z))
    start = 1 if autopilot == "ardupilot" else 0
    return len(vehicle_items) == len(items) and [norm(w) for w in vehicle_items[start:]] == [
        norm(w) for w in items[start:]]


async def _ours(conn: str, items, autopilot: str) -> tuple[float, float]:
    """(upload s, upload + verify s) with uavloc; raises on failure."""
    from uavloc_gcs.link import open_link, upload_mission

    async with await open_link(conn) as link:
        await link.wait_heartbeat(1, timeout_s=HEARTBEAT_WAIT_S)
        upload_done = []

        def progress(stage, done, total):
            if stage == "verify" and not upload_done:
                upload_done.append(time.perf_counter())
        t0 = time.perf_counter()
        await upload_mission(link, 1, 1, items, verify=True, autopilot=autopilot, progress=progress)
        t1 = time.perf_counter()
    return upload_done[0] - t0, t1 - t0


async def _mavsdk(conn: str, items) -> float:
    """Upload time with MAVSDK's mission_raw; raises on failure."""
    from mavsdk import ComponentType, Configuration, Mavsdk
    from mavsdk.plugins.mission_raw import MissionItem, MissionRaw

    loop = asyncio.get_running_loop()
    gcs = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
    try:
        gcs.add_any_connection(conn.replace("udpout:", "udpout://"))
        system = await loop.run_in_executor(None, gcs.first_autopilot, HEARTBEAT_WAIT_S)
        if system is None:
            raise RuntimeError("MAVSDK found no autopilot")
        mission_raw = MissionRaw(system)
        mitems = [MissionItem(w.seq, w.frame, w.command, w.current, w.autocontinue, w.param1, w.param2, w.param3,
                              w.param4, w.x, w.y, w.z, w.mission_type) for w in items]
        t0 = time.perf_counter()
        await loop.run_in_executor(None, mission_raw.upload_mission, mitems)
        return time.perf_counter() - t0
    finally:
        gcs.destroy()


async def _measure(args: argparse.Namespace) -> list[Row]:
    from sim_link.vehicles.faults import FaultConfig
    from sim_link.vehicles.fleet import FakeFleet
    from uavloc_gcs.errors import MissionTransferError
    from uavloc_gcs.link import clear_mission, open_link
    from uavloc_gcs.scenario import load_scenario

    from uavloc_gcs.examples import scenario_path

    sc = load_scenario(scenario_path(args.scenario)).replace(fleet={"autopilot": args.autopilot, "vehicles": 1})
    items = _mission(args.items, args.autopilot)

    async def clear(conn: str) -> None:
        """Every upload starts from an empty vehicle. A vehicle still inside an aborted transfer
        refuses (PX4: "Busy") until its own transfer timeout (5 s / 8 s) has passed."""
        for attempt in range(CLEAR_ATTEMPTS):
            try:
                async with await open_link(conn, source_system=254) as link:
                    await link.wait_heartbeat(1, timeout_s=HEARTBEAT_WAIT_S)
                    await clear_mission(link, 1, 1)
                return
            except MissionTransferError:
                if attempt == CLEAR_ATTEMPTS - 1:
                    raise
                await asyncio.sleep(VEHICLE_TRANSFER_TIMEOUT_S)

    rows = []
    losses = list(args.loss)
    bar = Progress(sum(args.runs_clean if loss == 0 else args.runs for loss in losses))
    for loss in losses:
        row = Row(loss)
        runs = args.runs_clean if loss == 0 else args.runs
        # one vehicle per loss rate; uavloc and MAVSDK take turns uploading to it
        async with FakeFleet(sc, speedup=1, seed=args.seed, base_port=0, faults=FaultConfig(loss=loss)) as fleet:
            (_, conn), = fleet.endpoints
            for run in range(runs):
                bar.step(f"loss {loss:g} upload {run + 1}")
                row.runs += 1
                ours = None
                await clear(conn)
                try:
                    up_s, verified_s = await _ours(conn, items, args.autopilot)
                    if _holds(fleet.vehicle(1).mission_items, items, args.autopilot):
                        row.ours_ok += 1
                        row.ours_s.append(up_s)
                        row.ours_verified_s.append(verified_s)
                        ours = up_s
                except Exception as err:  # a failure is a result here
                    row.notes.append(f"uavloc run {run}: {err}")
                if args.no_mavsdk:
                    continue
                await clear(conn)
                try:
                    m_s = await _mavsdk(conn, items)
                    if _holds(fleet.vehicle(1).mission_items, items, args.autopilot):
                        row.mavsdk_ok += 1
                        row.mavsdk_s.append(m_s)
                        if ours is not None:
                            row.pairs.append((ours, m_s))
                except Exception as err:
                    row.notes.append(f"MAVSDK run {run}: {str(err).split(';')[0]}")
        rows.append(row)
    return rows


def _med(xs) -> str:
    return f"{statistics.median(xs):.3f}" if xs else "-"


def print_upload_table(rows: list[Row], args: argparse.Namespace) -> None:
    print(f"Mission upload, {args.items} items, one {args.autopilot} fake vehicle on loopback UDP, "
          f"median seconds over the runs (uavloc and MAVSDK alternate on the same vehicle)")
    print(f"{'loss':>5} | {'runs':>4} | {'uavloc upload':>13} | {'+verify':>7} | {'MAVSDK upload':>13} | {'MAVSDK/uavloc':>13} "
          f"| {'uavloc ok':>9} | {'MAVSDK ok':>9}")
    for r in rows:
        ratio = statistics.median(m / o for o, m in r.pairs) if r.pairs else None
        mavsdk_ok = "-" if args.no_mavsdk else f"{r.mavsdk_ok}/{r.runs}"
        print(f"{r.loss:>5.0%} | {r.runs:>4} | {_med(r.ours_s):>13} | {_med(r.ours_verified_s):>7} | {_med(r.mavsdk_s):>13} | "
              f"{(f'{ratio:.2f}' if ratio else '-'):>13} | {f'{r.ours_ok}/{r.runs}':>9} | {mavsdk_ok:>9}")
    for r in rows:
        for note in r.notes:
            print(f"  {r.loss:.0%}: {note}")


def service_measurements(args: argparse.Namespace) -> int:
    """Replanning latency, RSSI ingestion rate and the store's kill -9 loss window, measured by
    ``benchmarks._service`` on the paper scenario; returns an exit code."""
    if args.no_service:
        return 0
    from benchmarks._service import main as service_main

    print("\nService (paper scenario):")
    return int(service_main() or 0)


def _quiet_mavsdk() -> None:
    """Send MAVSDK's own console log to Python logging (debug level) instead of the terminal."""
    try:
        from mavsdk import log_subscribe
    except ImportError:
        return
    mlog = logging.getLogger("mavsdk")
    log_subscribe(lambda level, message, file, line: (mlog.debug("%s", message), True)[1])


def main(args: argparse.Namespace) -> int:
    logging.getLogger("uavloc_gcs").setLevel(logging.ERROR)
    if not args.no_mavsdk:
        _quiet_mavsdk()
    ok = True
    if not args.no_upload:
        rows = asyncio.run(_measure(args))
        print_upload_table(rows, args)
        ok = all(r.ours_ok == r.runs for r in rows)
    return max(0 if ok else 1, service_measurements(args))
