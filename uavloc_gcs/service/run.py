"""Run one search end to end and write what the operator gets (shared by ``uavloc daemon`` and
``uavloc demo``): the daemon, then the results table, people.csv/geojson/kml and result.png."""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
import math
import signal
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np

from ..scenario import Scenario
from .daemon import Daemon, DaemonOptions
from .labels import PersonLabels
from .liveview import LiveView
from .outcome import SearchOutcome, coverage_statement, statement_for
from .lost import mark_lost, title_mark
from .partial import TITLE_MARK, mark_partial
from .results import PersonResult, results_table, write_results
from .store import StoreReader


@dataclass(frozen=True)
class RunResult:
    outcome: SearchOutcome
    people: tuple[PersonResult, ...]  # the outcome's, plus simulated people never heard
    table: str
    files: tuple[Path, ...]


def connections_for(scenario: Scenario) -> list[tuple[int, str]]:
    """[(system id, connection)] from the config's [link] section (vehicle i+1 = entry i)."""
    from ..errors import ConfigError  # noqa: PLC0415

    conns = scenario.link.connections
    if not conns:
        raise ConfigError("no vehicle connections: add [link] connections = [\"udpout:HOST:PORT\", ...] "
                          "with one entry per vehicle", source=scenario.source, key="link.connections")
    from ..link import parse_connection  # noqa: PLC0415

    for i, c in enumerate(conns):
        try:
            parse_connection(c)
        except ConfigError as exc:
            raise ConfigError(f"entry {i} ({c!r}) for vehicle {i + 1}: {exc}", source=scenario.source,
                              key="link.connections") from None
    return [(i + 1, c) for i, c in enumerate(conns)]


def rssi_connections_for(scenario: Scenario) -> tuple[tuple[int, str], ...]:
    """[(system id, RSSI connection)] from [link] rssi_connections ("" entries left out)."""
    from ..errors import ConfigError  # noqa: PLC0415
    from ..link import parse_connection  # noqa: PLC0415

    out = []
    for i, c in enumerate(scenario.link.rssi_connections or []):
        if not c:
            continue
        try:
            parse_connection(c)
        except ConfigError as exc:
            raise ConfigError(f"entry {i} ({c!r}) for vehicle {i + 1}: {exc}", source=scenario.source,
                              key="link.rssi_connections") from None
        out.append((i + 1, c))
    return tuple(out)


async def _run(daemon: Daemon, scenario: Scenario, options: DaemonOptions, web, on_web_url,
               finish: Callable[[SearchOutcome], "RunResult"],
               on_result: Callable[["RunResult"], None] | None) -> "RunResult":
    server = feed = None
    if web is not None:
        from .web import MapFeed, MapServer  # noqa: PLC0415 (aiohttp only when the map is wanted)

        feed = MapFeed(scenario, options.store_path, snapshot=daemon.snapshot, epoch=daemon.clock,
                       coverage=lambda: getattr(daemon, "coverage", None))
        server = await MapServer(feed, web).start()
        if on_web_url is not None:
            on_web_url(server.url)
    try:
        outcome = await _until_stopped(daemon, finish)  # Ctrl-C / SIGTERM: the fleet is told what to do first
        result = await asyncio.to_thread(finish, outcome)  # the map keeps answering meanwhile
        if feed is not None:
            feed.set_final(result.people, result.outcome.coverage)  # the map then shows what the files say
        if on_result is not None:
            on_result(result)
        if server is not None and web.keep:
            try:
                await asyncio.Event().wait()  # until Ctrl-C (asyncio.run cancels this task)
            except asyncio.CancelledError:
                pass
        return result
    finally:
        if server is not None:
            await server.stop()


def run_search(scenario: Scenario, connections: Sequence[tuple[int, str]], options: DaemonOptions,
               out_dir: Path, *, view: LiveView | None = None,
               truth: Callable[[Sequence[PersonResult], float], Mapping[int, tuple]] | None = None,
               on_daemon: Callable[[Daemon], None] | None = None, web=None,
               on_web_url: Callable[[str], None] | None = None,
               on_result: Callable[[RunResult], None] | None = None) -> RunResult:
    """Run the search to its end, then write the result files into ``out_dir``.

    ``web`` (a ``service.web.WebOptions``): also serve the live map while the search runs, in
    the same event loop; ``on_web_url(url)`` is called once it listens. ``on_result(result)`` is
    called once the files are written (before the map, with ``web.keep``, goes on serving the
    final state until Ctrl-C).

    ``truth(people, epoch_unix_s)`` (simulations only) returns {emitter id: (east, north)} true
    positions at each estimate's reference time, including people that were never heard.
    """
    labels = PersonLabels(options.store_path)
    if view is not None:
        view.labels = labels
        view.frame = scenario.frame
        view.report_follows = on_result is not None  # the statement is printed once, after the table
    daemon = Daemon(scenario, connections, options, view=view)
    if on_daemon is not None:
        on_daemon(daemon)

    def finish(outcome: SearchOutcome) -> RunResult:
        return _results(outcome, daemon, scenario, connections, options, out_dir, labels, truth)

    # the log goes on to a file whatever becomes of the console (a closed pipe: uavloc_gcs/console.py)
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    log_file = logging.FileHandler(Path(out_dir) / "uavloc.log", encoding="utf-8")
    log_file.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    log_file.setLevel(logging.INFO)
    root = logging.getLogger()
    level = root.level
    root.addHandler(log_file)
    if root.level > logging.INFO:  # the file gets the daemon's events; the console keeps its own level
        for handler in root.handlers:
            if handler is not log_file and handler.level == logging.NOTSET:
                handler.setLevel(level)
        root.setLevel(logging.INFO)
    try:
        return asyncio.run(_run(daemon, scenario, options, web, on_web_url, finish, on_result))
    finally:
        root.removeHandler(log_file)
        root.setLevel(level)
        log_file.close()


def _results(outcome: SearchOutcome, daemon: Daemon, scenario: Scenario, connections, options: DaemonOptions,
             out_dir: Path, labels: PersonLabels, truth) -> RunResult:
    """Label everyone, write the files and build the table and the statement."""
    people = list(outcome.people)
    truth_xy = None
    if truth is not None:
        truth_xy = dict(truth(people, daemon.epoch_unix_s or 0.0))
        heard = {p.emitter_id for p in people}
        for eid in sorted(set(truth_xy) - heard):
            people.append(PersonResult(eid, math.nan, math.nan, math.nan, math.nan, math.nan, math.nan, math.nan,
                                       math.nan, math.nan, False, False, "never heard"))
    labels.refresh()
    # anyone not labelled yet: the people heard first (in the field world they are linked from
    # addresses, not labelled from the store), the never heard last
    labels.add(p.emitter_id for p in sorted(people, key=lambda p: (p.reason == "never heard", p.emitter_id)))
    people = [dataclasses.replace(p, label=labels.get(p.emitter_id)) for p in people]
    heard = [p for p in people if p.reason != "never heard"]
    others = tuple(v for v, _ in connections if v not in (*outcome.vehicles_home, *outcome.vehicles_lost,
                                                          *outcome.vehicles_returning))
    summary, not_started = _coverage(daemon)
    in_air = tuple(getattr(outcome, "lost_in_air", ()))
    statement = statement_for(heard, scenario.people.required_accuracy_m, outcome.vehicles_lost, others,
                              outcome.vehicles_returning, coverage=summary, lost_in_air=in_air,
                              fleet=not outcome.partial)  # stopped: the stop report says it, once
    for vid, why in not_started:  # a refused start is no scan flown: say so, whatever else is said
        statement += f" Vehicle {vid} did not fly its scan ({why}); its part of the area was not searched."
    sorties = daemon._packs_text() if scenario.fleet.batteries > 1 and hasattr(daemon, "_packs_text") else ""
    if sorties:  # sorties flown and packs left per vehicle (issue 38)
        statement += " " + sorties
    searched, left = coverage_statement(summary, outcome.vehicles_lost, [vid for vid, _ in not_started],
                                        stopped=bool(getattr(outcome, "partial", "")))
    first = [x.sentence() for x in in_air]  # a vehicle lost in the air is what the operator must hear first
    outcome = dataclasses.replace(outcome, people=tuple(heard),
                                  statement=" ".join(filter(None, [*first, outcome.partial, statement, searched])),
                                  coverage=summary, unsearched_after_loss=left)
    if summary is not None:
        people = [dataclasses.replace(p, pod_here=summary.pod_at((p.east_m, p.north_m))) for p in people]
    epoch = daemon.clock() if hasattr(daemon, "clock") else daemon.epoch_unix_s  # UTC as it really was
    with StoreReader(options.store_path) as rd:
        tracks = rd.tracks()
    frame = scenario.frame
    files = write_results(out_dir, people, frame=frame, area_latlon_deg=np.array(scenario.polygon_latlon_deg),
                          tracks_latlon_deg=tracks, required_accuracy_m=scenario.people.required_accuracy_m,
                          truth_xy_m=truth_xy, name=scenario.name + (TITLE_MARK if outcome.partial else "") + title_mark(in_air),
                          epoch_unix_s=epoch, coverage=summary, terrain=scenario.dem,
                          fence_latlon_deg=scenario.geofence_latlon_deg or None, notes=(sorties,) if sorties else ())
    if outcome.partial:
        mark_partial(files, outcome.partial)
    mark_lost(files, in_air)  # (after: the lost vehicles come first)
    table = results_table(people, scenario.people.required_accuracy_m, truth_xy, epoch_unix_s=epoch,
                          coverage=summary, notes=(sorties,) if sorties else ())
    return RunResult(outcome, tuple(people), table, tuple(files))


def _coverage(daemon: Daemon):
    """The final coverage claims of ``daemon``'s search (search.coverage.final_summary) and the
    vehicles whose scans never started [(id, why)]; (None, [...]) without a coverage accumulator."""
    not_started = [(v.id, v.start_failed) for v in getattr(daemon, "vehicles", {}).values()
                   if getattr(v, "start_failed", "") and not getattr(v, "scan_done", False)]
    cov = getattr(daemon, "coverage", None)
    if cov is None:
        return None, not_started
    from ..search.coverage import final_summary  # noqa: PLC0415

    return final_summary(cov), not_started


STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


async def _until_stopped(daemon: Daemon, finish: Callable[[SearchOutcome], "RunResult"] | None = None) -> SearchOutcome:
    """Run the daemon; on SIGINT/SIGTERM let it send the fleet home (or on), write the results so far
    with ``finish`` (marked partial: service/partial.py), then raise
    :class:`~uavloc_gcs.errors.Interrupted` saying what each vehicle does and what was written."""
    from ..errors import Interrupted  # noqa: PLC0415

    loop = asyncio.get_running_loop()
    task = asyncio.current_task()
    got: list[int] = []

    def on_signal(signum, _frame=None) -> None:
        got.append(signum)
        loop.call_soon_threadsafe(task.cancel)

    with _signal_handlers(on_signal):
        try:
            return await daemon.run()
        except asyncio.CancelledError:
            if not got:
                raise
            task.uncancel()
            name = signal.Signals(got[0]).name
            partial = getattr(daemon, "partial_outcome", None)
            in_air = tuple(getattr(partial, "lost_in_air", ()) or ())
            first = [x.sentence() for x in in_air]  # a vehicle lost in the air is said first, once
            lines = [line for line in daemon.stop_report if not any(line.startswith(f"vehicle {x.vehicle}:")
                                                                     for x in in_air)]
            if not lines and not first:
                lines = ["no vehicle was commanded yet"]
            written = ""
            if finish is not None and partial is not None:
                try:
                    result = await asyncio.to_thread(finish, partial)
                    statement = result.outcome.statement
                    for sentence in first:
                        statement = statement.replace(sentence, "", 1).strip()
                    written = f" {statement} Written so far: " + ", ".join(p.name for p in result.files) + "."
                except Exception as exc:  # noqa: BLE001 - the stop is reported whatever happens here
                    written = f" The results so far could not be written ({exc})."
            said = f"stopped by {name}" + (": " + "; ".join(lines) if lines else "") + "."
            raise Interrupted(" ".join([*first, said]) + written, signal=got[0]) from None


@contextlib.contextmanager
def _signal_handlers(handler):
    """Install ``handler`` for SIGINT and SIGTERM (main thread only), restoring the previous ones."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.getsignal(s) for s in STOP_SIGNALS}

    def chained(signum, frame) -> None:
        handler(signum, frame)
        # a handler installed before that asks to hear the signal too (``uavloc_chain``: a test
        # suite that must stop on SIGTERM although a daemon inside one of its tests caught it)
        prev = previous.get(signum)
        if callable(prev) and getattr(prev, "uavloc_chain", False):
            prev(signum, frame)

    for s in STOP_SIGNALS:
        signal.signal(s, chained)
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
