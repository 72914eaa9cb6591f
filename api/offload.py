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
shutdown terminates them.
"""

from __future__ import annotations

import asyncio
import contextlib
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

from api.processes import WORKER_MODULES, close_inherited_alive_pipe, exit_when_orphaned
from ris_planner.runtime import allocator


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


def install_answered_handler(app: FastAPI) -> None:
    """Register the handler of :class:`AnsweredError` on ``app``."""
    app.add_exception_handler(AnsweredError, _on_answered)


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


class ParsePool:
    """The bounded process pool of the document routes (see the module docstring)."""

    def __init__(self, workers: int) -> None:
        self.workers = workers
        self.limiter = anyio.CapacityLimiter(workers)
        self._closed = False
        self._starter: threading.Thread | None = None
        self._pool = self._new_pool()

    def _new_pool(self) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=multiprocessing.get_context("forkserver"),
            initializer=_init_parse_worker,
            initargs=(os.getpid(), WORKER_MODULES),
        )

    def start(self) -> None:
        """Start every process now, in the background (the server answers meanwhile; the
        first document then seldom waits for a process to start: starting the forkserver,
        which imports the engine, takes seconds)."""

        def spawn() -> None:
            with contextlib.suppress(RuntimeError):  # closed meanwhile
                for _ in range(self.workers):
                    if self._closed:
                        return
                    self._pool.submit(_ready)

        self._starter = threading.Thread(target=spawn, name="parse-pool-start", daemon=True)
        self._starter.start()

    def pids(self) -> list[int]:
        procs = self._pool._processes or {}
        return sorted(p.pid for p in list(procs.values()) if p.pid is not None)

    async def run(self, fn: Callable[..., Any], *args: Any) -> Any:
        """``fn(*args)`` in a pool process (at most ``workers`` at once); a document's error
        raises :class:`AnsweredError` with the answer the exception handlers would give."""
        async with self.limiter:
            pool = self._pool
            try:
                # submitting may start a process (and wait for the forkserver to boot): in a
                # thread, never on the event loop
                future = await anyio.to_thread.run_sync(pool.submit, _call, fn, args)
                out = await asyncio.wrap_future(future)
            except BrokenProcessPool:
                # a process died (killed, out of memory): this request fails, the next ones
                # get a fresh pool
                if self._pool is pool:
                    self._terminate(pool)
                    self._pool = self._new_pool()
                raise
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
        self._terminate(self._pool, timeout_s)

    @staticmethod
    def _terminate(pool: ProcessPoolExecutor, timeout_s: float = 10.0) -> None:
        procs = list((pool._processes or {}).values())
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
        manager = getattr(pool, "_executor_manager_thread", None)
        if manager is not None:
            manager.join(timeout_s)
        # and close that pipe here, once the thread is done with it: the exit hook skips a
        # closed one (its descriptor may be gone already: the hook's write then failed, EBADF)
        wakeup = getattr(pool, "_executor_manager_thread_wakeup", None)
        if wakeup is not None and (manager is None or not manager.is_alive()):
            with contextlib.suppress(OSError):
                wakeup.close()
