"""One BLAS thread for the engine's array products (``compute_bounds``, the planning site cache).

The products there are medium-sized (a [3G̃, N] @ [N, P] steering product, the spherical
[3U, N] @ [N, 3U] Gram, per-pair 3×3 to 9×9 blocks). On a multi-core machine a second BLAS
thread saves little on them, and on a loaded one it costs a lot: with the 2-core machine busy
the 100 × 100 spherical Gram took 0.46 s with OpenBLAS's two threads against 0.015 s with one
(the threads wait for each other), and the planar ``random`` layout 0.28–0.43 s against
0.16–0.18 s (``benchmarks/bounds/bench_bounds.py --blas-threads``). One thread also makes the
results independent of the machine: a threaded Gram partitions its sums differently (spherical FIMs
moved by ~5e-15 between 1 and 2 threads). The API and the plan's worker processes already run with
one thread (``api.settings.blas_threads``, :func:`ris_planner.runtime.executor.
capped_blas_threads`).

The limit is process-wide while any caller holds it (BLAS has one thread count); nested and
concurrent holders share it and the last one out restores the previous count.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager
from functools import cache
from typing import Any

from threadpoolctl import ThreadpoolController

_LOCK = threading.Lock()
_HOLDERS = [0]
_RESTORE: list[Any] = [None]


@cache
def _controller() -> ThreadpoolController:
    """The BLAS libraries loaded now (numpy's OpenBLAS is, once ris_planner is imported)."""
    return ThreadpoolController().select(user_api="blas")


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Run the block with BLAS limited to one thread (module docstring)."""
    with _LOCK:
        ctl = _controller()
        if any(lib.num_threads > 1 for lib in ctl.lib_controllers):
            # the first to find threads keeps what to restore (a later raise of the count by
            # someone else while holders run is limited again, and restored to the first)
            limiter = ctl.limit(limits=1)
            if _RESTORE[0] is None:
                _RESTORE[0] = limiter
        _HOLDERS[0] += 1
    try:
        yield
    finally:
        with _LOCK:
            _HOLDERS[0] -= 1
            if _HOLDERS[0] == 0 and _RESTORE[0] is not None:
                _RESTORE[0].restore_original_limits()
                _RESTORE[0] = None
