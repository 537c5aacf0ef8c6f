"""How an exchange with a vehicle is judged. (The vehicle's states and moves: :mod:`.vehiclelife`.)

An exchange with a vehicle (upload, start, switch mission, return home) is not judged from its
acknowledgement alone: on a radio that loses packets the ACK of a command the vehicle carried out
is lost as often as the command. :func:`persist` runs the exchange; when it fails it waits for
fresh telemetry and asks ``done()`` whether the vehicle now does what was asked (its mode,
MISSION_CURRENT, mission on board); if not, it tries again after a backoff. Only when every try
failed and the vehicle still does not do it is the exchange a failure: the caller then marks the
vehicle unusable.
"""

from __future__ import annotations

import asyncio
import math
import logging
import time
from typing import Awaitable, Callable

from ..errors import LinkError
from .vehiclelife import ANY_TO, NEXT, allowed  # noqa: F401 (the one state table, re-exported)

log = logging.getLogger(__name__)

TRIES = 3
BACKOFF_S = (0.5, 1.0, 2.0)  # wall seconds before the 2nd, 3rd, ... try
SETTLE_S = 2.0  # wall seconds to wait for telemetry that shows the exchange's effect


class ExchangeFailed(LinkError):
    """Every try of an exchange failed and the vehicle does not do what was asked."""


async def persist(action: Callable[[], Awaitable[None]], done: Callable[[], bool], *, what: str,
                  vehicle: int, tries: int = TRIES, backoff_s=BACKOFF_S, settle_s: float = SETTLE_S,
                  heard_since: Callable[[float], bool] | None = None,
                  on_retry: Callable[[str], None] | None = None,
                  check: Callable[[], Awaitable[bool]] | None = None,
                  wall: Callable[[], float] = time.monotonic) -> str:
    """Run ``action`` until it succeeds or the vehicle is seen doing it; "acked" or "judged".

    ``done()`` judges from the latest telemetry; ``heard_since(t)`` says whether telemetry newer
    than wall time ``t`` has arrived (so the judgement is not made on what was known before);
    ``check()`` is an optional slower judgement that talks to the vehicle (e.g. reading the
    mission back). Raises :class:`ExchangeFailed` naming the last error.

    ``done()`` is also watched while the action runs: a command whose ACKs are lost is resent
    for seconds, and a vehicle can do what it was told, and be done with it, before the action
    gives up (a short look flown and landed from while MISSION_START waited for its ACK, at a
    simulator's speed-up). Judging only afterwards would then find it not doing it and tell it
    again: a landed vehicle sent out a second time.
    """
    last: LinkError | None = None
    for attempt in range(tries):
        if attempt:
            await asyncio.sleep(backoff_s[min(attempt - 1, len(backoff_s) - 1)])
        # the same judgement, with no deadline, for as long as the action runs
        watcher = asyncio.ensure_future(_judged(done, wall(), math.inf, heard_since, wall))
        try:
            await action()
            return "acked"
        except LinkError as exc:
            last = exc
            failed_at = wall()
        finally:
            seen = watcher.done() and watcher.result()
            watcher.cancel()
        if seen or await _judged(done, failed_at, settle_s, heard_since, wall):
            log.info("vehicle %d %s: %s, but the vehicle does it", vehicle, what, last)
            return "judged"
        if check is not None:
            try:
                if await check():
                    return "judged"
            except LinkError as exc:
                log.info("vehicle %d %s: check failed: %s", vehicle, what, exc)
        if on_retry is not None and attempt + 1 < tries:
            on_retry(f"vehicle {vehicle} {what}: {last}; trying again")
    raise ExchangeFailed(f"{what} failed {tries} times and the vehicle does not do it; last: {last}",
                         vehicle=str(vehicle))


async def _judged(done, since: float, settle_s: float, heard_since, wall) -> bool:
    deadline = wall() + settle_s
    while True:
        fresh = heard_since is None or heard_since(since)
        if fresh and done():
            return True
        if wall() >= deadline:
            return False
        await asyncio.sleep(0.05)
