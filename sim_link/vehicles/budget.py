"""Telemetry budget: bytes per second a fake vehicle sends while flying its scan mission.

Every message a vehicle emits (all streams, STATUSTEXT, MISSION_ITEM_REACHED and the RSSI
messages of its companion) is packed as MAVLink 2 exactly as on the wire and counted per
simulated second, from arming to landing. No sockets: the vehicles run in-process on the
scenario's world, so the numbers are deterministic for a seed. The RSSI goes as
UAVLOC_RSSI_BATCH2 (what the companion emulator sends: address, fingerprint, channel per entry)
unless ``--message`` asks for the old UAVLOC_RSSI_BATCH or ``auto`` (the old one whenever it
carries the slots losslessly, as in the paper's continuous world).

Two RSSI paths (docs/guide/daemon.md, "The RSSI path"): ``through`` -- the companion's RSSI goes
through the autopilot (ArduPilot with MAVn_OPTIONS bit 3) and shares the one radio with the
telemetry; ``beside`` -- it goes on a link of its own (a second radio, or a router on the
companion), so the autopilot's radio carries only the telemetry and the RSSI link only the
companion's messages (component 191). A router on the companion that merges both onto one radio
costs the same bytes as ``through``.

    python -m sim_link.vehicles.budget examples/paper.toml [--seed 1] [--signed] [--path through|beside]
                                       [--message UAVLOC_RSSI_BATCH2|UAVLOC_RSSI_BATCH|auto]
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass

import numpy as np

from uavloc_gcs.dialect import RSSI_MESSAGE_TYPES
from uavloc_gcs.dialect import mavlink as mav
from uavloc_gcs.dialect.rssi import BATCH2, MESSAGES, RssiBatcher
from uavloc_gcs.mission import to_wire
from uavloc_gcs.scan import plan_scan, scan_missions
from uavloc_gcs.scenario import Scenario, load_scenario

from .flavour import FLAVOURS
from .vehicle import FakeVehicle, VehicleConfig

RADIO_BYTES_S = 57_600 / 10  # a 57.6 kbit/s serial radio link carries 5760 bytes/s (8N1 framing)
SIGNATURE_BYTES = 13
ADVANCE_S = 0.2


@dataclass(frozen=True)
class VehicleBudget:
    vehicle: int
    flight_s: float
    mean_bytes_s: float
    peak_bytes_s: float  # busiest 1 s window
    bytes_by_type: dict
    rssi_entries: int
    rssi_messages: int  # with entries (keepalives, count 0, are counted apart)
    mean_by_component: dict = None  # component id (1 autopilot, 191 companion) -> mean B/s
    peak_by_component: dict = None  # component id -> busiest 1 s window B/s
    rssi_keepalives: int = 0  # count-0 messages: "heard nothing since" (dialect.rssi.KEEPALIVE_S)


def measure(scenario: Scenario, *, seed: int | None = None, signed: bool = False,
            vehicles: list[int] | None = None, message: str = BATCH2) -> list[VehicleBudget]:
    """Fly each vehicle's scan mission (or only ``vehicles``, 1-based) and count its downlink
    bytes per simulated second, the RSSI sent as ``message`` (rssi.MESSAGES)."""
    from ..world import World

    world = World(scenario, seed=seed)
    f = scenario.fleet
    flavour = FLAVOURS[f.autopilot]
    out = []
    for idx, plan in enumerate(scan_missions(scenario, plan_scan(scenario)), start=1):
        if vehicles is not None and idx not in vehicles:
            continue
        cfg = VehicleConfig(idx, flavour, scenario.frame, cruise_speed_m_s=f.speed_m_s,
                            max_accel_m_s2=f.max_acceleration_m_s2, energy_budget_j=f.energy_budget_j,
                            power=scenario.power_model, slot_s=scenario.channel.slot_s, epoch_unix_s=1.8e9,
                            companion_heartbeat=True)  # a real companion's 1 Hz HEARTBEAT counts too
        v = FakeVehicle(cfg, world)
        v.batcher = RssiBatcher(scenario.frame, cfg.epoch_unix_s, cfg.slot_s, message=message)  # as the companion
        v.mission.stores[0] = to_wire(plan, f.autopilot)
        v.executor.reset()
        v.set_mode("AUTO")
        v.arm()
        codecs = {c: mav.MAVLink(None, srcSystem=idx, srcComponent=c) for c in (1, 191)}
        per_s: dict[int, int] = {}
        per_s_comp: dict[int, dict[int, int]] = {1: {}, 191: {}}
        by_type: dict[str, int] = {}
        entries = msgs = keepalives = 0
        t = 0.0
        while not (v.landed and not v.armed and t > 5.0) and t < 7200.0:
            t = round(t + ADVANCE_S, 6)  # as the fleet advances at 20x with 10 ms ticks
            for r in v.advance(t):
                n = len(r.msg.pack(codecs[r.component])) + (SIGNATURE_BYTES if signed else 0)
                sec = int(np.floor(v.t_s - 1e-9))
                per_s[sec] = per_s.get(sec, 0) + n
                comp = per_s_comp[r.component]
                comp[sec] = comp.get(sec, 0) + n
                name = r.msg.get_type()
                by_type[name] = by_type.get(name, 0) + n
                if name in RSSI_MESSAGE_TYPES and r.msg.count:
                    entries += r.msg.count
                    msgs += 1
                elif name in RSSI_MESSAGE_TYPES:
                    keepalives += 1
        secs = range(int(np.ceil(t)))
        series = np.array([per_s.get(s, 0) for s in secs], dtype=float)
        comp_series = {c: np.array([d.get(s, 0) for s in secs], dtype=float) for c, d in per_s_comp.items()}
        out.append(VehicleBudget(idx, t, float(series.mean()), float(series.max()),
                                 {k: by_type[k] / t for k in sorted(by_type, key=lambda k: -by_type[k])},
                                 entries, msgs, {c: float(x.mean()) for c, x in comp_series.items()},
                                 {c: float(x.max()) for c, x in comp_series.items()}, keepalives))
    return out


def report(budgets: list[VehicleBudget], path: str = "through") -> str:
    if path == "beside":
        return _report_beside(budgets)
    lines = ["| vehicle | flight [s] | mean [B/s] | peak 1 s [B/s] | of 57.6 kbit/s (peak) | RSSI B/s | entries/msg |",
             "|---|---|---|---|---|---|---|"]
    for b in budgets:
        rssi = sum(b.bytes_by_type.get(k, 0.0) for k in RSSI_MESSAGE_TYPES)
        per = b.rssi_entries / b.rssi_messages if b.rssi_messages else 0.0
        lines.append(f"| uav{b.vehicle} | {b.flight_s:.0f} | {b.mean_bytes_s:.0f} | {b.peak_bytes_s:.0f} | "
                     f"{100 * b.peak_bytes_s / RADIO_BYTES_S:.0f} % | {rssi:.0f} | {per:.1f} |")
    worst = max(budgets, key=lambda b: b.mean_bytes_s)
    lines.append("")
    lines.append("mean bytes/s by message (uav%d): " % worst.vehicle
                 + ", ".join(f"{k} {v:.0f}" for k, v in worst.bytes_by_type.items()))
    return "\n".join(lines)


def _report_beside(budgets: list[VehicleBudget]) -> str:
    lines = ["| vehicle | autopilot radio mean / peak [B/s] | of 57.6 kbit/s (peak) | RSSI link mean / peak [B/s] "
             "| of 57.6 kbit/s (peak) |", "|---|---|---|---|---|"]
    for b in budgets:
        am, ap_ = b.mean_by_component[1], b.peak_by_component[1]
        rm, rp = b.mean_by_component[191], b.peak_by_component[191]
        lines.append(f"| uav{b.vehicle} | {am:.0f} / {ap_:.0f} | {100 * ap_ / RADIO_BYTES_S:.0f} % | {rm:.0f} / {rp:.0f} | "
                     f"{100 * rp / RADIO_BYTES_S:.0f} % |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m sim_link.vehicles.budget", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenario")
    p.add_argument("--seed", type=int, default=None)
    p.add_argument("--signed", action="store_true", help="count the 13-byte MAVLink 2 signature too")
    p.add_argument("--path", choices=("through", "beside"), default="through",
                   help="RSSI through the autopilot's radio (default) or on a link of its own")
    p.add_argument("--message", choices=MESSAGES, default=BATCH2,
                   help="the RSSI message (default: UAVLOC_RSSI_BATCH2, as the companion emulator sends)")
    a = p.parse_args(argv)
    print(report(measure(load_scenario(a.scenario), seed=a.seed, signed=a.signed, message=a.message), a.path))
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
