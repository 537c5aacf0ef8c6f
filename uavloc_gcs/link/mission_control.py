"""Flying a mission on a real autopilot: streams, arming, start, switch in flight, return home.

Each sequence here was measured on ArduCopter and PX4 SITL (tests/sitl/test_flight.py keeps the
measurement as a test); what differs is a named field of :class:`~.autopilots.Flavour`:

* start on the ground -- put ArduPilot in GUIDED (it does not arm in AUTO; GUIDED needs a position,
  so it is never armed in a manual mode waiting for one), PX4 in Hold (``Flavour.arm_mode``), arm
  (waiting until the vehicle is ready, see :func:`arm_when_ready`), make ``first_seq`` current,
  MISSION_START.
  ArduPilot DENIES MISSION_START with a first item other than 0 and resumes from its current
  item (``mission_start_takes_first_item``), so the first item is set with set-current first.
* switch to a just-uploaded mission in flight -- PX4 restarts a mission uploaded in AUTO.MISSION
  from item 0 by itself (``upload_restarts_mission``) and answers DO_SET_MISSION_CURRENT
  UNSUPPORTED (``set_current_command``: it takes the legacy MISSION_SET_CURRENT message);
  ArduPilot keeps its item index across an upload, so the item is set; after set-current on a
  finished mission ArduPilot's AUTO holds until MISSION_START (``finished_mission_needs_start``).
* return home -- MAV_CMD_NAV_RETURN_TO_LAUNCH on both.
"""

from __future__ import annotations

import asyncio
import logging
import time
from typing import Callable, Mapping

from ..dialect import mavlink
from ..errors import CommandError
from .autopilots import Flavour
from .command import MAV_RESULT_UNSUPPORTED, arm, command_long, return_to_launch, set_mode, start_mission
from .connection import Link

log = logging.getLogger(__name__)

# Messages the daemon needs and the rate it asks for (Hz, in the vehicle's time).
DEFAULT_STREAMS: dict[str, float] = {
    "SYSTEM_TIME": 1.0, "GLOBAL_POSITION_INT": 4.0, "MISSION_CURRENT": 2.0, "SYS_STATUS": 1.0,
    "HOME_POSITION": 0.5, "EXTENDED_SYS_STATE": 1.0,
    "GPS_RAW_INT": 0.5,  # (the fix type: ready to arm, service/vehicle.py)
}
STREAM_COMMAND_RETRIES = 2
ARM_READY_TIMEOUT_S = 90.0  # wall seconds to keep retrying a refused arm (EKF settling after boot)
ARM_BACKOFF_S = (0.5, 1.0, 2.0, 3.0)  # waits between refused arms, the last repeated
ARM_REFUSALS = (mavlink.MAV_RESULT_FAILED, mavlink.MAV_RESULT_DENIED, mavlink.MAV_RESULT_TEMPORARILY_REJECTED)
MISSION_STATE_COMPLETED = 5  # MISSION_STATE_COMPLETE in MISSION_CURRENT.mission_state
AP_DATA_STREAM_HZ = 4  # REQUEST_DATA_STREAM fallback: every ArduPilot stream group at this rate
SET_CURRENT_CONFIRM_S = 3.0
MISSION_VALID_TIMEOUT_S = 15.0  # wall seconds to keep repeating a refused MISSION_START
POSITION_READY_TIMEOUT_S = 120.0  # wall seconds to wait for a freshly booted vehicle to know where it is
POSITION_POLL_S = 2.0
START_CONFIRM_S = 3.0  # wall seconds to wait for a HEARTBEAT after a mission start
STATUSTEXT_GRACE_S = 1.5  # wall seconds to wait for the text explaining a refusal (PX4 SITL: 0.6 s after the ACK)
STATUSTEXT_CHUNK_GAP_S = 0.2
# Refusals that no repetition changes: the mission on board (or the vehicle's place in it) is wrong
# for a start. ArduCopter ModeAuto::init: armed and landed, a mission that does not go on with a
# take-off is refused with this text and MISSION_START answers FAILED.
FINAL_START_REFUSALS = ("missing takeoff",)


class StartRefused(CommandError):
    """The vehicle refused to start its mission for a reason a repetition does not change
    (``reason``: its own words, e.g. "Auto: Missing Takeoff Cmd")."""


def final_start_refusal(text: str | None) -> bool:
    """Whether a STATUSTEXT says the start can only succeed with another mission."""
    return text is not None and any(w in text.lower() for w in FINAL_START_REFUSALS)


async def request_streams(link: Link, system: int, flavour: Flavour,
                          rates: Mapping[str, float] | None = None, *, component: int = 1) -> dict[str, bool]:
    """Ask the vehicle to send each message in ``rates`` (name -> Hz) with SET_MESSAGE_INTERVAL.

    Real autopilots stream little on a fresh link (ArduPilot: only HEARTBEAT, HOME_POSITION,
    STATUSTEXT until asked; PX4: no SYSTEM_TIME on the ground-station link). Returns which
    messages were accepted. Where ArduPilot refuses or does not answer, REQUEST_DATA_STREAM for
    all its stream groups is sent as well (it has no ACK; the messages simply start).
    """
    rates = dict(DEFAULT_STREAMS if rates is None else rates)
    accepted: dict[str, bool] = {}
    for name, hz in rates.items():
        msg_id = getattr(mavlink, f"MAVLINK_MSG_ID_{name}")
        interval_us = -1 if hz <= 0 else int(1e6 / hz)
        try:
            await command_long(link, system, component, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, (msg_id, interval_us),
                               retries=STREAM_COMMAND_RETRIES)
            accepted[name] = True
        except CommandError as err:
            log.info("vehicle %d: %s", system, err)
            accepted[name] = False
    if flavour.name == "ardupilot" and not all(accepted.values()):
        await link.send(link.mav.request_data_stream_encode(system, component, mavlink.MAV_DATA_STREAM_ALL,
                                                            AP_DATA_STREAM_HZ, 1))
    return accepted


class StatusWatch:
    """The vehicle's latest STATUSTEXTs while open (to name why a command was refused).

    A long text arrives in chunks sharing a non-zero ``id`` (PX4 splits "Arming denied: Resolve
    system health failures first" in two); chunks are joined. PX4 sends the text about 0.6 s after
    the refusing COMMAND_ACK (measured on SITL), so :meth:`reason_soon` waits a moment for it.

    Only a text that can explain a refusal is named as the reason: severity WARNING or worse, or
    worded like a refusal. Autopilots also chat at INFO: PX4 SITL's "[logger] ./log/....ulg"
    arrived between an arm refusal's ACK and its "Arming denied" in CI, and was once named as the
    reason."""

    def __init__(self, link: Link, system: int):
        # the latest texts, oldest first: [text, could it explain a refusal, mark() count when it came]
        self._texts: list[list] = []
        self._marks = 0
        self._last_id = 0
        self._arrived = asyncio.Event()  # an explaining text arrived since mark()
        self._sub = link.subscribe("STATUSTEXT", source_system=system, callback=self._on)

    @staticmethod
    def explains(text: str, severity: int) -> bool:
        """Could this text say why a command was refused?"""
        low = text.lower()
        worded = (low.startswith(("prearm", "arm", "preflight", "arming", "disarm"))
                  or any(w in low for w in ("denied", "refused", "failed", "rejected")))
        return worded or severity <= mavlink.MAV_SEVERITY_WARNING

    def _on(self, msg) -> None:
        text = str(msg.text).rstrip("\x00")
        severity = int(getattr(msg, "severity", mavlink.MAV_SEVERITY_INFO))
        chunk_id = int(getattr(msg, "id", 0) or 0)
        if chunk_id and chunk_id == self._last_id and int(getattr(msg, "chunk_seq", 0) or 0) > 0 and self._texts:
            last = self._texts[-1]
            last[0] = (last[0] + text).strip()
            last[1] = last[1] or self.explains(last[0], severity)
        else:
            self._texts.append([text.strip(), self.explains(text, severity), self._marks])
            del self._texts[:-20]
        self._last_id = chunk_id
        if self._texts[-1][1]:
            self._arrived.set()

    def mark(self) -> None:
        """Forget that a text arrived (call before sending the command whose refusal to explain)."""
        self._arrived.clear()
        self._marks += 1

    def reason(self) -> str | None:
        """The latest text that could explain a refusal, preferring one that came since :meth:`mark`;
        None when the vehicle said nothing of the kind (its INFO chatter is not a reason)."""
        explaining = [(text, marks == self._marks) for text, explains, marks in self._texts if explains]
        fresh = [text for text, new in explaining if new]
        return fresh[-1] if fresh else (explaining[-1][0] if explaining else None)

    def fresh(self) -> list[str]:
        """Every explaining text that came since :meth:`mark`, oldest first."""
        return [text for text, explains, marks in self._texts if explains and marks == self._marks]

    async def reason_soon(self, wait_s: float = STATUSTEXT_GRACE_S) -> str | None:
        """:meth:`reason`, after waiting up to ``wait_s`` for an explaining text when none came
        since :meth:`mark` (and a moment more for the rest of a chunked text)."""
        if not self._arrived.is_set():
            try:
                await asyncio.wait_for(self._arrived.wait(), wait_s)
                await asyncio.sleep(STATUSTEXT_CHUNK_GAP_S)
            except TimeoutError:
                pass
        return self.reason()

    def close(self) -> None:
        self._sub.close()

    def __enter__(self) -> "StatusWatch":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


async def arm_when_ready(link: Link, system: int, component: int = 1, *,
                         timeout_s: float = ARM_READY_TIMEOUT_S) -> None:
    """Arm, retrying with backoff while the vehicle refuses (a freshly booted ArduCopter says
    "Arm: Accels inconsistent" or waits for its EKF to use GPS). After ``timeout_s`` the
    CommandError names the autopilot's own reason from its latest STATUSTEXT."""
    deadline = time.monotonic() + timeout_s
    attempt = 0
    with StatusWatch(link, system) as watch:
        while True:
            watch.mark()
            try:
                await arm(link, system, component)
                return
            except CommandError as err:
                result = getattr(err, "result", None)
                if result not in ARM_REFUSALS or time.monotonic() >= deadline:
                    reason = await watch.reason_soon()
                    message = str(err).split(": ", 1)[-1] if err.vehicle else str(err)
                    final = CommandError(f"{message}{f' ({reason})' if reason else ''}"
                                         f"{f' after {attempt + 1} tries' if attempt else ''}",
                                         vehicle=str(system), operation="arm")
                    final.result = result
                    final.reason = reason
                    raise final from None
                wait = ARM_BACKOFF_S[min(attempt, len(ARM_BACKOFF_S) - 1)]
                log.info("vehicle %d: arming refused (%s); retrying in %g s", system, watch.reason(), wait)
                attempt += 1
                await asyncio.sleep(min(wait, max(0.0, deadline - time.monotonic())))


async def set_current(link: Link, system: int, component: int, flavour: Flavour, seq: int) -> None:
    """Make ``seq`` the current item: DO_SET_MISSION_CURRENT where the autopilot takes it, else the
    legacy MISSION_SET_CURRENT message, confirmed by MISSION_CURRENT reporting ``seq`` or later (PX4
    passes a DO_CHANGE_SPEED at once, so the item itself may never be reported)."""
    if flavour.set_current_command:
        try:
            await command_long(link, system, component, mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, (seq, 0))
            return
        except CommandError as err:
            if getattr(err, "result", None) != MAV_RESULT_UNSUPPORTED:
                raise
    with link.subscribe("MISSION_CURRENT", source_system=system, predicate=lambda m: m.seq >= seq) as cur:
        for _ in range(3):
            await link.send(link.mav.mission_set_current_encode(system, component, seq))
            try:
                await cur.get(SET_CURRENT_CONFIRM_S)
                return
            except TimeoutError:
                continue
    raise CommandError(f"MISSION_SET_CURRENT {seq}: the vehicle never reported item {seq} or later as current",
                       vehicle=str(system), operation="set current item")


async def start_when_valid(link: Link, system: int, component: int, first_seq: int = 0, *,
                           timeout_s: float = MISSION_VALID_TIMEOUT_S,
                           before_start: Callable[[], None] | None = None) -> None:
    """MISSION_START, repeated while the vehicle refuses it for a short while: PX4 checks a new
    mission in the background and DENIES the start until then ("Mission start denied! No valid
    mission", seen on SITL right after an upload). The final error names the STATUSTEXT reason;
    a refusal no repetition changes ("Auto: Missing Takeoff Cmd") is :class:`StartRefused` at once.

    ``before_start()`` is called right before every MISSION_START is sent and may raise: the
    caller's check of the vehicle's state at the moment of the start, after every await."""
    deadline = time.monotonic() + timeout_s
    attempt = 0
    with StatusWatch(link, system) as watch:
        while True:
            watch.mark()
            if before_start is not None:
                before_start()
            try:
                await start_mission(link, system, component, first_seq, 0)
                return
            except CommandError as err:
                final = False
                if getattr(err, "result", None) == mavlink.MAV_RESULT_FAILED:  # (what ArduCopter answers)
                    await watch.reason_soon()
                    # (ArduCopter says "Auto: Missing Takeoff Cmd", then "Mode change to Auto failed: init failed")
                    final = any(final_start_refusal(text) for text in watch.fresh())
                if final or getattr(err, "result", None) not in ARM_REFUSALS or time.monotonic() >= deadline:
                    reason = await watch.reason_soon()
                    if final:  # the words that make it final, not the chatter after them
                        reason = next(text for text in watch.fresh() if final_start_refusal(text))
                    if reason:
                        err.args = (f"{err.args[0]} ({reason})",)
                        err.reason = reason
                    if final:
                        refused = StartRefused(str(err).split(": ", 1)[-1] if err.vehicle else str(err),
                                               vehicle=str(system), operation="start")
                        refused.result, refused.reason = getattr(err, "result", None), reason
                        raise refused from None
                    raise
                attempt += 1
                await asyncio.sleep(ARM_BACKOFF_S[min(attempt - 1, len(ARM_BACKOFF_S) - 1)])


async def wait_until_positioned(link: Link, system: int, component: int = 1, *,
                                timeout_s: float = POSITION_READY_TIMEOUT_S) -> None:
    """Wait until the vehicle has set its home, i.e. knows where it is (HOME_POSITION, asked for
    with MAV_CMD_REQUEST_MESSAGE). Measured on ArduCopter SITL started together with the daemon:
    it arms before its EKF uses GPS, then refuses AUTO ("Mode change to Auto failed: requires
    position") until its arming times out and it disarms, so a start that only retried the
    MISSION_START left it in AUTO on the ground, disarmed, for good."""
    from .mission_download import home_position  # noqa: PLC0415 - mission_download imports command

    deadline = time.monotonic() + timeout_s
    with StatusWatch(link, system) as watch:
        while True:
            left = deadline - time.monotonic()
            if await home_position(link, system, component, timeout_s=max(0.1, min(POSITION_POLL_S, left))):
                return
            if time.monotonic() >= deadline:
                reason = watch.reason()
                raise CommandError(f"no home position after {timeout_s:g} s: the vehicle does not know where it is"
                                   f"{f' ({reason})' if reason else ''}", vehicle=str(system), operation="start")


async def start_mission_from(link: Link, system: int, component: int, flavour: Flavour, first_seq: int, *,
                             armed: bool, mode: str, timeout_s: float = POSITION_READY_TIMEOUT_S,
                             before_start: Callable[[], None] | None = None) -> None:
    """Arm on the ground (when not ``armed``) and fly the uploaded mission from ``first_seq``.

    Judged from the vehicle, not only from the ACKs: a start counts once a HEARTBEAT sent after
    it shows the vehicle armed. Measured on ArduCopter SITL started together with the daemon: it
    arms before its EKF uses GPS, refuses AUTO ("Mode change to Auto failed: requires position"),
    disarms by itself after DISARM_DELAY, and a MISSION_START accepted later leaves it in AUTO,
    disarmed, on the ground for good. Such a start is done again (mode, arm, start) until
    ``timeout_s``; a :class:`StartRefused` is not (the mission itself is wrong for a start).
    ``before_start()``: see :func:`start_when_valid` (also called before arming)."""
    if not armed:
        await wait_until_positioned(link, system, component, timeout_s=timeout_s)
    deadline = time.monotonic() + timeout_s
    beats: list = []
    sub = link.subscribe("HEARTBEAT", source_system=system,
                         callback=lambda m: beats.append(m) if m.autopilot != mavlink.MAV_AUTOPILOT_INVALID else None)
    try:
        attempt = 0
        while True:
            hb = beats[-1] if beats else None
            now_armed = armed if hb is None else bool(hb.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
            now_mode = mode if hb is None else flavour.mode_name(hb.custom_mode, hb.type)
            try:
                if not now_armed:
                    if before_start is not None:
                        before_start()
                    if flavour.arm_mode and now_mode not in flavour.armable_modes:
                        await set_mode(link, system, component, flavour.arm_mode, autopilot=flavour)
                    await arm_when_ready(link, system, component)
                await _start_from(link, system, component, flavour, first_seq, before_start)
            except CommandError as err:
                # only a vehicle that answered "no" is asked again here; a missing ACK goes to the
                # caller, which judges from the vehicle's telemetry whether it started anyway
                if isinstance(err, StartRefused) or getattr(err, "result", None) not in ARM_REFUSALS \
                        or time.monotonic() >= deadline:
                    raise
                attempt += 1
                await asyncio.sleep(ARM_BACKOFF_S[min(attempt - 1, len(ARM_BACKOFF_S) - 1)])
                continue
            started = len(beats)
            wait_until = time.monotonic() + START_CONFIRM_S
            while len(beats) == started and time.monotonic() < wait_until:
                await asyncio.sleep(0.05)
            if len(beats) == started or beats[-1].base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED:
                return  # armed after the start (or the vehicle is silent: the daemon judges it)
            if time.monotonic() >= deadline:
                raise CommandError("the mission started but the vehicle is disarmed on the ground",
                                   vehicle=str(system), operation="start")
            attempt += 1
            log.info("vehicle %d: mission started while disarmed; arming and starting again", system)
    finally:
        sub.close()


async def _start_from(link: Link, system: int, component: int, flavour: Flavour, first_seq: int,
                      before_start: Callable[[], None] | None = None) -> None:
    if flavour.mission_start_takes_first_item:
        await start_when_valid(link, system, component, first_seq, before_start=before_start)
        return
    # Also when first_seq is the first item: ArduPilot keeps its item index across an upload and
    # MISSION_START resumes a mission stopped by RTL from there (a second search on the same
    # vehicles started the new scan at its old item 11, on the ground: "Auto: Missing Takeoff Cmd").
    await set_current(link, system, component, flavour, first_seq)
    await start_when_valid(link, system, component, 0, before_start=before_start)


async def switch_mission(link: Link, system: int, component: int, flavour: Flavour, first_seq: int, *,
                         in_mission_mode: bool, mission_state: int | None,
                         before_start: Callable[[], None] | None = None) -> None:
    """Fly the just-uploaded mission from ``first_seq`` while airborne (``before_start``: see
    :func:`start_when_valid`; PX4 arms by MISSION_START, so a vehicle that landed meanwhile would
    take off)."""
    if in_mission_mode and flavour.upload_restarts_mission and first_seq == flavour.first_mission_seq:
        return  # the upload itself restarted it from its first item
    await set_current(link, system, component, flavour, first_seq)
    finished = mission_state == MISSION_STATE_COMPLETED
    # ArduPilot ignores MISSION_START(0, 0) while its mission runs and resumes from the current
    # item when it does not, so it is always sent there: the state we last heard may be stale.
    if not in_mission_mode or finished or flavour.finished_mission_needs_start:
        await start_when_valid(link, system, component, first_seq if flavour.mission_start_takes_first_item else 0,
                               before_start=before_start)


async def return_home(link: Link, system: int, component: int = 1) -> None:
    """RTL: the vehicle flies home and lands (both autopilots disarm after landing)."""
    await return_to_launch(link, system, component)


__all__ = ["DEFAULT_STREAMS", "StartRefused", "StatusWatch", "arm_when_ready", "final_start_refusal", "request_streams",
           "return_home", "set_current", "start_mission_from", "start_when_valid", "switch_mission"]
