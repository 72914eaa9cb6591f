"""Request bodies parsed and validated in worker processes, never in the server process.

A request document is parsed (``json.loads``), converted from its frame and validated by
pydantic in C calls that hold the interpreter lock for their whole length – 0.7 s for an 8 MB
body – and while one runs no other thread of the process runs: not the event loop, not
``/healthz`` (docs/guides/service-operations.md, "Liveness under load"). Threads do not help,
and parsing elsewhere only to unpickle the parsed document here costs as much as parsing it.
So the whole of a route's document work runs in a pool process (:class:`ParsePool`) and only
bytes come back: the answer's JSON body, rendered there (a 4xx by the same functions as the
exception handlers, :func:`api.errors.exception_answer`), or – for a submission – the document
as the JSON text the job store keeps. The server process only moves bytes.

The pool has ``RIS_PLANNER_PARSE_CONCURRENCY`` processes (the bound on document work at
once; the others wait in its queue), forked from the job runner's forkserver (the engine
already imported), started with the server and stopped with it: each exits when the server is
gone (it closes the forkserver's "alive" pipe and watches the server's pid), and the server's
shutdown terminates them. A process that dies (killed, out of memory) fails only the request it
was serving (:class:`ParseProcessDiedError`, 500) and is replaced; one found dead while idle is
replaced before it takes a request, failing no one.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import multiprocessing
import os
import threading
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import Any

import anyio
from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse, Response

from api.errors import error_response
from api.processes import WORKER_MODULES, close_inherited_alive_pipe, exit_when_orphaned
from ris_planner.runtime import allocator

log = logging.getLogger("api")


@dataclass(frozen=True)
class Answer:
    """A rendered HTTP answer (status, JSON body bytes, extra headers)."""

    status: int
    body: bytes
    headers: dict[str, str]

    def response(self) -> Response:
        return Response(
            self.body, status_code=self.status, headers=self.headers, media_type="application/json"
        )

    @classmethod
    def of(cls, response: JSONResponse) -> Answer:
        skip = {"content-length", "content-type"}
        headers = {k: v for k, v in response.headers.items() if k not in skip}
        return cls(response.status_code, bytes(response.body), headers)


class AnsweredError(Exception):
    """A document's error, already rendered by a pool process (:func:`install_answered_handler`
    answers it)."""

    def __init__(self, answer: Answer) -> None:
        super().__init__(answer.status)
        self.answer = answer


async def _on_answered(request: Request, exc: Exception) -> Response:
    """An error a parse process rendered already: its answer as it is."""
    assert isinstance(exc, AnsweredError)
    return exc.answer.response()


async def _on_process_died(request: Request, exc: Exception) -> Response:
    """The parse process serving the request died: this request fails, with a message."""
    log.warning("%s %s: %s", request.method, request.url.path, exc)
    return error_response(500, "internal_error", str(exc))


def install_answered_handler(app: FastAPI) -> None:
    """Register the handlers of :class:`AnsweredError` and :class:`ParseProcessDiedError` on
    ``app``."""
    app.add_exception_handler(AnsweredError, _on_answered)
    app.add_exception_handler(ParseProcessDiedError, _on_process_died)


@dataclass(frozen=True)
class _Refused:
    """What a pool process returns for a document's error (the answer; no exception object
    crosses the process boundary)."""

    answer: Answer


def _init_parse_worker(server_pid: int, modules: tuple[str, ...]) -> None:
    """Pool initializer: tuned like a job worker, gone with the server, imports done now."""
    import importlib

    allocator.tune_malloc()
    close_inherited_alive_pipe()
    threading.Thread(
        target=exit_when_orphaned, args=(server_pid,), name="orphan-watch", daemon=True
    ).start()
    for name in modules:
        importlib.import_module(name)


def _ready() -> int:
    return os.getpid()


def _call(fn: Callable[..., Any], args: tuple[Any, ...]) -> Any:
    """Run ``fn(*args)`` in a pool process; a document's error comes back as its answer."""
    from api.errors import exception_answer

    try:
        return fn(*args)
    except Exception as exc:
        answer = exception_answer(exc)
        if answer is None:
            raise
        return _Refused(Answer.of(answer))


class ParseProcessDiedError(RuntimeError):
    """The parse process serving a request died (killed, out of memory) before it answered:
    that request fails (500), the process is replaced."""


class ParsePool:
    """The bounded process pool of the document routes (see the module docstring).

    Each process is an executor of its own (a ``ProcessPoolExecutor`` of one worker) that
    serves one request at a time: when a process dies, the executor breaks with it and fails
    only the request it was serving – an executor of several processes fails every request it
    holds – and only that executor is replaced. A process found dead before it takes a request
    (killed while idle) is replaced without failing anyone."""

    def __init__(self, workers: int) -> None:
        self.workers = workers
        self.limiter = anyio.CapacityLimiter(workers)
        self._closed = False
        self._starter: threading.Thread | None = None
        self._swaps: list[threading.Thread] = []  # replacements under way (joined by close)
        self._idle = [self._new_executor() for _ in range(workers)]
        self._live = set(self._idle)

    @staticmethod
    def _new_executor() -> ProcessPoolExecutor:
        return ProcessPoolExecutor(
            max_workers=1,
            mp_context=multiprocessing.get_context("forkserver"),
            initializer=_init_parse_worker,
            initargs=(os.getpid(), WORKER_MODULES),
        )

    def start(self) -> None:
        """Start every process now, in the background (the server answers meanwhile; the
        first document then seldom waits for a process to start: starting the forkserver,
        which imports the engine, takes seconds)."""
        executors = list(self._idle)

        def spawn() -> None:
            with contextlib.suppress(RuntimeError, BrokenProcessPool):  # closed meanwhile
                for executor in executors:
                    if self._closed:
                        return
                    executor.submit(_ready)

        self._starter = threading.Thread(target=spawn, name="parse-pool-start", daemon=True)
        self._starter.start()

    def pids(self) -> list[int]:
        procs = [p for e in list(self._live) for p in list((e._processes or {}).values())]
        return sorted(p.pid for p in procs if p.pid is not None)

    @staticmethod
    def _dead(executor: ProcessPoolExecutor) -> bool:
        """Whether the executor broke, or its process died, while it was idle."""
        if getattr(executor, "_broken", False):
            return True
        procs = list((executor._processes or {}).values())
        return any(p.exitcode is not None for p in procs)

    def _replace(self, executor: ProcessPoolExecutor) -> ProcessPoolExecutor:
        """A new executor in the place of ``executor``. On a thread of its own (joining a
        manager thread, starting a process must not hold the event loop) the old one is shut
        down and the new one's process started: the pool is whole again at once."""
        self._live.discard(executor)
        fresh = self._new_executor()
        self._live.add(fresh)

        def swap() -> None:
            self._terminate(executor)
            with contextlib.suppress(RuntimeError, BrokenProcessPool):  # closed meanwhile
                if not self._closed:
                    fresh.submit(_ready)

        thread = threading.Thread(target=swap, name="parse-pool-replace", daemon=True)
        self._swaps = [t for t in self._swaps if t.is_alive()] + [thread]
        thread.start()
        return fresh

    async def run(self, fn: Callable[..., Any], *args: Any) -> Any:
        """``fn(*args)`` in a pool process (at most ``workers`` at once); a document's error
        raises :class:`AnsweredError` with the answer the exception handlers would give,
        the death of the process that served it :class:`ParseProcessDiedError`."""
        async with self.limiter:
            # processes killed while idle are not this request's doing: replaced, every one
            self._idle = [self._replace(e) if self._dead(e) else e for e in self._idle]
            executor = self._idle.pop()  # one idle executor per token of the limiter
            try:
                try:
                    # submitting may start a process (and wait for the forkserver to boot): in
                    # a thread, never on the event loop
                    future = await anyio.to_thread.run_sync(executor.submit, _call, fn, args)
                except BrokenProcessPool:  # it died between the check and the submission
                    executor = self._replace(executor)
                    future = await anyio.to_thread.run_sync(executor.submit, _call, fn, args)
                try:
                    out = await asyncio.wrap_future(future)
                except BrokenProcessPool:
                    executor = self._replace(executor)
                    raise ParseProcessDiedError(
                        "the parse process reading this request's document died (killed, or out"
                        " of memory); nothing was done – a smaller document, or try again"
                    ) from None
            finally:
                self._idle.append(executor)
        if isinstance(out, _Refused):
            raise AnsweredError(out.answer)
        return out

    def close(self, timeout_s: float = 10.0) -> None:
        """Stop every process now (a parse in progress is abandoned). The start-up thread is
        waited for first: a process it started after the others were terminated would wait
        forever for the task queue's lock that a terminated one held."""
        self._closed = True
        if self._starter is not None:
            self._starter.join(timeout_s)
        for thread in list(self._swaps):  # each terminates the executor it replaced
            thread.join(timeout_s)
        for executor in list(self._live):
            self._terminate(executor, timeout_s)
        self._live.clear()

    @staticmethod
    def _terminate(pool: ProcessPoolExecutor, timeout_s: float = 10.0) -> None:
        procs = list((pool._processes or {}).values())
        # taken before the shutdown, which forgets them (sets both to None)
        manager = getattr(pool, "_executor_manager_thread", None)
        wakeup = getattr(pool, "_executor_manager_thread_wakeup", None)
        pool.shutdown(wait=False, cancel_futures=True)
        for p in procs:
            with contextlib.suppress(OSError, ValueError):
                p.terminate()
        for p in procs:
            with contextlib.suppress(OSError, ValueError):
                p.join(timeout_s)
                if p.is_alive():
                    p.kill()
                    p.join(timeout_s)
        # the pool's manager thread closes its wake-up pipe on its way out; the interpreter's
        # exit hook writes to that pipe, and on Python 3.11 the two race (EBADF, a traceback
        # in the server's log at shutdown): let the thread finish first
        if manager is not None:
            manager.join(timeout_s)
        # and close that pipe here, once the thread is done with it: the exit hook skips a
        # closed one (its descriptor may be gone already: the hook's write then failed, EBADF)
        if wakeup is not None and (manager is None or not manager.is_alive()):
            with contextlib.suppress(OSError):
                wakeup.close()
