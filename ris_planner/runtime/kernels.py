"""One compiled parallel kernel at a time per process.

numba runs a ``parallel=True`` kernel on its own thread pool. Its OpenMP and TBB threading
layers accept launches from several Python threads at once, but the ``workqueue`` layer – the
one numba falls back to where neither runtime loads – does not: a second launch while one runs
aborts the process. A plan's checks run on a thread beside the later stages
(docs/concepts/planning.md, "Pipeline"), and the service answers bounds requests on several
threads, so every call of a parallel kernel (the CRB diagonals of
:mod:`ris_planner.inversion.crb`, the layout scorer, the obstacle walk) holds
:func:`parallel_kernel`. A kernel already spreads over every core, so the second caller
waiting costs nothing that running both at once would have saved.
"""

from __future__ import annotations

import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager

_LOCK = threading.Lock()


@contextmanager
def parallel_kernel() -> Iterator[None]:
    """Hold the process's parallel-kernel lock for the block (module docstring)."""
    with _LOCK:
        yield


def compiled_code_loaded() -> bool:
    """Whether this process has already loaded compiled code (numba's runtime is initialised:
    some kernel ran). The first kernel of a process pays ≈ 0.5–1 s to set numba up; each
    further one loads from the on-disk cache in milliseconds (an obstacle walk: ≈ 20 ms), so
    ``engine="auto"`` visibility compiles from a far smaller query once this holds
    (:data:`ris_planner.environment.scene.AUTO_COMPILED_WARM_MIN_WORK`). False where numba is
    not imported or its runtime cannot say."""
    if "numba" not in sys.modules:
        return False
    try:
        from numba.core.runtime import rtsys
    except ImportError:  # pragma: no cover - numba's layout changed
        return False
    return bool(getattr(rtsys, "_init", False))
