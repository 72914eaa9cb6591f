"""glibc malloc thresholds for the engine's array temporaries (set by the entry points, never
at import).

A bounds batch makes many short-lived arrays of 0.1–10 MB (the [N, 512] steering blocks, the
[5, 5, P] FIM products, the [P, 7, 7] sums). glibc serves an allocation above its mmap
threshold with a fresh mapping and returns it to the system when freed, so every such
temporary is page-faulted anew; its heuristic raises the threshold only after a freed mapping
and trims the heap top again, so the faults keep coming. On the 2-core machine the planar
``random`` Fig. 10 layout (4 RISs, 4753 pairs) spent ≈ 25 % of its CPU time there: 133–149
against 101–104 ms CPU per layout with the thresholds below (alternating runs, README "Validation
and speed of the bounds"); tests/test_allocator.py counts the page faults.

Importing :mod:`ris_planner` changes nothing in the host process: the thresholds are set by
the entry points – the ``ris-planner`` command line (:func:`ris_planner.cli.app`), the
service's startup and its job workers – and, as an opt-in, by a script that calls
:func:`tune_malloc`. A process that tuned itself marks the environment
(``RIS_PLANNER_MALLOC_TUNING=1``) so the worker processes it spawns (the local pool) follow it
(:func:`tune_worker`).

The values are those the heuristic itself reaches after a freed 32 MiB array (glibc's
``DEFAULT_MMAP_THRESHOLD_MAX`` on 64-bit, trim at twice that): at most 64 MiB of freed heap
stays mapped for reuse. Nothing is changed when ``RIS_PLANNER_MALLOC_TUNING=0``, when the
process was started with glibc's own ``MALLOC_MMAP_THRESHOLD_`` / ``MALLOC_TRIM_THRESHOLD_``
(the user chose), or off glibc (no ``mallopt``).
"""

from __future__ import annotations

import ctypes
import os
import sys

M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
"""glibc's ``mallopt`` parameter numbers (malloc.h)."""

MMAP_THRESHOLD_BYTES = 32 << 20
TRIM_THRESHOLD_BYTES = 64 << 20

TUNING_ENV = "RIS_PLANNER_MALLOC_TUNING"
GLIBC_ENV = ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_")


_STATE = {"tuned": False}


def tune_malloc() -> bool:
    """Set the thresholds in this process (see the module docstring) unless the user opted out
    (``RIS_PLANNER_MALLOC_TUNING=0``) or chose glibc's own variables; whether they are set.
    Marks the environment so spawned workers follow (:func:`tune_worker`)."""
    if _STATE["tuned"]:
        return True
    if os.environ.get(TUNING_ENV, "1").strip() == "0":
        return False
    if any(k in os.environ for k in GLIBC_ENV) or not sys.platform.startswith("linux"):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    ok = mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES) == 1
    ok = ok and mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES) == 1
    if ok:
        _STATE["tuned"] = True
        os.environ[TUNING_ENV] = "1"
    return ok


def tune_worker() -> bool:
    """In a worker process: tune only when the process that started it did
    (``RIS_PLANNER_MALLOC_TUNING=1`` in the inherited environment)."""
    if os.environ.get(TUNING_ENV, "").strip() != "1":
        return False
    return tune_malloc()


def tuned() -> bool:
    """Whether this process runs with the thresholds."""
    return _STATE["tuned"]


# ----- numba's on-disk cache ------------------------------------------------------------------

NUMBA_FALLBACK_CACHE = "ris_planner-numba-cache"
"""Folder (under the system's temporary directory, one per user) of the compiled kernels when
neither the package's own ``__pycache__`` nor the user's cache folder is writable."""


def ensure_numba_cache(source_file: str) -> str | None:
    """Make sure numba can cache the kernels of ``source_file`` (called by each kernel module
    before its ``@njit(cache=True)`` functions are defined: without a writable location numba
    refuses to define them). Numba writes next to the source (``__pycache__``) when that is
    writable, else in the user's cache folder (``~/.cache/numba``); when neither is (a
    read-only install run by a user without a writable home) this sets numba's cache folder
    to a stable per-user folder under the temporary directory. ``NUMBA_CACHE_DIR`` set by the
    user always wins. Returns the folder set, or None when numba's own choice stands
    (docs/getting-started.md, "Compiled kernels")."""
    import tempfile

    from numba.core import caching, config

    if config.CACHE_DIR:  # type: ignore[attr-defined]
        return None
    for locator in (caching.InTreeCacheLocator, caching.UserWideCacheLocator):
        if locator.from_function(ensure_numba_cache, source_file) is not None:
            return None
    uid = os.getuid() if hasattr(os, "getuid") else 0
    path = os.path.join(tempfile.gettempdir(), f"{NUMBA_FALLBACK_CACHE}-{uid}")
    os.makedirs(path, mode=0o700, exist_ok=True)
    config.CACHE_DIR = path  # type: ignore[attr-defined]
    return path
