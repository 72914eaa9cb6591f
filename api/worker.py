"""Job execution in worker processes, never in the event loop.

:class:`JobRunner` (in the server process) keeps a FIFO of queued job ids and a dispatcher
thread that starts one worker process per job, at most ``workers`` at a time. Processes come
from a ``forkserver`` (the engine's modules preloaded once, then each job is a cheap fork of a
process without threads). A worker (:func:`execute_job`) marks its job running, calls the job
kind's function with a progress callback that writes to SQLite as it goes, and stores the result
or a one-line error. Cancelling a running job terminates its process; a worker that dies
(killed, out of memory) ends its job as failed with the exit code.

A job kind is a module-level function ``(document, progress, out_dir) -> JobOutput`` (see
:mod:`api.kinds`); it is handed to the worker by reference (pickled by qualified name).
"""

from __future__ import annotations

import logging
import multiprocessing
import multiprocessing.connection
import os
import threading
import time
import traceback
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from multiprocessing.process import BaseProcess
from pathlib import Path
from typing import Any

from pydantic import ValidationError
from threadpoolctl import threadpool_limits

from api.store import JobStore
from ris_planner.cli import validation_problems
from ris_planner.errors import RisPlannerError
from ris_planner.progress import ProgressCallback

log = logging.getLogger("api.worker")

PRELOAD_MODULES = ["api.worker", "api.kinds", "ris_planner.planning", "ris_planner.power.report"]
"""Imported once by the forkserver so each job's process starts without re-importing them."""

PROGRESS_INTERVAL_S = 0.2
"""A worker writes progress to SQLite at most this often (and always on completion)."""


@dataclass(frozen=True)
class JobOutput:
    """What a job kind returns: the result document (JSON-ready) and its figure files."""

    result: dict[str, Any]
    figures: dict[str, Path] = field(default_factory=dict)


JobFunction = Callable[[dict[str, Any], ProgressCallback, Path], JobOutput]


class JobCancelledError(Exception):
    """Raised from the progress callback when the job is no longer running (cancelled)."""


class StoreProgress:
    """A :data:`ProgressCallback` writing a job's progress to the store (throttled); raises
    :class:`JobCancelledError` once the job is no longer running."""

    def __init__(self, store: JobStore, job_id: str, interval_s: float = PROGRESS_INTERVAL_S):
        self.store = store
        self.job_id = job_id
        self.interval_s = interval_s
        self._last = 0.0

    def __call__(self, fraction: float, message: str = "") -> None:
        now = time.monotonic()
        if fraction < 1.0 and now - self._last < self.interval_s:
            return
        self._last = now
        if not self.store.set_progress(self.job_id, fraction, message):
            raise JobCancelledError(self.job_id)


def describe_error(exc: BaseException) -> str:
    """A one-line message for a failed job (the field paths for validation errors)."""
    if isinstance(exc, ValidationError):  # the CLI's message, on one line
        return "invalid document: " + "; ".join(validation_problems(exc))
    if isinstance(exc, RisPlannerError):
        return str(exc)
    return f"{type(exc).__name__}: {exc}"


ORPHAN_CHECK_S = 1.0
"""A worker checks this often whether its parent (the forkserver) is gone, and exits if so."""


def _exit_when_orphaned() -> None:
    """Daemon thread: a worker whose server was killed (so the forkserver exited too) stops
    instead of computing on; the restarted server has marked its job failed."""
    parent = os.getppid()
    while True:
        time.sleep(ORPHAN_CHECK_S)
        if os.getppid() != parent:
            os._exit(1)


def execute_job(
    db_path: Path, figures_dir: Path, job_id: str, func: JobFunction, blas_threads: int = 1
) -> None:
    """Run one job to its end state (the body of a worker process)."""
    threading.Thread(target=_exit_when_orphaned, name="orphan-watch", daemon=True).start()
    threadpool_limits(limits=blas_threads)
    store = JobStore(db_path)
    job = store.get(job_id)
    if job is None or not store.start(job_id):
        return  # cancelled (or taken) before it started
    out_dir = figures_dir / job_id
    progress = StoreProgress(store, job_id)
    try:
        output = func(job.request, progress, out_dir)
        figures = {name: str(path.relative_to(out_dir)) for name, path in output.figures.items()}
    except JobCancelledError:
        return
    except Exception as exc:  # every failure ends the job with a message, never a hang
        if not isinstance(exc, RisPlannerError | ValidationError):
            log.error("job %s (%s) failed:\n%s", job_id, job.kind, traceback.format_exc())
        store.fail(job_id, describe_error(exc))
        return
    store.succeed(job_id, output.result, figures)


class JobRunner:
    """Queue and worker processes of one server process (see the module docstring)."""

    def __init__(
        self,
        store: JobStore,
        figures_dir: Path,
        kinds: Mapping[str, JobFunction],
        workers: int,
        blas_threads: int = 1,
        poll_s: float = 0.05,
    ) -> None:
        self.store = store
        self.figures_dir = figures_dir
        self.kinds = dict(kinds)
        self.workers = workers
        self.blas_threads = blas_threads
        self.poll_s = poll_s
        self._queue: deque[str] = deque()
        self._procs: dict[str, BaseProcess] = {}
        self._lock = threading.Condition()
        self._stopping = False
        self._thread: threading.Thread | None = None
        self._ctx = multiprocessing.get_context("forkserver")
        self._ctx.set_forkserver_preload(PRELOAD_MODULES)

    # -- public ------------------------------------------------------------------------------

    def start(self) -> None:
        """Repair the store after a restart, re-queue its queued jobs, start dispatching."""
        for job_id in self.store.recover():
            self._queue.append(job_id)
        self._stopping = False
        self._thread = threading.Thread(target=self._loop, name="job-dispatcher", daemon=True)
        self._thread.start()

    def submit(self, job_id: str) -> None:
        with self._lock:
            self._queue.append(job_id)
            self._lock.notify_all()

    def cancel(self, job_id: str) -> bool:
        """Cancel a queued or running job (terminating its process); False if it had ended."""
        applied = self.store.cancel(job_id)
        with self._lock:
            proc = self._procs.get(job_id)
            if applied and proc is not None and proc.is_alive():
                proc.terminate()
            self._lock.notify_all()
        return applied

    def running(self) -> int:
        with self._lock:
            return sum(p.is_alive() for p in self._procs.values())

    def stop(self, timeout_s: float = 10.0) -> None:
        """Stop dispatching; terminate running workers and put their jobs back in the queue."""
        with self._lock:
            self._stopping = True
            self._lock.notify_all()
        if self._thread is not None:
            self._thread.join(timeout_s)
        with self._lock:
            for job_id, proc in self._procs.items():
                if proc.is_alive():
                    proc.terminate()
                proc.join(timeout_s)
                self.store.requeue(job_id)
            self._procs.clear()

    # -- dispatcher thread ---------------------------------------------------------------------

    def _launch(self, job_id: str) -> None:
        job = self.store.head(job_id)
        if job is None or job.status != "queued":
            return
        func = self.kinds.get(job.kind)
        if func is None:
            self.store.fail(job_id, f"unknown job kind {job.kind!r} (not served by this version)")
            return
        proc = self._ctx.Process(
            target=execute_job,
            args=(self.store.path, self.figures_dir, job_id, func, self.blas_threads),
            name=f"job-{job_id}",
            daemon=True,
        )
        proc.start()
        self._procs[job_id] = proc

    def _reap(self) -> None:
        for job_id, proc in list(self._procs.items()):
            if proc.is_alive():
                continue
            proc.join()
            del self._procs[job_id]
            if proc.exitcode != 0:  # no-op when the job was cancelled (terminated) or ended
                self.store.fail(job_id, f"worker process exited with code {proc.exitcode}")

    def _loop(self) -> None:
        while True:
            with self._lock:
                if self._stopping:
                    return
                self._reap()
                while self._queue and len(self._procs) < self.workers:
                    job_id = self._queue.popleft()
                    try:
                        self._launch(job_id)
                    except Exception as exc:  # a broken job must not stop the dispatcher
                        log.exception("could not start job %s", job_id)
                        self.store.fail(job_id, f"could not start a worker process: {exc}")
                sentinels = [p.sentinel for p in self._procs.values()]
                if not sentinels:
                    self._lock.wait(self.poll_s * 4)
                    continue
            multiprocessing.connection.wait(sentinels, timeout=self.poll_s)
