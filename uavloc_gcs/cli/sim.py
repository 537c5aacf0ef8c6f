"""``uavloc sim``: run fake MAVLink vehicles (or the companion emulator) until Ctrl-C.

    uavloc sim examples/paper.toml [--speedup 20] [--loss 0.05] [--seed 1] [--signing-key HEX]
    uavloc sim --companion --autopilot tcp:127.0.0.1:5760 examples/paper.toml
    uavloc sim --no-rssi examples/paper.toml &   # fake autopilots only, then attach the emulator:
    uavloc sim --companion --autopilot udpout:127.0.0.1:14561 examples/paper.toml

Vehicle i is MAVLink system i on UDP ``host:(base_port + i)``: with the default base port 14560,
uav1 listens on 14561, uav2 on 14562, ... A ground station connects with ``udpout:127.0.0.1:14561``.
"""

from __future__ import annotations

import argparse

from ..errors import ConfigError
from ._inputs import number


def register(sub) -> None:
    p = sub.add_parser("sim", help="run fake MAVLink vehicles (software in the loop) or the companion emulator",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenario", help="scenario TOML (fleet, area, simulated people), or a shipped one by name: "
                                    "paper, small, field")
    p.add_argument("--speedup", type=number(float, above=0, max=1000), default=None, help="simulated seconds per real second "
                   "(default: simulation.speedup of the scenario)")
    p.add_argument("--loss", type=number(float, min=0, max=1), default=0.0, help="packet loss probability, each direction (0-1)")
    p.add_argument("--latency-ms", type=number(float, min=0, max=60000), default=0.0, help="one-way link latency [ms]")
    p.add_argument("--seed", type=number(int, min=0, max=2**32 - 1), default=None, help="world and fault seed (default: simulation.seed)")
    p.add_argument("--signing-key", default=None, metavar="HEX", help="MAVLink 2 signing key, 64 hex digits")
    p.add_argument("--base-port", type=number(int, min=0, max=65535), default=14560, help="vehicle i listens on base port + i (default 14560)")
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default loopback)")
    p.add_argument("--gcs", default=None, metavar="HOST:PORT", help="also stream to this ground station address")
    p.add_argument("--status-s", type=number(float, min=0), default=10.0, help="print a status line every N real seconds (0: off)")
    p.add_argument("--no-rssi", action="store_true",
                   help="no onboard RSSI: an external companion (e.g. uavloc sim --companion) provides it; "
                        "the vehicles then forward messages between their peers as an autopilot routes them")
    p.add_argument("--companion", action="store_true", help="run the companion emulator against a real autopilot")
    p.add_argument("--autopilot", default=None, metavar="URL",
                   help="with --companion: tcp:HOST:PORT, udpout:HOST:PORT or udpin:HOST:PORT")
    p.add_argument("--rssi-to", default=None, metavar="URL",
                   help="with --companion: send the RSSI beside the autopilot to this connection (e.g. "
                        "udpout:127.0.0.1:14600, the daemon's [link] rssi_connections entry) instead of "
                        "through it; PX4 drops the RSSI message, ArduPilot forwards it only with MAVn_OPTIONS bit 3")
    p.add_argument("--via-sense", action="store_true",
                   help="turn the simulated slots into radiotap probe requests and send what uavloc sense's parser "
                        "and aggregator make of them (the companion's, or the fake vehicles' onboard RSSI; "
                        "docs/guide/sense.md)")
    p.set_defaults(func=run)


def _key(text: str | None) -> bytes | None:
    if text is None:
        return None
    try:
        key = bytes.fromhex(text)
    except ValueError:
        key = b""
    if len(key) != 32:
        raise ConfigError("must be 64 hexadecimal digits (a 32-byte key)", key="--signing-key")
    return key


def _address(text: str | None):
    if text is None:
        return None
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit():
        raise ConfigError(f"{text!r} is not HOST:PORT", key="--gcs")
    return host, int(port)


def run(args) -> int:
    import asyncio
    import signal

    from uavloc_gcs.scenario import load_scenario

    scenario = load_scenario(args.scenario)
    key = _key(args.signing_key)
    if not 0.0 <= args.loss <= 1.0:
        raise ConfigError(f"{args.loss} is not a probability in [0, 1]", key="--loss")
    if args.speedup is not None and not args.speedup > 0:
        raise ConfigError(f"{args.speedup} must be > 0", key="--speedup")
    if args.companion and not args.autopilot:
        raise ConfigError("--companion needs --autopilot URL (e.g. tcp:127.0.0.1:5760)", key="--autopilot")
    if not args.companion and not 0 <= args.base_port <= 65535 - scenario.fleet.vehicles:
        raise ConfigError(f"{args.base_port} leaves no room for {scenario.fleet.vehicles} ports", key="--base-port")

    async def main() -> None:
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGTERM,):
            loop.add_signal_handler(sig, stop.set)
        if args.companion:
            await _run_companion(args, scenario, key, stop)
        else:
            await _run_fleet(args, scenario, key, stop)

    try:
        asyncio.run(main())
    except KeyboardInterrupt:
        print("uavloc sim: stopped", flush=True)
    return 0


async def _run_companion(args, scenario, key, stop) -> None:
    from sim_link.vehicles.companion import CompanionEmulator
    from sim_link.vehicles.connection import parse_url

    parse_url(args.autopilot)
    if args.rssi_to is not None:
        parse_url(args.rssi_to)
    comp = CompanionEmulator(scenario, args.autopilot, seed=args.seed, signing_key=key, rssi_url=args.rssi_to,
                             via_sense=args.via_sense)
    path = f"beside the autopilot to {args.rssi_to}" if args.rssi_to else "through the autopilot"
    print(f"uavloc sim: companion emulator on {args.autopilot}: {len(comp.world)} simulated people, "
          f"UAVLOC_RSSI_BATCH from component 191 {path}; Ctrl-C to stop", flush=True)
    await comp.run(stop)


async def _run_fleet(args, scenario, key, stop) -> None:
    import asyncio

    from sim_link.vehicles.faults import FaultConfig
    from sim_link.vehicles.fleet import FakeFleet

    faults = FaultConfig(loss=args.loss, latency_s=args.latency_ms / 1000.0)
    fleet = FakeFleet(scenario, speedup=args.speedup, seed=args.seed, base_port=args.base_port, host=args.host,
                      faults=faults, signing_key=key, gcs_address=_address(args.gcs),
                      onboard_rssi=not args.no_rssi, route=args.no_rssi,
                      vehicle_options={"via_sense": True} if args.via_sense else None)
    async with fleet:
        f = scenario.fleet
        print(f"uavloc sim: {f.vehicles} fake {f.autopilot} vehicles, speed-up {fleet.speedup:g}x, seed {fleet.seed}, "
              f"{len(fleet.world)} simulated people" + (", signing on" if key else "")
              + (f", loss {args.loss:g}" if args.loss else ""), flush=True)
        for (name, url), v in zip(fleet.endpoints, fleet.vehicles):
            port = url.rsplit(":", 1)[1]
            print(f"  {name}: MAVLink system {v.sysid}, UDP port {port}  (connect: {url})", flush=True)
        print(f"mission clock: t = 0 at UNIX {fleet.epoch_unix_s:.0f} s (SYSTEM_TIME); Ctrl-C to stop", flush=True)
        while not stop.is_set():
            try:
                await asyncio.wait_for(stop.wait(), args.status_s if args.status_s > 0 else 3600)
            except asyncio.TimeoutError:
                if args.status_s > 0:
                    print(_status(fleet), flush=True)


def _status(fleet) -> str:
    parts = [f"t={fleet.now_s():7.1f}s"]
    for v in fleet.vehicles:
        x, y, z = v.position_xyz_m
        parts.append(f"uav{v.sysid} {v.mode}{'*' if v.armed else ''} ({x:.0f},{y:.0f},{z:.0f}) "
                     f"{100 * v.battery_remaining_fraction:.0f}%")
    return "  ".join(parts)
