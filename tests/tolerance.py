"""The project's one tolerance rule for comparing floats that two routes computed.

Rule (docs/concepts/numerics.md, "Comparing results"):

* **Exact** only where the operation is exact by construction: integers, booleans, strings,
  masks, copies, and two routes inside one process that perform the same IEEE operations in
  the same order (a documented bit-for-bit contract between a fast and a reference route).
* **Everywhere else** – across processes, threads, BLAS kernels (``OPENBLAS_CORETYPE``), numpy
  SIMD dispatch (``NPY_DISABLE_CPU_FEATURES``) or stored files – a float is compared with the
  relative tolerance ``ulps · ε · cond`` where ε is the double-precision unit roundoff
  (2.2e-16), ``ulps`` the number of roundings on the longest dependency chain the two routes
  may order differently (a dot product of n terms reorders n roundings; a backward-stable
  factorisation a small multiple of the matrix size), and ``cond`` the condition number of
  the computation (1 for well-conditioned arithmetic, the scaled condition number of the
  Fisher information for a bound obtained by inverting it: :func:`fim_cond`).
* A route with a **documented accuracy** is compared at that accuracy (``accuracy``), never at
  its last bit: an iterative solver (an SDP by an interior-point method) at its stopping
  tolerance, a reported bound (PEB, CEB, DEB, SEB) and every plan figure derived from bounds at
  the bounds' accuracy contract :data:`BOUND_ACCURACY` (docs/concepts/numerics.md).

``inf``/``nan``/``None`` must sit at the same places in both; everything that is not a float
is compared exactly.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

EPS = float(np.finfo(np.float64).eps)
"""Double-precision machine epsilon (2.22e-16)."""

BOUND_ACCURACY = 1e-6
"""The accuracy contract of a reported bound: relative 1e-6 wherever the information on the
unknown states is non-singular to working precision. Results that went through another process
(REST, CLI, worker pools, Dask) are compared to it; plan objectives are means, quantiles and
fractions of such bounds."""

SDP_ACCURACY = 1e-4
"""An SDP solution (objective, powers) re-solved in another process, or re-evaluated by
``compute_bounds``: the interior-point solver stops at Clarabel's default gap 1e-8 on the
whitened problem, which leaves the reported objective ~1e-8–1e-5 from the exact optimum."""

DEFAULT_ULPS = 64.0
"""Roundings a typical short reordered chain (a 7×7 factorisation, a reordered sum of tens of
terms) may differ by: 64 ulps ≈ 1.4e-14 relative."""


def fim_cond(f: Any) -> float:
    """Condition number of a Fisher information after unit-diagonal scaling, over the states it
    informs (rows with a zero diagonal – a known or absent part – left out): the relative
    accuracy a backward-stable inversion reaches scales with it. ≥ 1; huge or ``inf`` when
    singular."""
    f = np.asarray(f, dtype=float)
    keep = np.diag(f) > 0
    if not keep.any():
        return 1.0
    f = f[np.ix_(keep, keep)]
    d = np.sqrt(np.diag(f))
    return max(1.0, float(np.linalg.cond(f / np.outer(d, d))))


def rtol(ulps: float = DEFAULT_ULPS, cond: float = 1.0, accuracy: float = 0.0) -> float:
    """Relative tolerance of the rule: ``max(ulps · ε · cond, accuracy)``."""
    return max(ulps * EPS * max(cond, 1.0), accuracy)


def _close(a: float, b: float, tol: float, atol: float) -> bool:
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    if math.isinf(a) or math.isinf(b):
        return a == b
    return abs(a - b) <= atol + tol * max(abs(a), abs(b))


def assert_close(
    got: Any,
    want: Any,
    *,
    ulps: float = DEFAULT_ULPS,
    cond: float = 1.0,
    accuracy: float = 0.0,
    atol: float = 0.0,
    where: str = "",
) -> None:
    """Assert that ``got`` equals ``want`` under the rule: floats (scalars, arrays, and floats
    nested in JSON-like dicts and lists) to :func:`rtol` (plus ``atol`` for values that are
    zero up to rounding), everything else exactly; ``None``/``inf``/``nan`` at the same places.
    ``where`` prefixes the message with a path."""
    tol = rtol(ulps, cond, accuracy)
    _assert(got, want, tol, atol, where or "value")


def _is_number(x: Any) -> bool:
    return isinstance(x, (float, int, np.floating, np.integer)) and not isinstance(x, bool)


def _assert(got: Any, want: Any, tol: float, atol: float, where: str) -> None:
    if isinstance(want, Mapping):
        assert isinstance(got, Mapping), f"{where}: {type(got).__name__} is not a mapping"
        assert set(got) == set(want), f"{where}: keys {sorted(got)} != {sorted(want)}"
        for key in want:
            _assert(got[key], want[key], tol, atol, f"{where}.{key}")
        return
    if isinstance(want, np.ndarray) or isinstance(got, np.ndarray):
        g, w = np.asarray(got), np.asarray(want)
        assert g.shape == w.shape, f"{where}: shape {g.shape} != {w.shape}"
        if g.dtype.kind in "fc" or w.dtype.kind in "fc":
            for part in (np.real, np.imag) if "c" in (g.dtype.kind, w.dtype.kind) else (np.real,):
                gp, wp = part(g).astype(float), part(w).astype(float)
                same_special = (np.isnan(gp) == np.isnan(wp)).all() and (
                    gp[np.isinf(wp) | np.isinf(gp)] == wp[np.isinf(wp) | np.isinf(gp)]
                ).all()
                assert same_special, f"{where}: inf/nan at different places"
                fin = np.isfinite(wp) & np.isfinite(gp)
                diff = np.abs(gp[fin] - wp[fin])
                lim = atol + tol * np.maximum(np.abs(gp[fin]), np.abs(wp[fin]))
                bad = np.flatnonzero(diff > lim)
                assert bad.size == 0, (
                    f"{where}: {bad.size} of {fin.sum()} values differ beyond rtol {tol:.3g}"
                    f" (worst relative {float(np.max(diff / np.maximum(lim, 1e-300))):.3g}× the"
                    " limit)"
                )
        else:
            assert np.array_equal(g, w), f"{where}: {g} != {w}"
        return
    if isinstance(want, Sequence) and not isinstance(want, (str, bytes)):
        assert isinstance(got, Sequence) and not isinstance(got, (str, bytes)), (
            f"{where}: {type(got).__name__} is not a list"
        )
        assert len(got) == len(want), f"{where}: length {len(got)} != {len(want)}"
        for i, (g, w) in enumerate(zip(got, want, strict=True)):
            _assert(g, w, tol, atol, f"{where}[{i}]")
        return
    if isinstance(want, (float, np.floating)) or isinstance(got, (float, np.floating)):
        assert _is_number(got) and _is_number(want), f"{where}: {got!r} != {want!r}"
        assert _close(float(got), float(want), tol, atol), (
            f"{where}: {got!r} != {want!r} (rtol {tol:.3g}, atol {atol:.3g})"
        )
        return
    assert got == want, f"{where}: {got!r} != {want!r}"
