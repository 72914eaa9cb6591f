"""Job execution in worker processes, never in the event loop.

:class:`JobRunner` (in the server process) keeps a FIFO of queued job ids and a dispatcher
thread that starts one worker process per job, at most ``workers`` at a time. Processes come
from a ``forkserver`` (the engine's modules preloaded once, then each job is a cheap fork of a
process without threads). A worker (:func:`execute_job`) marks its job running, calls the job
kind's function with a progress callback that writes to SQLite as it goes, and stores the result
or a one-line error. Cancelling a running job terminates its process; a worker that dies
(killed, out of memory) ends its job as failed with the exit code.

Faults (README "Fault behaviour"): the dispatcher never dies – each cycle runs under a guard
that records the fault and backs off, and a final state the store cannot take now (locked,
busy) is kept and written once the store answers again. A worker ends with its server: it
closes the forkserver's "alive" pipe it inherits (so the forkserver exits when the server
does), asks the kernel for SIGKILL when its parent dies (Linux ``PR_SET_PDEATHSIG``) and checks
the server's pid every :data:`api.processes.ORPHAN_CHECK_S` (the fallback elsewhere).
Figures are written to a hidden folder and moved in place only when the job succeeds: a
cancelled or failed job leaves no partial figures.

A job kind is a module-level function ``(document, progress, out_dir) -> JobOutput`` (see
:mod:`api.kinds`); it is handed to the worker by reference (pickled by qualified name).
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import logging
import math
import multiprocessing
import multiprocessing.connection
import multiprocessing.forkserver
import os
import re
import shutil
import signal
import sqlite3
import sys
import threading
import time
import traceback
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from datetime import datetime
from multiprocessing.process import BaseProcess
from pathlib import Path
from typing import Any

from pydantic import ValidationError
from threadpoolctl import threadpool_limits

from api.processes import (
    WORKER_MODULES,
    close_inherited_alive_pipe,
    exit_when_orphaned,
)
from api.store import (
    BUSY_TIMEOUT_S,
    RETRY_S,
    FileIdentity,
    JobStore,
    StoreUnavailableError,
    utc_now,
)
from ris_planner.core.errors import RisPlannerError
from ris_planner.core.io_json import one_line_validation_error
from ris_planner.runtime import allocator
from ris_planner.runtime.progress import LAST_BEFORE_END, ProgressCallback

log = logging.getLogger("api.worker")

PRELOAD_MODULES = [
    "api.worker",
    "api.kinds",
    "ris_planner.planning",
    # the package loads its names on first use: what a plan job runs, preloaded here
    "ris_planner.io.geoplan",
    "ris_planner.planning.pipeline",
    "ris_planner.planning.outputs.report",
    "ris_planner.power.report",
    *WORKER_MODULES,
    "api.preload",
]
"""Imported once by the forkserver so each job's process (and each parse process,
:mod:`api.offload`) starts without re-importing them; the last, :mod:`api.preload`, also sets
up matplotlib and numba's runtime there."""

JOB_STAGE = "job"
"""The ``timing_s`` entry a job adds to a plan's stages: its own bookkeeping in the worker –
recording its start in the store, before the plan, and moving its figures in place, after it
–, so that a plan job's ``timing_s`` sums to ``finished_at − started_at`` as a command-line
plan's sums to the command's wall time (docs/concepts/planning.md, "Pipeline")."""

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
    """A :data:`ProgressCallback` writing a job's progress to the store (throttled: at most
    every ``interval_s``, but always the end and the first call of a new stage – the part of
    the message before its first ``:``, :class:`ris_planner.runtime.progress.Stages` – so a long
    stage
    with one call is never hidden behind the previous one's); raises
    :class:`JobCancelledError` once the job is no longer running. The job function's own 1.0
    is written as :data:`~ris_planner.runtime.progress.LAST_BEFORE_END`: the job reaches 1.0 only
    when its result is stored."""

    def __init__(self, store: JobStore, job_id: str, interval_s: float = PROGRESS_INTERVAL_S):
        self.store = store
        self.job_id = job_id
        self.interval_s = interval_s
        self._last = 0.0
        self._stage: str | None = None

    def __call__(self, fraction: float, message: str = "") -> None:
        now = time.monotonic()
        stage = message.split(":", 1)[0]
        if fraction < 1.0 and now - self._last < self.interval_s and stage == self._stage:
            return
        self._last = now
        self._stage = stage
        if fraction >= 1.0:  # 1.0 comes with the result (JobStore.succeed), never before it
            fraction, message = LAST_BEFORE_END, "storing the result"
        if not self.store.set_progress(self.job_id, fraction, message):
            raise JobCancelledError(self.job_id)


_PATH = re.compile(r"(?<![\w.:/])(?:/[^\s/'\"():;,]+)+/?")
"""An absolute POSIX path inside a message."""


def redact_paths(text: str) -> str:
    """``text`` with every absolute path replaced by its last component (job messages are
    read by clients; the server's file layout is not theirs to see)."""
    return _PATH.sub(lambda m: m.group(0).rstrip("/").rsplit("/", 1)[-1] or "/", text)


def describe_error(exc: BaseException) -> str:
    """A one-line message for a failed job (the field paths for validation errors), without
    server file paths."""
    if isinstance(exc, ValidationError):  # the CLI's message, on one line
        text = one_line_validation_error(exc)
    elif isinstance(exc, RisPlannerError):
        text = str(exc)
    elif isinstance(exc, MemoryError):
        text = "out of memory: the job needs more memory than a worker may use"
    else:
        text = f"{type(exc).__name__}: {exc}"
    return redact_paths(" ".join(text.split()))[:2000]


EXIT_STORE_UNAVAILABLE = 75
"""A worker's exit status when the job database did not answer within its retry time."""
EXIT_STORE_GONE = 76
"""A worker's exit status when the job database file was removed or replaced."""

_PR_SET_PDEATHSIG = 1


def set_parent_death_signal(sig: int = signal.SIGKILL) -> bool:
    """Linux: deliver ``sig`` to this process when its parent dies (``prctl``); False where
    unavailable (other systems rely on :func:`api.processes.exit_when_orphaned`)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        return int(libc.prctl(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0)) == 0
    except (OSError, AttributeError):
        return False


def _own_process_group() -> None:
    """Make this worker the leader of a process group of its own: the plan's process pool
    (:class:`ris_planner.planning.LocalExecutor`) starts in it, so :func:`terminate_job` stops
    the job and every process it started at once."""
    with contextlib.suppress(OSError, AttributeError):
        os.setpgid(0, 0)


def terminate_job(proc: BaseProcess, sig: int = signal.SIGTERM) -> None:
    """``sig`` to a job's process group (the worker and its pool, :func:`_own_process_group`);
    to the worker alone while it has not made its group yet."""
    pid = proc.pid
    if pid is None:
        return
    try:
        if os.getpgid(pid) == pid:
            os.killpg(pid, sig)
            return
    except (ProcessLookupError, PermissionError, AttributeError):
        pass
    with contextlib.suppress(ProcessLookupError):
        os.kill(pid, sig)


def _remove(path: Path) -> None:
    shutil.rmtree(path, ignore_errors=True)


def staging_dir(figures_dir: Path, job_id: str) -> Path:
    """Where a running job writes its figures (moved to ``figures_dir/job_id`` on success)."""
    return figures_dir / f".{job_id}.partial"


JOB_NICENESS = 5
"""A job's process runs this much nicer than the server (``os.nice``; its threads and its plan's
worker pool inherit it): when jobs fill the cores, the server – its ``/healthz`` threads, the
event loop – and the parse processes, which answer requests, get the CPU first
(docs/guides/service-operations.md, "Liveness under load"). On an idle machine it changes
nothing."""


def lower_priority(niceness: int = JOB_NICENESS) -> None:
    """Make this process ``niceness`` nicer (no-op where the platform refuses)."""
    with contextlib.suppress(OSError, AttributeError):
        os.nice(niceness)


def cap_memory(budget_mb: int) -> None:
    """Cap this process's address space at its current size plus ``budget_mb`` (Linux
    ``RLIMIT_AS``): a job that outgrows its budget gets MemoryError (its job fails with "out of
    memory") instead of pushing the machine into swap or the OOM killer."""
    try:
        import resource

        pages = int(Path("/proc/self/statm").read_text().split()[0])
        current = pages * os.sysconf("SC_PAGE_SIZE")
        limit = current + (budget_mb << 20)
        hard = resource.getrlimit(resource.RLIMIT_AS)[1]
        if hard != resource.RLIM_INFINITY:
            limit = min(limit, hard)
        resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    except (OSError, ValueError, ImportError):  # not Linux: the size estimate alone guards
        pass


def execute_job(
    db_path: Path,
    figures_dir: Path,
    job_id: str,
    func: JobFunction,
    blas_threads: int = 1,
    identity: FileIdentity | None = None,
    server_pid: int | None = None,
    store_options: dict[str, float] | None = None,
    memory_mb: int | None = None,
) -> None:
    """Run one job to its end state (the body of a worker process)."""
    allocator.tune_malloc()  # a service process (ris_planner.runtime.allocator)
    _own_process_group()
    close_inherited_alive_pipe()
    set_parent_death_signal()
    lower_priority()
    if memory_mb is not None:
        cap_memory(memory_mb)
    server = os.getppid() if server_pid is None else server_pid
    threading.Thread(
        target=exit_when_orphaned, args=(server,), name="orphan-watch", daemon=True
    ).start()
    threadpool_limits(limits=blas_threads)
    try:
        _execute(db_path, figures_dir, job_id, func, identity, store_options or {})
    except (StoreUnavailableError, sqlite3.Error) as exc:  # read-only, full, corrupt: no retry
        from api.store import StoreGoneError

        log.error("job %s: the job database failed: %s", job_id, exc)
        _remove(staging_dir(figures_dir, job_id))
        sys.exit(EXIT_STORE_GONE if isinstance(exc, StoreGoneError) else EXIT_STORE_UNAVAILABLE)


def _execute(
    db_path: Path,
    figures_dir: Path,
    job_id: str,
    func: JobFunction,
    identity: FileIdentity | None,
    store_options: dict[str, float],
) -> None:
    store = JobStore(
        db_path,
        expect=identity,
        busy_timeout_s=store_options.get("busy_timeout_s", BUSY_TIMEOUT_S),
        retry_s=store_options.get("retry_s", RETRY_S),
    )
    job = store.get(job_id)
    t_start, started = time.perf_counter(), utc_now()
    if job is None or not store.start(job_id, started):
        return  # cancelled (or taken) before it started
    staging, final = staging_dir(figures_dir, job_id), figures_dir / job_id
    _remove(staging)
    progress = StoreProgress(store, job_id)
    try:
        t_func = time.perf_counter()
        output = func(job.request, progress, staging)
        t_done = time.perf_counter()
        figures = {name: str(path.relative_to(staging)) for name, path in output.figures.items()}
    except JobCancelledError:
        _remove(staging)
        return
    except (StoreUnavailableError, sqlite3.Error):
        raise
    except Exception as exc:  # every failure ends the job with a message, never a hang
        _remove(staging)
        if not isinstance(exc, RisPlannerError | ValidationError):
            log.error("job %s (%s) failed:\n%s", job_id, job.kind, traceback.format_exc())
        store.fail(job_id, describe_error(exc))
        return
    if figures:
        _remove(final)
        staging.rename(final)
    t_end, finished = time.perf_counter(), utc_now()
    timing = output.result.get("timing_s")
    if isinstance(timing, dict):  # a plan: the job's own bookkeeping is a stage of its time
        timing[JOB_STAGE] = (t_func - t_start) + (t_end - t_done)
    if not store.succeed(job_id, output.result, figures, finished):
        _remove(final)  # cancelled while it finished: no figures for a cancelled job
    _remove(staging)


def exit_message(code: int | None) -> str:
    """Why a worker process ended without recording its job's end (one line)."""
    if code == EXIT_STORE_UNAVAILABLE:
        return "the worker could not record the job's end: the job database did not answer"
    if code == EXIT_STORE_GONE:
        return "the job database was removed or replaced while this job ran; submit it again"
    if code is not None and code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = f"signal {-code}"
        hint = " (out of memory?)" if -code == signal.SIGKILL else ""
        return f"worker process was killed by {name}{hint}"
    return f"worker process exited with code {code}"


FAULT_HOLD_S = 300.0
"""``/healthz`` shows the last fault (``last_fault``) for this long after it."""


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
        memory_mb: int | None = None,
    ) -> None:
        self.store = store
        self.memory_mb = memory_mb
        self.figures_dir = figures_dir
        self.kinds = dict(kinds)
        self.workers = workers
        self.blas_threads = blas_threads
        self.poll_s = poll_s
        self._queue: deque[str] = deque()
        self._kind_of: dict[str, str] = {}
        self._procs: dict[str, BaseProcess] = {}
        self._unsettled: dict[str, str] = {}  # job id → final error not yet stored
        self._deleted: set[str] = set()  # removed while their process ran
        self._lock = threading.Condition()
        self._stopping = False
        self._thread: threading.Thread | None = None
        self._db_lost = threading.Event()
        self._fault: str | None = None  # the dispatcher's fault, until a cycle succeeds
        self._last_fault: str | None = None
        self._fault_at = -math.inf
        self._ctx = multiprocessing.get_context("forkserver")
        self._ctx.set_forkserver_preload(PRELOAD_MODULES)
        store.on_recreated = self._db_lost.set

    # -- public ------------------------------------------------------------------------------

    def start(self) -> None:
        """Repair the store after a restart, re-queue its queued jobs, start dispatching."""
        for job_id in self.store.recover():
            self._queue.append(job_id)
        self._stopping = False
        self._thread = threading.Thread(target=self._loop, name="job-dispatcher", daemon=True)
        self._thread.start()

    def submit(self, job_id: str, kind: str = "unknown") -> None:
        with self._lock:
            self._queue.append(job_id)
            self._kind_of[job_id] = kind
            self._lock.notify_all()

    def cancel(self, job_id: str) -> bool:
        """Cancel a queued or running job (terminating its process); False if it had ended."""
        applied = self.store.cancel(job_id)
        with self._lock:
            proc = self._procs.get(job_id)
            if applied and proc is not None and proc.is_alive():
                terminate_job(proc)
            self._lock.notify_all()
        return applied

    def delete(self, job_id: str) -> bool:
        """Remove a job: a queued or running one is cancelled first (its process terminated),
        then its row and its figure folder are removed; False if there was no such job."""
        with self._lock:
            self._deleted.add(job_id)  # its worker's exit must not record it again
        self.cancel(job_id)
        existed = self.store.delete(job_id)
        _remove(self.figures_dir / job_id)
        with self._lock:
            if job_id not in self._procs:
                self._deleted.discard(job_id)
        return existed

    def running(self) -> int:
        """Worker processes alive now. Lock-free (a snapshot of the process table): the
        dispatcher holds the lock while it starts a process, which can take seconds, and
        ``/healthz`` must not wait for it."""
        return sum(p.is_alive() for p in list(self._procs.values()))

    def worker_pids(self) -> list[int]:
        """Pids of the running worker processes (lock-free, as :meth:`running`)."""
        procs = list(self._procs.values())
        return [p.pid for p in procs if p.pid is not None and p.is_alive()]

    def health(self) -> str | None:
        """None when healthy, else why the service is degraded now: a dispatcher cycle that
        failed and has not succeeded since, or a store call failing now (the service is ``ok``
        again as soon as the store answers and the dispatcher completes a cycle)."""
        if self._fault is not None:
            return self._fault
        return self.store.faults.current

    def last_fault(self) -> str | None:
        """The last fault met within :data:`FAULT_HOLD_S` (recovered or not), for the record:
        the dispatcher's or the store's, whichever came later."""
        found = []
        if self._last_fault is not None:
            found.append((self._fault_at, self._last_fault))
        if self.store.faults.recent:
            last = self.store.faults.recent[-1]
            found.append((last.mono, last.reason))
        at, reason = max(found, default=(-math.inf, None))
        return reason if time.monotonic() - at < FAULT_HOLD_S else None

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
                    terminate_job(proc)
                proc.join(timeout_s)
                if proc.is_alive():  # not daemonic: the interpreter's exit would wait for it
                    terminate_job(proc, signal.SIGKILL)
                    proc.join(timeout_s)
                _remove(staging_dir(self.figures_dir, job_id))
                try:
                    self.store.requeue(job_id)
                except (StoreUnavailableError, sqlite3.Error) as exc:
                    log.error("could not re-queue job %s at shutdown: %s", job_id, exc)
            self._procs.clear()

    # -- dispatcher thread ---------------------------------------------------------------------

    def _note_fault(self, reason: str) -> None:
        log.error("job dispatcher: %s", reason)
        self._fault, self._fault_at = reason, time.monotonic()
        self._last_fault = reason

    def _launch(self, job_id: str) -> None:
        job = self.store.head(job_id)
        if job is None or job.status != "queued":
            return
        func = self.kinds.get(job.kind)
        if func is None:
            self.store.fail(job_id, f"unknown job kind {job.kind!r} (not served by this version)")
            return
        self._kind_of[job_id] = job.kind
        store_options = {"busy_timeout_s": self.store.busy_timeout_s, "retry_s": self.store.retry_s}
        proc = self._ctx.Process(
            target=execute_job,
            args=(
                self.store.path,
                self.figures_dir,
                job_id,
                func,
                self.blas_threads,
                self.store.identity,
                os.getpid(),
                store_options,
                self.memory_mb,
            ),
            name=f"job-{job_id}",
            # not daemonic: a plan job starts its own process pool (a daemonic process may not
            # have children); stop() terminates every worker, and a worker whose server died
            # exits on its own (set_parent_death_signal, exit_when_orphaned)
            daemon=False,
        )
        proc.start()
        self._procs[job_id] = proc
        log.info("job %s (%s) started in process %s", job_id, job.kind, proc.pid)

    def _settle(self, job_id: str, error: str) -> None:
        """Store a job's final error; kept for a later cycle when the store is unavailable."""
        self._unsettled[job_id] = error
        if not self.store.fail(job_id, error) and self.store.head(job_id) is None:
            self.store.record_lost(job_id, self._kind_of.get(job_id, "unknown"), "running")
        del self._unsettled[job_id]
        self._kind_of.pop(job_id, None)

    def _reap(self) -> None:
        for job_id, proc in list(self._procs.items()):
            if proc.is_alive():
                continue
            proc.join()
            del self._procs[job_id]
            _remove(staging_dir(self.figures_dir, job_id))
            kind = self._kind_of.get(job_id, "unknown")
            if job_id in self._deleted:  # removed (DELETE): nothing to record
                self._deleted.discard(job_id)
                self._kind_of.pop(job_id, None)
                log.info("job %s (%s) removed", job_id, kind)
                continue
            if proc.exitcode != 0:  # no-op when the job was cancelled (terminated) or ended
                self._settle(job_id, exit_message(proc.exitcode))
            else:
                self._kind_of.pop(job_id, None)
            self._log_end(job_id, kind, proc.exitcode)

    def _log_end(self, job_id: str, kind: str, exitcode: int | None) -> None:
        """One info line for a job whose process ended: its final state and time."""
        try:
            head = self.store.head(job_id)
        except (StoreUnavailableError, sqlite3.Error):
            head = None
        if head is None:
            log.info("job %s (%s) ended (worker exit code %s)", job_id, kind, exitcode)
            return
        took = ""
        if head.started_at and head.finished_at:
            seconds = datetime.fromisoformat(head.finished_at) - datetime.fromisoformat(
                head.started_at
            )
            took = f" in {seconds.total_seconds():.1f} s"
        error = f": {head.error}" if head.error else ""
        log.info("job %s (%s) %s%s%s", job_id, kind, head.status, took, error)

    def _handle_lost_database(self) -> None:
        """The store recreated a removed database: stop the workers writing to the old one
        and record every job this server knew (running, queued) as failed in the new one."""
        self._db_lost.clear()
        self._note_fault(
            f"the job database {self.store.path.name} was removed while the server ran; a new"
            " empty database was created and the jobs it held are lost"
        )
        for job_id, proc in list(self._procs.items()):
            if proc.is_alive():
                terminate_job(proc)
            proc.join(10.0)
            del self._procs[job_id]
            _remove(staging_dir(self.figures_dir, job_id))
            self.store.record_lost(job_id, self._kind_of.pop(job_id, "unknown"), "running")
        for job_id in list(self._queue):
            if self.store.head(job_id) is None:
                self._queue.remove(job_id)
                self.store.record_lost(job_id, self._kind_of.pop(job_id, "unknown"), "queued")

    def _cycle(self) -> list[Any]:
        """One dispatcher step under the lock; the sentinels to wait on (empty: idle)."""
        for job_id, error in list(self._unsettled.items()):
            self._settle(job_id, error)
        self.store._check_identity()  # a removed database is noticed even when idle
        if self._db_lost.is_set():
            self._handle_lost_database()
        self._reap()
        while self._queue and len(self._procs) < self.workers:
            job_id = self._queue[0]
            try:
                self._launch(job_id)
            except (StoreUnavailableError, sqlite3.Error):
                raise  # the job stays queued; retried next cycle
            except Exception as exc:  # a broken job must not stop the dispatcher
                log.exception("could not start job %s", job_id)
                self._queue.popleft()
                self._settle(job_id, f"could not start a worker process: {describe_error(exc)}")
                continue
            self._queue.popleft()
        return [p.sentinel for p in self._procs.values()]

    def _loop(self) -> None:
        pause = self.poll_s
        while True:
            with self._lock:
                if self._stopping:
                    return
                try:
                    sentinels = self._cycle()
                    pause = self.poll_s
                    self._fault = None  # recovered (last_fault keeps it for the record)
                except Exception as exc:  # the dispatcher never dies: note, back off, go on
                    self._note_fault(f"job dispatcher: {describe_error(exc)}")
                    pause = min(2 * pause, 2.0)
                    self._lock.wait(pause)
                    continue
                if not sentinels:
                    self._lock.wait(self.poll_s * 4)
                    continue
            multiprocessing.connection.wait(sentinels, timeout=self.poll_s)
