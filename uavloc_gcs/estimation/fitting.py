"""Where the search's estimates are computed: in the caller's thread, or in a worker process.

An estimate in the field world costs from a tenth of a second to tens of seconds of pure-Python
CPU (multi-start fits, turn models, the sampled radius). Run in the daemon's own process, that work
holds the interpreter lock: the event loop stops reading the vehicles' links, every vehicle looks
silent and is marked lost, and a search stalls for minutes of mission time (issue 42: a field demo
whose vehicles waited 1,500 s on the ground for one round of fits). So the daemon fits in a worker
process (:class:`ProcessFitter`) while its loop keeps reading; experiments and tests fit in the
caller (:class:`InlineFitter`), which keeps them deterministic and as fast as before.

Both take :class:`FitJob` s and hand back :class:`FitResult` s; a job is a pure function of its
fields (:func:`run_fit`), so where it runs changes nothing but when its result arrives.
"""

from __future__ import annotations

import concurrent.futures as cf
import logging
import multiprocessing
import time
from dataclasses import dataclass
from typing import Any

from ..errors import EstimationError
from ..observations import SlotBatch

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class FitJob:
    """One person's estimate to compute: ``estimate_emitter``'s inputs. ``version`` is what the
    caller uses to tell a result for older data from one for its latest (e.g. the slot count)."""

    emitter_id: int
    version: int
    slots: SlotBatch
    max_speed_m_s: float
    t_ref_s: float
    model_motion: bool
    previous: Any = None
    silence: Any = None
    censored: Any = None
    # When the estimate's 95 % radius is within this [m] (a fix to be), the heard slots are fitted
    # again without the evidence of where the phone was not heard, and must agree (FitResult.contradicted)
    check_within_m: float | None = None
    # The field world's grid posterior (estimation.burst_grid) instead of estimate_emitter: its spec
    # and the person's bursts (heard, and the vehicles that listened to one and heard nothing)
    grid: Any = None
    bursts: tuple = ()


@dataclass(frozen=True)
class FitResult:
    """The outcome of a :class:`FitJob`: ``estimate``, or ``error`` (bad data: an EstimationError's
    sentence) or ``crash`` (a defect in the estimator, with its type), and the CPU time it took.
    ``contradicted``: why the heard slots alone disagree with a sharp estimate ("" when they agree
    or were not asked)."""

    emitter_id: int
    version: int
    estimate: Any = None
    error: str = ""
    crash: str = ""
    runtime_s: float = 0.0
    contradicted: str = ""


def run_fit(job: FitJob, channel, dem) -> FitResult:
    """Compute ``job`` (``dem``: the scenario's terrain, or None for flat ground)."""
    from .terrain_fit import fit_for

    t0 = time.perf_counter()
    if job.grid is not None:
        return _run_grid(job, t0)
    try:
        fit = fit_for(dem)
        est = fit(job.slots, channel, max_speed_m_s=job.max_speed_m_s, t_ref_s=job.t_ref_s,
                  model_motion=job.model_motion, previous=job.previous, silence=job.silence, censored=job.censored)
        contradicted = ""
        if job.check_within_m is not None and (job.silence is not None or job.censored is not None) \
                and getattr(est, "ok", False) and est.radius95_m <= job.check_within_m:
            contradicted = _contradiction(est, fit(job.slots, channel, max_speed_m_s=job.max_speed_m_s,
                                                   t_ref_s=job.t_ref_s, model_motion=job.model_motion))
        return FitResult(job.emitter_id, job.version, estimate=est, runtime_s=time.perf_counter() - t0,
                         contradicted=contradicted)
    except EstimationError as exc:
        return FitResult(job.emitter_id, job.version, error=str(exc), runtime_s=time.perf_counter() - t0)
    except Exception as exc:  # noqa: BLE001 -- one person's estimate never ends the search
        log.exception("emitter %d: the estimator failed", job.emitter_id)
        return FitResult(job.emitter_id, job.version, crash=f"{type(exc).__name__}: {exc}",
                         runtime_s=time.perf_counter() - t0)


def _run_grid(job: FitJob, t0: float) -> FitResult:
    """``job`` on the grid (estimation.burst_grid); the same contradiction check, the silent
    listeners left out for it."""
    from .burst_grid import grid_estimate

    try:
        est = grid_estimate(job.emitter_id, job.bursts, job.grid, job.t_ref_s)
        contradicted = ""
        heard = tuple(b for b in job.bursts if not b.silent)
        if job.check_within_m is not None and len(heard) < len(job.bursts) and est.radius95_m <= job.check_within_m:
            contradicted = _contradiction(est, grid_estimate(job.emitter_id, heard, job.grid, job.t_ref_s))
        return FitResult(job.emitter_id, job.version, estimate=est, runtime_s=time.perf_counter() - t0,
                         contradicted=contradicted)
    except EstimationError as exc:
        return FitResult(job.emitter_id, job.version, error=str(exc), runtime_s=time.perf_counter() - t0)
    except Exception as exc:  # noqa: BLE001 -- one person's estimate never ends the search
        log.exception("emitter %d: the grid estimate failed", job.emitter_id)
        return FitResult(job.emitter_id, job.version, crash=f"{type(exc).__name__}: {exc}",
                         runtime_s=time.perf_counter() - t0)


def _contradiction(est, plain) -> str:
    """Why ``plain`` (the heard slots alone) contradicts the sharp estimate ``est``: the two 95 %
    circles do not meet ("" when they do, or when ``plain`` says nothing usable).

    Where the phone was not heard is strong evidence, and wrong when the motion model is: a paper
    demo's walker who turned during a look was fitted, with the silences of the passes around,
    into a mode 142 m from the truth with a 7.3 m radius and declared located, while the heard slots
    alone put them 11 m from the truth (issue 42). A fix must not rest on the silences alone."""
    import math

    import numpy as np

    r = float(getattr(plain, "radius95_m", math.inf))
    if not getattr(plain, "ok", False) or not math.isfinite(r):
        return ""
    apart = float(np.linalg.norm(np.asarray(est.position_xy_m) - np.asarray(plain.position_xy_m)))
    if apart <= r + float(est.radius95_m):
        return ""
    return (f"the slots where it was heard put it {apart:.0f} m from the estimate (95 % radius {r:.0f} m); "
            "only where it was not heard points there")


class InlineFitter:
    """Fits in the caller, at once: :meth:`submit` computes, :meth:`results` hands back.
    ``fit``: what computes a job (default :func:`run_fit`)."""

    def __init__(self, channel, dem=None, *, fit=run_fit) -> None:
        self.channel, self.dem, self.fit = channel, dem, fit
        self._done: list[FitResult] = []

    def can_take(self) -> bool:
        return True

    def in_flight(self) -> int:
        return 0

    def submit(self, job: FitJob) -> None:
        self._done.append(self.fit(job, self.channel, self.dem))

    def results(self) -> list[FitResult]:
        out, self._done = self._done, []
        return out

    def close(self) -> None:
        self._done = []


# the worker process's channel and terrain (set once by _init_worker)
_WORKER: dict[str, Any] = {}


def _init_worker(channel, dem, fit) -> None:
    _WORKER["channel"], _WORKER["dem"], _WORKER["fit"] = channel, dem, fit


def _work(job: FitJob) -> FitResult:
    return _WORKER["fit"](job, _WORKER["channel"], _WORKER["dem"])


class ProcessFitter:
    """Fits in a worker process, one batch of jobs at a time.

    :meth:`submit` jobs while :meth:`can_take` (the caller submits its batch, most urgent first);
    :meth:`results` hands the batch back once every job of it is done, all together, as
    :class:`InlineFitter` does within one call: decisions then follow one consistent set of
    estimates instead of replanning on each person's result in turn (measured on the paper demo: 46
    replans instead of 8, when results were taken one at a time). One batch at a time, so that who
    is fitted next is decided when the worker is free, with the newest knowledge of who matters.
    :meth:`close` cancels what is under way and ends the worker at once (a stopped search must not
    wait for a fit). A worker that dies is started again; the jobs it held come back as crashes, so
    those people are fitted again with their next data.
    """

    MAX_RESTARTS = 3

    def __init__(self, channel, dem=None, *, workers: int = 1, fit=run_fit, max_batch: int = 8) -> None:
        # ``fit``: what computes a job in the worker (default :func:`run_fit`); a module-level
        # function, so that the worker can import it. ``max_batch``: jobs per batch at most (a
        # batch is handed back whole: its length bounds how long an urgent result can wait)
        self.channel, self.dem, self.workers, self.fit = channel, dem, int(workers), fit
        self.max_batch = int(max_batch)
        self._pool: cf.ProcessPoolExecutor | None = None
        self._futures: list[tuple[FitJob, cf.Future]] = []
        self._open = True  # the batch accepts jobs (until results() starts waiting for it)
        self._restarts = 0

    def _start(self) -> cf.ProcessPoolExecutor:
        if self._pool is None:
            ctx = multiprocessing.get_context("spawn")  # the daemon has threads: never fork it
            self._pool = cf.ProcessPoolExecutor(self.workers, mp_context=ctx, initializer=_init_worker,
                                                initargs=(self.channel, self.dem, self.fit))
        return self._pool

    def can_take(self) -> bool:
        return self._open and len(self._futures) < self.max_batch

    def in_flight(self) -> int:
        return len(self._futures)

    def submit(self, job: FitJob) -> None:
        self._futures.append((job, self._start().submit(_work, job)))

    def results(self) -> list[FitResult]:
        """The batch, once all of it is done (else nothing yet; no more jobs join it meanwhile)."""
        if not self._futures:
            return []
        self._open = False
        if not all(fut.done() for _, fut in self._futures):
            return []
        out, broken = [], False
        for job, fut in self._futures:
            try:
                out.append(fut.result())
            except cf.process.BrokenProcessPool as exc:
                broken = True
                out.append(FitResult(job.emitter_id, job.version, crash=f"the fitting process died ({exc})"))
            except Exception as exc:  # noqa: BLE001 -- e.g. a job that could not be pickled
                out.append(FitResult(job.emitter_id, job.version, crash=f"{type(exc).__name__}: {exc}"))
        self._futures, self._open = [], True
        if broken:
            self._restart()
        return out

    def _restart(self) -> None:
        self._shutdown()
        self._restarts += 1
        if self._restarts > self.MAX_RESTARTS:
            raise EstimationError(f"the fitting process died {self._restarts} times; giving up on it")
        log.warning("the fitting process died; starting it again (%d of %d)", self._restarts, self.MAX_RESTARTS)

    def _shutdown(self) -> None:
        pool, self._pool = self._pool, None
        if pool is None:
            return
        procs = list(getattr(pool, "_processes", {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for p in procs:  # a fit under way is not waited for
            if p.is_alive():
                p.terminate()
        for p in procs:
            p.join(timeout=5.0)
        for p in procs:  # one that did not take SIGTERM in time (a busy machine): SIGKILL
            if p.is_alive():
                p.kill()
                p.join(timeout=5.0)

    def close(self) -> None:
        self._futures, self._open = [], True
        self._shutdown()
