"""``ris-planner warmup``: compile every numba kernel of the package once, into numba's on-disk
cache, so that the first plan after an install pays no compilation (docs/getting-started.md,
"Compiled kernels"; measured by ``benchmarks/planning/bench_cold_start.py``).

The kernels are found, not listed: every module of the package whose source defines an
``@njit`` function (:func:`kernel_modules`) is imported and each numba dispatcher defined in it
collected (:func:`kernels`) – a kernel added to any module is covered without an edit here.
They are compiled by running the package's own entry points on small inputs
(:data:`WORKLOADS`): the callers pass the very argument types (dtype, dimensions, layout) of a
real run, so the cached signatures are the ones a plan looks up – including both site-cache
precisions (float64, float32) of the planning scorer and the compiled visibility engine. A
kernel that none of the workloads compiled is an error naming it (:class:`WarmupError`); the
test suite runs the check (tests/test_warmup.py).

Numba caches next to each kernel's source (``__pycache__``) or, where the package folder is
not writable, in the user's cache folder, or in a per-user temporary folder when neither is
(:func:`ris_planner.runtime.allocator.ensure_numba_cache`); ``NUMBA_CACHE_DIR`` overrides all three.
Run the warm-up as the user (and with the ``NUMBA_CACHE_DIR``) that runs the plans.
"""

from __future__ import annotations

import importlib
import math
import os
import time
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

PACKAGE = "ris_planner"


class WarmupError(RuntimeError):
    """A kernel the warm-up did not compile (its workloads do not reach it)."""


def _package_root() -> Path:
    return Path(importlib.import_module(PACKAGE).__file__ or "").resolve().parent


def kernel_modules() -> list[str]:
    """Modules of the package whose source defines numba-compiled functions (``@njit`` or
    ``@numba.njit``/``@jit``), by name; found by reading the sources (no import)."""
    root = _package_root()
    names = []
    for path in sorted(root.rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        if any(marker in text for marker in ("@njit", "@numba.njit", "@jit(", "@numba.jit")):
            rel = path.relative_to(root.parent).with_suffix("")
            parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
            names.append(".".join(parts))
    return names


def kernels() -> dict[str, Any]:
    """Every numba dispatcher defined in :func:`kernel_modules`, by ``module.function``."""
    from numba.core.dispatcher import Dispatcher

    found: dict[str, Any] = {}
    for name in kernel_modules():
        module = importlib.import_module(name)
        for attr, value in vars(module).items():
            if isinstance(value, Dispatcher) and value.py_func.__module__ == name:
                found[f"{name}.{attr}"] = value
    return found


def cached_signatures(dispatcher: Any) -> int:
    """Signatures of a kernel in numba's on-disk cache for this machine's CPU (a kernel that
    only other kernels call is compiled into them: loaded from the cache with its callers,
    it gets no signature of its own in the process, but its own cache entry stays)."""
    cache_file = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)
    if cache_file is None:
        return 0
    try:
        index = cache_file._load_index()
        magic = dispatcher.targetctx.codegen().magic_tuple()
    except Exception:  # an unreadable index counts as none
        return 0
    return sum(1 for key in index if len(key) > 1 and key[1] == magic)


def signatures(dispatcher: Any) -> int:
    """Signatures of a kernel compiled in this process or cached on disk, whichever more."""
    return max(len(dispatcher.signatures), cached_signatures(dispatcher))


def uncompiled(found: dict[str, Any] | None = None) -> list[str]:
    """The kernels with no signature compiled in this process nor cached on disk (none after
    :func:`warm_up`)."""
    found = kernels() if found is None else found
    return sorted(name for name, d in found.items() if not signatures(d))


# ----- the workloads: the package's entry points on small inputs ------------------------------


def _ring_plan(n_sites: int, pairs: int, **over: Any) -> dict[str, Any]:
    """A plan of ``n_sites`` candidates on a ring facing the centre (a fraction of a second)."""
    candidates = []
    for k in range(n_sites):
        phi = 2 * math.pi * k / n_sites + 0.1
        candidates.append(
            {
                "position": [4.5 * math.cos(phi), 4.5 * math.sin(phi), 2.0 + (k % 2)],
                "orientation": [phi + math.pi, math.pi / 6, 0.0],
            }
        )
    grid = {"grid": {"x": [-3, 3, 0.5], "y": [-3, 3, 0.5], "z": [0, 0.5, 0.5]}}
    doc: dict[str, Any] = {
        "candidates": candidates,
        "tx_map": grid,
        "rx_map": grid,
        "pairs": {"sample": pairs, "seed": 1},
        "objective": {"kind": "mean_capped", "metric": "rx", "cap_m": 1.0},
        "ris_count": [2, 3],
    }
    return doc | over


@contextmanager
def _environ(**values: str) -> Any:
    old = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _plans() -> None:
    """The planning scorer on a float64 site cache (both objectives' metric modes: one UE's
    PEB with the coverage screen, the max of both) and on a float32 one (a site-cache budget
    of 1 MiB: 6 sites × 1200 pairs fit only as float32)."""
    from ris_planner.model.limits import CACHE_MEMORY_ENV
    from ris_planner.planning import SerialExecutor, run_plan

    with SerialExecutor() as ex:
        run_plan(_ring_plan(5, 200), executor=ex)
        run_plan(
            _ring_plan(5, 200, objective={"kind": "quantile", "metric": "max", "q": 0.9}),
            executor=ex,
        )
        with _environ(**{CACHE_MEMORY_ENV: "1"}):
            run_plan(_ring_plan(6, 1200, ris_count=[2]), executor=ex)


def _inversions() -> None:
    """The CRB inversions of ``compute_bounds`` and the scorer's square-root route: the
    compiled LDLᵀ, the Householder/Jacobi square-root diagonal and the Jacobi SVD."""
    from ris_planner.inversion import crb

    rng = np.random.default_rng(0)
    a = rng.standard_normal((8, 9, 7))
    a[:2, :, 6] = 0.0  # rank-deficient factors: the SVD and leak rule, not only the QR route
    crb.sqrt_crb_diagonal(a)
    crb.svd(a)
    f = np.einsum("nri,nrj->nij", a, a)
    rows, cols = np.tril_indices(7)
    packed = np.ascontiguousarray(f[:, rows, cols])
    crb.fast_diagonal(np.ascontiguousarray(packed.T), 7, engine="numba")
    idx = np.arange(8)
    crb.summed_crb_diagonal(packed, packed, idx, idx[::-1].copy(), 7, lambda i: a[i], "numba")


def _visibility() -> None:
    """The compiled visibility engine on a prism and a wall."""
    from ris_planner.environment import Scene
    from ris_planner.environment.model import Environment

    env = Environment.model_validate(
        {
            "obstacles": [
                {"kind": "prism", "footprint": [[0, 0], [2, 0], [2, 2], [0, 2]], "height_m": 3},
                {"kind": "wall", "start": [4, -1], "end": [4, 3], "height_m": 3},
            ]
        }
    )
    scene = Scene(env, engine="numba")
    a = np.array([[-1.0, 1.0, 1.0], [-1.0, -3.0, 1.0], [3.0, 1.0, 1.0]])
    b = np.array([[5.0, 1.0, 1.0], [5.0, -3.0, 1.0], [5.0, 1.0, 1.0]])
    scene.blocked(a, b)


WORKLOADS: dict[str, Callable[[], None]] = {
    "inversions": _inversions,
    "visibility": _visibility,
    "plans": _plans,
}
"""The warm-up's runs, by name, in order."""


@dataclass(frozen=True)
class WarmupReport:
    """What :func:`warm_up` did: the kernels and their compiled signatures, seconds per
    workload, where numba caches (per kernel module)."""

    kernels: dict[str, int]
    seconds: dict[str, float]
    cache_dirs: dict[str, str]

    def to_json(self) -> dict[str, Any]:
        return {
            "kernels": self.kernels,
            "seconds": self.seconds,
            "total_s": round(sum(self.seconds.values()), 3),
            "cache_dirs": self.cache_dirs,
        }


def _cache_dir(dispatcher: Any) -> str:
    cache = getattr(dispatcher, "_cache", None)
    return str(getattr(cache, "cache_path", getattr(cache, "_cache_path", "?")))


def prepare_figures() -> None:
    """matplotlib on its Agg backend with pyplot and the plan's figure code imported (≈ 0.4 s
    of a process's first figure): for :func:`prepare_process` and the command line's figure
    helper (:mod:`ris_planner.planning.figure_process`), which set it up before it is
    needed."""
    import matplotlib

    matplotlib.use("Agg")
    for module in ("matplotlib.pyplot", "ris_planner.planning.outputs.report"):
        importlib.import_module(module)


def prepare_process() -> None:
    """Set up, in this process, what each plan would otherwise set up in its own: matplotlib on
    its Agg backend (the figures' import, ≈ 0.4 s) and numba's runtime with the scorer's and
    the walk's kernel modules (≈ 0.5–0.8 s before the first kernel of a process runs; the
    kernels themselves then load from the cache in milliseconds). Runs no parallel kernel and
    so starts no thread: the process may fork afterwards – the service's forkserver calls it
    once and every plan job, a fork of it, starts with both (docs/guides/service-operations.md,
    "Job processes")."""
    prepare_figures()
    from ris_planner.environment import _jit  # noqa: F401 - the walk's kernels, imported
    from ris_planner.inversion import _crb_jit

    _crb_jit.work_rows(7)  # a serial kernel from the cache: numba's runtime is set up


def warm_up(say: Callable[[str], None] | None = None) -> WarmupReport:
    """Run :data:`WORKLOADS` (compiling and caching every kernel they reach), then check that
    every kernel of the package has a compiled signature; :class:`WarmupError` names any that
    has none."""
    seconds: dict[str, float] = {}
    for name, run in WORKLOADS.items():
        t0 = time.perf_counter()
        run()
        seconds[name] = round(time.perf_counter() - t0, 3)
        if say is not None:
            say(f"warm-up: {name} in {seconds[name]:.1f} s")
    found = kernels()
    missing = uncompiled(found)
    if missing:
        raise WarmupError(
            f"the warm-up compiled no signature of {', '.join(missing)}: add a workload that"
            " reaches it (ris_planner.planning.warmup.WORKLOADS)"
        )
    dirs = {name.rsplit(".", 1)[0]: _cache_dir(d) for name, d in found.items()}
    return WarmupReport({n: signatures(d) for n, d in found.items()}, seconds, dirs)
