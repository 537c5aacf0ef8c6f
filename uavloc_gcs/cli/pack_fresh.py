"""``uavloc pack-fresh VEHICLE --out DIR``: the operator says a waiting vehicle has a fresh pack
(issue 38). The running daemon reads it from its store (``DIR/search.sqlite``) while the vehicle
waits, and launches the vehicle unless the vehicle itself reports a figure that says the pack is
not fresh (service/swaps.py)."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("pack-fresh", help="tell the running daemon that a waiting vehicle has a fresh pack",
                       description="Tell the running daemon that a vehicle waiting on the ground has a fresh "
                                   "pack: it is checked and given its next sortie.")
    p.add_argument("vehicle", type=int, metavar="VEHICLE", help="the vehicle's system id")
    p.add_argument("--out", required=True, metavar="DIR", help="the running daemon's --out directory")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..service.store import request_pack_fresh

    request_pack_fresh(Path(args.out) / "search.sqlite", args.vehicle)
    print(f"told the daemon in {args.out}: vehicle {args.vehicle} has a fresh pack (it is launched only if "
          "it does not report a pack that is not fresh)")
    return 0
