"""One interface for running layout-scoring chunks: in-process, a local process pool (the
default; BLAS threads capped at one per worker) or a Dask distributed cluster.

A task is ``fn(shared, chunk)``; ``shared`` (the site cache and weights) is sent once per
worker, the chunks are small arrays of layout indices.
"""

from __future__ import annotations

import multiprocessing
import os
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from contextlib import contextmanager
from typing import Any, TypeVar

S = TypeVar("S")
C = TypeVar("C")
R = TypeVar("R")

BLAS_THREAD_VARS = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    "NUMEXPR_NUM_THREADS",
    "NUMBA_NUM_THREADS",  # the compiled scorer's threads (ris_planner._crb_jit)
)


@contextmanager
def capped_blas_threads(n: int = 1) -> Iterator[None]:
    """Set the BLAS/OpenMP thread variables while worker processes start (they read them at
    import), so N workers do not oversubscribe the cores; restored afterwards."""
    old = {k: os.environ.get(k) for k in BLAS_THREAD_VARS}
    os.environ.update({k: str(n) for k in BLAS_THREAD_VARS})
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


class Executor(ABC):
    """Runs ``fn(shared, chunk)`` for every chunk and returns the results in chunk order."""

    workers: int = 1
    site_blocks: bool = False
    """Whether tasks should carry their own site block instead of a shared whole cache."""

    block_memo: Any = None
    """The search's handles of the current scorer's site blocks (set by the search)."""

    def share(self, obj: Any) -> Any:
        """A handle tasks may carry instead of ``obj`` (a cluster sends ``obj`` once)."""
        return obj

    def release(self) -> None:
        """Forget every :meth:`share` handle (and the search's block memo)."""
        self.block_memo = None

    @abstractmethod
    def map(
        self,
        fn: Callable[[S, C], R],
        shared: S,
        chunks: Sequence[C],
        on_done: Callable[[int], None] | None = None,
    ) -> list[R]:
        """Results in chunk order; ``on_done(n_finished)`` after each chunk."""

    def close(self) -> None:  # noqa: B027 - a no-op unless the executor holds workers
        """Release workers (idempotent)."""

    def __enter__(self) -> Executor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class SerialExecutor(Executor):
    """Everything in the calling process."""

    def map(
        self,
        fn: Callable[[S, C], R],
        shared: S,
        chunks: Sequence[C],
        on_done: Callable[[int], None] | None = None,
    ) -> list[R]:
        out = []
        for i, c in enumerate(chunks):
            out.append(fn(shared, c))
            if on_done is not None:
                on_done(i + 1)
        return out


_WORKER_SHARED: dict[str, Any] = {}


def _init_worker(shared: Any) -> None:
    _WORKER_SHARED["shared"] = shared


def _run_task(fn: Callable[[Any, Any], Any], chunk: Any) -> Any:
    return fn(_WORKER_SHARED["shared"], chunk)


class LocalExecutor(Executor):
    """A process pool (spawned workers, one BLAS thread each); ``shared`` goes to each worker
    once, through the pool initializer. Jobs of a single chunk run in-process."""

    def __init__(self, workers: int | None = None) -> None:
        self.workers = max(1, workers if workers is not None else (os.cpu_count() or 1))
        self._pool: ProcessPoolExecutor | None = None
        self._shared: Any = None

    def _pool_for(self, shared: Any) -> ProcessPoolExecutor:
        if self._pool is None or self._shared is not shared:
            self.close()
            with capped_blas_threads(1):
                self._pool = ProcessPoolExecutor(
                    max_workers=self.workers,
                    mp_context=multiprocessing.get_context("spawn"),
                    initializer=_init_worker,
                    initargs=(shared,),
                )
                # start every worker now, while the thread caps are in the environment
                list(self._pool.map(abs, range(self.workers)))
            self._shared = shared
        return self._pool

    def map(
        self,
        fn: Callable[[S, C], R],
        shared: S,
        chunks: Sequence[C],
        on_done: Callable[[int], None] | None = None,
    ) -> list[R]:
        if self.workers == 1 or len(chunks) <= 1:
            return SerialExecutor().map(fn, shared, chunks, on_done)
        pool = self._pool_for(shared)
        futures: dict[Future[R], int] = {
            pool.submit(_run_task, fn, c): i for i, c in enumerate(chunks)
        }
        out: list[Any] = [None] * len(chunks)
        for n, fut in enumerate(as_completed(futures), start=1):
            out[futures[fut]] = fut.result()
            if on_done is not None:
                on_done(n)
        return out

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None
            self._shared = None


class DaskExecutor(Executor):
    """Dask distributed: ``address`` of a running scheduler (``tcp://host:8786``) or an
    existing ``distributed.Client``. ``shared`` is scattered to every worker once; the layout
    search sends tasks that carry only their site blocks (``planning.search._evaluate_blocks``),
    so no worker needs the whole site cache."""

    site_blocks = True

    def __init__(self, address: Any) -> None:
        from distributed import Client

        self._own = not isinstance(address, Client)
        self.client = Client(address) if self._own else address
        self.workers = max(1, len(self.client.scheduler_info().get("workers", {})))
        self._shared: Any = None
        self._future: Any = None
        self._handles: dict[int, tuple[Any, Any]] = {}

    def share(self, obj: Any) -> Any:
        """A future of ``obj`` scattered once (to one worker; Dask moves it where needed)."""
        key = id(obj)
        if key not in self._handles or self._handles[key][0] is not obj:
            self._handles[key] = (obj, self.client.scatter(obj))
        return self._handles[key][1]

    def map(
        self,
        fn: Callable[[S, C], R],
        shared: S,
        chunks: Sequence[C],
        on_done: Callable[[int], None] | None = None,
    ) -> list[R]:
        from distributed import as_completed as dask_completed

        if self._shared is not shared:
            self._future = self.client.scatter(shared, broadcast=True)
            self._shared = shared
        futures = [self.client.submit(fn, self._future, c, pure=False) for c in chunks]
        index = {f.key: i for i, f in enumerate(futures)}
        out: list[Any] = [None] * len(chunks)
        for n, fut in enumerate(dask_completed(futures), start=1):
            out[index[fut.key]] = fut.result()
            if on_done is not None:
                on_done(n)
        return out

    def release(self) -> None:
        self._handles.clear()
        self.block_memo = None

    def close(self) -> None:
        self.release()
        if self._own:
            self.client.close()
            self._own = False
