"""The ``uavloc`` command line. Each subcommand lives in its own module in this package.

A command module defines ``register(subparsers)`` which adds its parser and sets
``func=run``; ``run(args) -> int`` returns the exit code. Heavy imports stay inside ``run`` so
``uavloc --help`` is quick. This is the only place errors are turned into text and exit codes.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import importlib.util
import logging
import os
import sys

from ..errors import ConfigError, FileFormatError, InfeasibleError, Interrupted, LinkError, UavlocError

# Command modules, in the order ``uavloc --help`` lists them.
COMMANDS = [
    "demo",
    "plan",
    "preview",
    "localize",
    "route",
    "sim",
    "sitl",
    "upload",
    "download",
    "daemon",
    "pack-fresh",
    "experiment",
    "sense",
    "bench",
]

EXIT_BAD_INPUT = 2
EXIT_LINK = 3
EXIT_FAILED = 1


def _version() -> str:
    """The installed distribution's version (the package's own when run from a checkout)."""
    from importlib import metadata

    from .. import __version__

    try:
        return metadata.version("uavloc")
    except metadata.PackageNotFoundError:
        return __version__


class _Parser(argparse.ArgumentParser):
    """A bad flag is one sentence naming it (exit 2), without the usage block above it."""

    def error(self, message: str):
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="uavloc",
        description="Find people from the RSSI of their phones with a UAV fleet over MAVLink.",
    )
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output (-vv for debug)")
    parser.add_argument("--version", action="version", version=f"uavloc {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        modname = f"{__name__}.{name.replace('-', '_')}"
        if importlib.util.find_spec(modname) is None:
            continue
        importlib.import_module(modname).register(sub)
    return parser


def exit_code_for(err: UavlocError) -> int:
    if isinstance(err, (ConfigError, FileFormatError, InfeasibleError)):
        return EXIT_BAD_INPUT
    if isinstance(err, LinkError):
        return EXIT_LINK
    return EXIT_FAILED


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as done:  # --help, --version, or a bad flag (its sentence is printed)
        return done.code if isinstance(done.code, int) else 0
    previous = (sys.stdout, sys.stderr)
    if getattr(args, "command", None) in ("daemon", "demo"):  # a closed or stalled console never stops a search
        from ..console import install  # noqa: PLC0415

        install()
    level = logging.WARNING - 10 * min(args.verbose, 2)
    logging.basicConfig(level=level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_BAD_INPUT
    try:
        return int(args.func(args) or 0)
    except Interrupted as err:
        print(f"uavloc {args.command}: {err}", file=sys.stderr)
        return 128 + err.signal
    except UavlocError as err:
        print(f"uavloc {args.command}: error: {err}", file=sys.stderr)
        return exit_code_for(err)
    except KeyboardInterrupt:
        print(f"uavloc {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader went away (``uavloc preview x.plan | head``): not an error worth a traceback.
        with contextlib.suppress(OSError):
            sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - silence the flush at exit
        return 0
    finally:
        from ..console import drain  # noqa: PLC0415

        drain()  # the last lines (the results table) are written before the process ends
        # main() called in-process (tests, a host program) leaves the caller's streams as it found them
        sys.stdout, sys.stderr = previous


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
