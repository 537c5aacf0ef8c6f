"""One exception root for everything uavloc raises on purpose.

Library code raises these with the facts a person needs (file and line, vehicle id, operation,
MAVLink result code); only the CLI formats them and chooses exit codes.
"""

from __future__ import annotations


class UavlocError(Exception):
    """Root of all errors uavloc raises deliberately. ``str(err)`` is one readable sentence."""


class ConfigError(UavlocError):
    """A scenario/config value is missing, malformed or impossible.

    ``source`` is the file (or "<string>"), ``key`` the dotted key path that is wrong.
    """

    def __init__(self, message: str, *, source: str | None = None, key: str | None = None):
        self.source = source
        self.key = key
        self.message = message  # without the file and key (a command re-blames it on its flag)
        where = []
        if source:
            where.append(source)
        if key:
            where.append(f"key '{key}'")
        prefix = ": ".join([", ".join(where)]) + ": " if where else ""
        super().__init__(prefix + message)


class OutputError(ConfigError):
    """An output file or directory cannot be written (the directory refuses it, the disk is full);
    names the path and, where a flag gave it, the flag. Bad input: refused before any work where
    it can be foreseen."""


class FileFormatError(UavlocError):
    """A mission/area/data file is malformed. Names the file, the line or item, and the field."""

    def __init__(
        self,
        message: str,
        *,
        path: str | None = None,
        line: int | None = None,
        item: int | None = None,
        field: str | None = None,
    ):
        self.path = path
        self.line = line
        self.item = item
        self.field = field
        where = [path or "<string>"]
        if line is not None:
            where.append(f"line {line}")
        if item is not None:
            where.append(f"item {item}")
        if field is not None:
            where.append(f"field '{field}'")
        super().__init__(", ".join(where) + ": " + message)


class InfeasibleError(UavlocError):
    """The requested scenario or plan cannot be satisfied (energy budget, unreachable target, ...).
    ``target_id``: the one target to blame, if any; ``why``: the reason in that target's own terms
    (for a person's row, which already says who and where)."""

    def __init__(self, message: str, *, target_id=None, why: str | None = None):
        super().__init__(message)
        self.target_id = target_id
        self.why = why


class LinkError(UavlocError):
    """A MAVLink connection or exchange failed. ``vehicle`` names the vehicle/connection."""

    def __init__(self, message: str, *, vehicle: str | None = None, operation: str | None = None):
        self.vehicle = vehicle
        self.operation = operation
        where = []
        if vehicle:
            where.append(f"vehicle {vehicle}")
        if operation:
            where.append(operation)
        super().__init__((" ".join(where) + ": " if where else "") + message)


class MissionTransferError(LinkError):
    """A mission upload/download failed; carries the item seq and the MAV_MISSION_RESULT if known."""

    def __init__(
        self,
        message: str,
        *,
        vehicle: str | None = None,
        operation: str | None = None,
        seq: int | None = None,
        result: int | None = None,
        result_name: str | None = None,
    ):
        self.seq = seq
        self.result = result
        self.result_name = result_name
        extra = []
        if seq is not None:
            extra.append(f"item {seq}")
        if result_name is not None:
            extra.append(f"result {result_name}")
        elif result is not None:
            extra.append(f"result {result}")
        if extra:
            message = f"{message} ({', '.join(extra)})"
        super().__init__(message, vehicle=vehicle, operation=operation)


class CommandError(LinkError):
    """A COMMAND_LONG/INT was refused or not acknowledged."""


class EstimationError(UavlocError):
    """Bad input to the estimator (not: "not enough data", which is a normal result)."""


class Interrupted(UavlocError):
    """The operator stopped a running command (Ctrl-C, SIGTERM); ``signal`` is the signal number.
    ``str(err)`` says what was left in which state (e.g. which vehicles fly home)."""

    def __init__(self, message: str, *, signal: int = 2):
        self.signal = signal
        super().__init__(message)
