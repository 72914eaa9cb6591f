"""One interface for running layout-scoring chunks: in-process, a local process pool (the
default; BLAS threads capped at one per worker) or a Dask distributed cluster.

A task is ``fn(shared, chunk)``; ``shared`` (the site cache and weights) reaches each worker
once, the chunks are small arrays of layout indices.

The local pool shares ``shared``'s large arrays instead of copying them (Linux): they are
written once into an anonymous memory file (``memfd_create``, never a name in ``/dev/shm``)
that the workers map copy-on-write through ``/proc/<pid>/fd`` – one copy in RAM for every
worker, and nothing left behind whatever the exit, since the memory goes away with the last
process that holds the file (:class:`SharedArrays`). The tasks carry only a small pickle of
``shared`` whose arrays are handles into that file (:func:`share_pickle`).
"""

from __future__ import annotations

import importlib
import io
import mmap
import multiprocessing
import os
import pickle
import threading
import time
import uuid
import weakref
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

from ris_planner.runtime import allocator

S = TypeVar("S")
C = TypeVar("C")
R = TypeVar("R")

BLAS_THREAD_VARS = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    "NUMEXPR_NUM_THREADS",
    "NUMBA_NUM_THREADS",  # the compiled scorer's threads (ris_planner.inversion._crb_jit)
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

    def start(self) -> None:  # noqa: B027 - a no-op unless the executor starts workers
        """Start workers now, without waiting (the caller's own work overlaps their start)."""

    @property
    def started(self) -> bool:
        """Whether the executor holds started local workers (tasks then cost no start-up)."""
        return False

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


SHARE_MIN_BYTES = 1 << 16
"""Arrays of at least this size go into the shared memory file; smaller ones (the weights of a
few thousand pairs, masks of a few sites) travel inside each task's pickle, where they cost
less than a page-aligned slot."""

SHARE_ALIGN = 4096
"""Offset alignment of the arrays in the memory file (a page: every mapped array starts on a
page of its own, so a worker's copy-on-write of one array never copies its neighbour's bytes)."""

MEMFD_PREFIX = "ris_planner-share-"
"""Name of the anonymous memory files (``/proc/<pid>/fd/N`` links read ``/memfd:<name>``)."""

WARM_MODULES = ("ris_planner.planning.search.layouts", "ris_planner.planning.certify.branch_bound")
"""Modules a local worker imports as it starts (numpy, numba and the scorer), so that a pool
started early has its imports done by the time the first task arrives."""


def sharing_supported() -> bool:
    """Whether arrays can be shared with local workers (Linux: ``memfd_create`` and
    ``/proc/<pid>/fd``); elsewhere the pool pickles ``shared`` to each worker."""
    return hasattr(os, "memfd_create") and os.path.isdir(f"/proc/{os.getpid()}/fd")


class SharedArrays:
    """One anonymous memory file (``memfd_create``) holding the large arrays of one shared
    object, owned by the creating process. :meth:`put` appends an array and gives its handle;
    a worker maps the file (``/proc/<owner pid>/fd/<fd>``, private copy-on-write: the arrays
    stay writeable as unpickled ones, and no write reaches another process). :meth:`close`
    drops the owner's file descriptor; the memory is freed when the last mapping goes too."""

    def __init__(self) -> None:
        self.name = MEMFD_PREFIX + uuid.uuid4().hex
        self.fd: int | None = os.memfd_create(self.name, os.MFD_CLOEXEC)
        self.size = 0
        self.pid = os.getpid()
        # closed when this object goes, should no one call close()
        self._finalizer = weakref.finalize(self, os.close, self.fd)

    def put(self, arr: np.ndarray[Any, Any]) -> tuple[Any, ...]:
        """Copy ``arr`` into the file; the arguments of :func:`_attach_array`."""
        assert self.fd is not None, "the shared arrays are closed"
        fortran = bool(arr.flags.f_contiguous and not arr.flags.c_contiguous)
        data = np.asarray(arr, order="F" if fortran else "C").ravel(order="K")  # no copy
        offset = -(-self.size // SHARE_ALIGN) * SHARE_ALIGN
        view = data.view(np.uint8).data  # a 1-D byte memoryview
        done = 0
        while done < view.nbytes:  # pwrite may write less than asked
            done += os.pwrite(self.fd, view[done:], offset + done)
        self.size = offset + view.nbytes
        return (self.pid, self.fd, self.name, offset, arr.dtype, arr.shape, fortran)

    def close(self) -> None:
        """Drop the owner's descriptor (idempotent)."""
        if self.fd is not None:
            self._finalizer()  # os.close(fd), once
            self.fd = None


_ATTACHED: dict[str, mmap.mmap] = {}
"""The memory files mapped while one pickle is loaded (:func:`load_shared`); emptied after it,
so a file is unmapped once its arrays are dropped."""


def _attach_array(
    pid: int,
    fd: int,
    name: str,
    offset: int,
    dtype: np.dtype[Any],
    shape: tuple[int, ...],
    fortran: bool,
) -> np.ndarray[Any, Any]:
    """An array in the memory file of :class:`SharedArrays` (mapped once per load)."""
    mm = _ATTACHED.get(name)
    if mm is None:
        path = f"/proc/{pid}/fd/{fd}"
        try:
            link = os.readlink(path)
            handle = os.open(path, os.O_RDONLY) if link == f"/memfd:{name} (deleted)" else -1
        except FileNotFoundError:
            handle = -1  # the owner closed it (or exited)
        except OSError as err:
            raise RuntimeError(
                f"cannot open the shared arrays of process {pid} ({err}); on a system that hides"
                " other processes' /proc entries use LocalExecutor(share_memory=False)"
            ) from err
        if handle < 0:
            raise RuntimeError(f"shared arrays {name} are gone (process {pid} closed them)")
        try:
            mm = mmap.mmap(handle, 0, flags=mmap.MAP_PRIVATE, prot=mmap.PROT_READ | mmap.PROT_WRITE)
        finally:
            os.close(handle)
        _ATTACHED[name] = mm
    count = int(np.prod(shape, dtype=np.int64))
    flat = np.frombuffer(mm, dtype=dtype, count=count, offset=offset)
    return flat.reshape(shape, order="F" if fortran else "C")


class _SharingPickler(pickle.Pickler):
    """Pickles every ndarray of at least :data:`SHARE_MIN_BYTES` as a handle into ``arrays``
    (any object graph: the site cache's fields, whatever they are); an object whose class has
    ``__share_state__()`` is pickled with that state instead of ``__getstate__()``'s."""

    def __init__(self, file: io.BytesIO, arrays: SharedArrays) -> None:
        super().__init__(file, protocol=pickle.HIGHEST_PROTOCOL)
        self._arrays = arrays

    def reducer_override(self, obj: Any) -> Any:
        if isinstance(obj, np.ndarray):
            if obj.nbytes >= SHARE_MIN_BYTES and not obj.dtype.hasobject:
                return _attach_array, self._arrays.put(obj)
            return NotImplemented
        hook = getattr(type(obj), "__share_state__", None)
        if hook is None or isinstance(obj, type):
            return NotImplemented
        # the object's own reduction with the state it chose for shared arrays (e.g. the
        # per-process caches a worker need not rebuild when they cost no copy)
        rv = obj.__reduce_ex__(pickle.HIGHEST_PROTOCOL)
        return (*rv[:2], hook(obj), *rv[3:])


@dataclass(frozen=True)
class SharedPickle:
    """``shared`` pickled with its large arrays in :attr:`arrays` (kept open by the owner);
    ``key`` names it in the workers."""

    key: str
    data: bytes
    arrays: SharedArrays

    def __getstate__(self) -> dict[str, Any]:
        return {"key": self.key, "data": self.data, "arrays": None}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)


def share_pickle(obj: Any) -> SharedPickle:
    """``obj`` pickled for local workers, its large arrays written once into shared memory."""
    arrays = SharedArrays()
    try:
        buf = io.BytesIO()
        _SharingPickler(buf, arrays).dump(obj)
    except BaseException:
        arrays.close()
        raise
    return SharedPickle(arrays.name, buf.getvalue(), arrays)


def load_shared(payload: SharedPickle) -> Any:
    """The object of :func:`share_pickle` (its large arrays mapped, not copied)."""
    try:
        return pickle.loads(payload.data)
    finally:
        _ATTACHED.clear()


_WORKER_SHARED: dict[str, Any] = {}

PARENT_CHECK_S = 0.5
"""A pool worker checks this often whether the process that started it is gone (and exits)."""


def _exit_with_parent(parent: int) -> None:
    """Daemon thread of a pool worker: exit as soon as its parent process (pid ``parent``, the
    pool's owner: passed in, since it may die while the worker still starts) is gone. A worker
    blocks on its task queue, whose write end it holds itself, so it would never notice a
    parent killed without closing the pool (a cancelled service job, a killed command line)."""
    while os.getppid() == parent:
        time.sleep(PARENT_CHECK_S)
    os._exit(1)


def _start_parent_watch(parent: int) -> None:
    if os.getppid() != parent:
        os._exit(1)
    threading.Thread(
        target=_exit_with_parent, args=(parent,), name="parent-watch", daemon=True
    ).start()


def _init_worker(shared: Any, parent: int) -> None:
    allocator.tune_worker()
    _start_parent_watch(parent)
    _WORKER_SHARED["shared"] = shared


def _run_task(fn: Callable[[Any, Any], Any], chunk: Any) -> Any:
    return fn(_WORKER_SHARED["shared"], chunk)


def _warm_worker(modules: tuple[str, ...], parent: int) -> None:
    """Pool initializer of the sharing pool: import the task modules now."""
    allocator.tune_worker()
    _start_parent_watch(parent)
    for name in modules:
        importlib.import_module(name)


def _run_shared_task(fn: Callable[[Any, Any], Any], payload: SharedPickle, chunk: Any) -> Any:
    """A task of the sharing pool: load ``payload`` once per worker (the previous one dropped
    first, so its mapping goes), then ``fn(shared, chunk)``."""
    if _WORKER_SHARED.get("key") != payload.key:
        _WORKER_SHARED.clear()
        _WORKER_SHARED["shared"] = load_shared(payload)
        _WORKER_SHARED["key"] = payload.key
    return fn(_WORKER_SHARED["shared"], chunk)


def _worker_ready() -> None:
    """The warm-up task (one per worker: the pool spawns a process per task up to its size)."""


class LocalExecutor(Executor):
    """A process pool (spawned workers, one BLAS thread each); jobs of a single chunk run
    in-process.

    With ``share_memory`` (the default where :func:`sharing_supported`) the pool is started
    once (:meth:`start`, early if the caller likes: the workers' imports then overlap its own
    work) and ``shared``'s large arrays are written once into shared memory that every worker
    maps (:func:`share_pickle`); otherwise ``shared`` is pickled to each worker through a pool
    initializer, a new pool per shared object."""

    def __init__(self, workers: int | None = None, share_memory: bool | None = None) -> None:
        self.workers = max(1, workers if workers is not None else (os.cpu_count() or 1))
        self.share_memory = sharing_supported() if share_memory is None else share_memory
        if self.share_memory and not sharing_supported():
            raise ValueError("share_memory needs Linux (memfd_create and /proc/<pid>/fd)")
        self._pool: ProcessPoolExecutor | None = None
        self._shared: Any = None
        self._payload: SharedPickle | None = None
        self._warm: list[Future[None]] = []

    def _spawn(self, initializer: Callable[..., None], initargs: tuple[Any, ...]) -> None:
        with capped_blas_threads(1):
            self._pool = ProcessPoolExecutor(
                max_workers=self.workers,
                mp_context=multiprocessing.get_context("spawn"),
                initializer=initializer,
                initargs=(*initargs, os.getpid()),
            )
            # start every worker now, while the thread caps are in the environment (the pool
            # spawns a process per submitted task until it has them all)
            self._warm = [self._pool.submit(_worker_ready) for _ in range(self.workers)]

    def start(self) -> None:
        """Start the sharing pool's workers without waiting for them (no-op without
        ``share_memory``, one worker, or when started)."""
        if self.share_memory and self.workers > 1 and self._pool is None:
            self._spawn(_warm_worker, (WARM_MODULES,))

    @property
    def started(self) -> bool:
        return self._pool is not None and self.workers > 1

    def worker_pids(self) -> list[int]:
        """The process ids of the pool's workers (none before :meth:`start` or the first
        parallel :meth:`map`, nor after :meth:`close`); waits until they run."""
        for f in self._warm:
            f.result()
        # (the pool spawns its processes as tasks arrive; it keeps them in ``_processes``)
        processes = {} if self._pool is None else self._pool._processes
        return sorted(int(p.pid) for p in (processes or {}).values() if p.pid is not None)

    def _pool_for(self, shared: Any) -> ProcessPoolExecutor:
        if self.share_memory:
            self.start()
            if self._shared is not shared:
                self._drop_payload()
                self._payload = share_pickle(shared)
                self._shared = shared
        elif self._pool is None or self._shared is not shared:
            self.close()
            self._spawn(_init_worker, (shared,))
            self._shared = shared
        assert self._pool is not None
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
        try:
            if shared is None:  # the tasks need no shared object: any running pool serves
                if self._pool is None:
                    self._pool_for(None)
                assert self._pool is not None
                futures: dict[Future[R], int] = {
                    self._pool.submit(fn, None, c): i  # type: ignore[arg-type]
                    for i, c in enumerate(chunks)
                }
            else:
                pool = self._pool_for(shared)
                payload = self._payload
                futures = {
                    (
                        pool.submit(_run_shared_task, fn, payload, c)
                        if payload is not None
                        else pool.submit(_run_task, fn, c)
                    ): i
                    for i, c in enumerate(chunks)
                }
            out: list[Any] = [None] * len(chunks)
            for n, fut in enumerate(as_completed(futures), start=1):
                out[futures[fut]] = fut.result()
                if on_done is not None:
                    on_done(n)
        except BaseException:
            # a failed task, a lost worker or an interrupt: nothing is left running or held
            # (the next call starts a fresh pool)
            self.close()
            raise
        return out

    def _drop_payload(self) -> None:
        if self._payload is not None:
            self._payload.arrays.close()
            self._payload = None

    def release(self) -> None:
        """Close the shared memory of the current ``shared`` (the workers keep their mapping
        until the next ``shared`` arrives)."""
        super().release()
        if self.share_memory:
            self._drop_payload()
            self._shared = None

    def close(self) -> None:
        self._drop_payload()
        self._shared = None
        self._warm = []
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


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
