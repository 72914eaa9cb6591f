"""Numerically sound CRB of the state [p_T, p_R, B] from per-path information (docs/concepts/
numerics.md, "Accuracy rule for bounds").

Every path ℓ gives an equivalent FIM Ĩ_ℓ [m, m] on its channel parameters and a Jacobian
J_ℓ [m, 7] (eq. crb_sidelink), so F = Σ_ℓ J_ℓᵀ Ĩ_ℓ J_ℓ. With Ĩ_ℓ = L_ℓ L_ℓᵀ the rows
A_ℓ = L_ℓᵀ J_ℓ are a square-root factor: F = AᵀA for the stack A of all paths' rows
[P, n_obs, 7]. Forming F squares the condition number; working on A does not.

The route (one rule for ``compute_bounds`` and the planning scorer, so both give the same
numbers bit for bit):

1. Fast path: batched LDLᵀ of the symmetrically scaled F (:mod:`ris_planner.inversion.ldl`), which
is
   accurate to ~ε·cond(F̂). Kept where trace(F̂⁻¹) ≤ :data:`FAST_TRACE_LIMIT` (F̂ = F scaled to
   unit diagonal; cond(F̂) ≤ 7·trace(F̂⁻¹) since λ_max(F̂) ≤ 7).
2. Everything else (near-singular or singular pairs): SVD of the column-scaled factor
   Â = A·diag(1/‖A_:,j‖) restricted to the unknown states, Â = U Σ Vᵀ. Singular values with
   σ_j ≤ :data:`SINGULAR_SV_RTOL`·σ_max span the numerical null space. A state i is
   identifiable when its leak into the null space, ‖V[i, null]‖, is ≤ :data:`NULL_LEAK_TOL`;
   its bound is then (F⁻)_ii = Σ_{j kept} V_ij²/σ_j² / ‖A_:,i‖² (the pseudo-inverse is a
   generalised inverse of F, and every generalised inverse gives the CRB of an estimable
   state). A non-identifiable state is ``inf``. So a null direction that involves only the
   clock or the TX does not hide a determined PEB_R.

Both steps are compiled (:mod:`ris_planner.inversion._crb_jit`, numba): the LDLᵀ from
:data:`JIT_MIN_MATRICES` on, with exactly the bits of :mod:`ris_planner.inversion.ldl`; the
square-root
step always (:func:`sqrt_crb_diagonal`: a certified QR where no singular value can be near the
threshold, the one-sided Jacobi SVD elsewhere), so ``compute_bounds`` and the planning scorer
take the same arithmetic for every pair.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Literal, NamedTuple

import numpy as np
from numpy.typing import NDArray

from ris_planner.inversion import ldl
from ris_planner.runtime.kernels import parallel_kernel

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int_]
Engine = Literal["auto", "numba", "numpy"]

JIT_MIN_MATRICES = 100_000
"""``crb_diagonal`` runs the compiled LDLᵀ from this many matrices on (below, numpy's takes
≤ 25 ms, less than importing numba; both give the same bits)."""

FAST_TRACE_LIMIT = 1e8
"""The LDLᵀ of F is used when trace(F̂⁻¹) ≤ this. Rounding F̂'s entries (sums of PSD terms,
each |F̂_ij| ≤ 1) perturbs a CRB entry by at most λ_max(F̂⁻¹)·‖δF̂‖ ≤ trace(F̂⁻¹)·‖δF̂‖;
measured against the square-root route on 10 000 layout-pairs of the planning benchmark
(plain coordinates, ``examples/crb_accuracy.py``) the relative error of PEB_R stayed
≤ 3.7e-16·trace(F̂⁻¹), i.e. ≤ 4e-8 at the limit: inside the contract's 1e-6 with a factor
25 margin. Above it the square-root route decides."""

SINGULAR_SV_RTOL = 1e-9
"""A singular value of the column-scaled square-root factor Â with σ ≤ this · σ_max belongs to
the null space (the state information is singular there). Float64 perturbations of Â of
~ε·σ_max move σ_min by that much, so a kept σ ≥ 1e-9·σ_max carries ≤ 2.2e-7 relative error,
and the CRB (∝ 1/σ²) ≤ ~5e-7: reported bounds stay within 1e-6. The threshold is cond(F̂)
= 1e18 in the squared form; an exactly singular layout has σ_min ~ 1e-16·σ_max."""

NULL_LEAK_TOL = 1e-6
"""A state is identifiable when its component in the numerical null space, ‖V[i, null]‖, is
≤ this. Float64 null vectors are accurate to ~ε·σ_max/σ_gap ≤ 2.2e-7 when the kept singular
values are ≥ SINGULAR_SV_RTOL·σ_max, so an exactly orthogonal state reads ≤ 2.2e-7."""


QR_CERT_MARGIN = 2.0
"""Safety factor of the QR certificate of :func:`sqrt_crb_diagonal`: the computed ‖R⁻¹‖_F
carries ≤ ~ε·cond(Â) ≤ 2.2e-7 relative rounding where the certificate applies (cond(Â) ≤
1e9/√k), so a factor 2 keeps every certified σ_min twice above the threshold."""


def path_factor(efim: FloatArray, jacobian: FloatArray) -> FloatArray:
    """Square-root rows L_ℓᵀ J_ℓ of one path's contribution J_ℓᵀ Ĩ_ℓ J_ℓ, [P, m, 7].

    efim : [P, m, m] symmetric positive semidefinite (Ĩ_ℓ = V diag(w) Vᵀ, L = V diag(√w));
    jacobian : [P, m, 7]. Negative rounding eigenvalues are clipped to 0.
    """
    if efim.shape[-1] == 1:
        # [P, 1, 7]
        return np.asarray(np.sqrt(np.clip(efim, 0.0, None)) * jacobian)
    w, v = np.linalg.eigh(efim)
    # [P, m, m] rows √w_k v_kᵀ
    lt = np.sqrt(np.clip(w, 0.0, None))[:, :, None] * v.transpose(0, 2, 1)
    return np.asarray(lt @ jacobian)


def stack_factors(factors: list[FloatArray], present: BoolArray | None = None) -> FloatArray:
    """The stacked square-root factor A [P, n_obs, 7] of the paths' rows [P, m_ℓ, 7], in path
    order; ``present`` [P, n_paths] zeroes the rows of a path missing for a pair."""
    if present is not None:
        factors = [f * present[:, k, None, None] for k, f in enumerate(factors)]
    return np.concatenate(factors, axis=1)


class _SqrtSVD(NamedTuple):
    """SVD of the column-scaled square-root factor (module docstring)."""

    scale: FloatArray  # [N, k] ‖A_:,i‖ (zeros replaced by 1)
    zero: BoolArray  # [N, k] states with no information at all
    inv_s2: FloatArray  # [N, k] 1/σ_j² on the kept singular values, 0 on the null space
    null: BoolArray  # [N, k] null-space singular values
    vt: FloatArray  # [N, k, k] Vᵀ


def svd(a: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(singular values [N, k], descending; Vᵀ [N, k, k]) of a [N, r, k]: the compiled
    one-sided Jacobi SVD (:func:`ris_planner.inversion._crb_jit.svd_jacobi`), per matrix
    independent of
    the batch, so ``compute_bounds`` and the scorer agree bit for bit on every pair."""
    from ris_planner.inversion import _crb_jit

    size, _, k = a.shape
    s = np.empty((size, k))
    vt = np.empty((size, k, k))
    if size:
        _crb_jit.svd_jacobi(np.ascontiguousarray(a, dtype=np.float64), s, vt)
    return s, vt


def svd_lapack(a: FloatArray) -> tuple[FloatArray, FloatArray]:
    """:func:`svd` by LAPACK (``numpy.linalg.svd``; the route before the compiled one): the
    tests' and benchmarks' reference. Pads r < k with zero rows to get the full V."""
    size, r, k = a.shape
    if r < k:
        a = np.concatenate([a, np.zeros((size, k - r, k))], axis=1)
    _, s, vt = np.linalg.svd(a, full_matrices=False)
    return s, vt


def _sqrt_svd(a: FloatArray) -> _SqrtSVD:
    # [N, k] column norms = sqrt(F_ii)
    scale = np.sqrt(np.einsum("nrk,nrk->nk", a, a))
    zero = ~(scale > 0.0)
    safe = np.where(zero, 1.0, scale)
    s, vt = svd(a / safe[:, None, :])
    # [N, k]: null-space singular values (all of them when Â = 0)
    null = s <= SINGULAR_SV_RTOL * s[:, :1]
    null |= ~(s[:, :1] > 0.0)
    inv_s2 = np.zeros_like(s)
    np.divide(1.0, np.square(s, where=~null, out=np.ones_like(s)), where=~null, out=inv_s2)
    return _SqrtSVD(safe, zero, inv_s2, null, vt)


def sqrt_crb_diagonal(a: FloatArray) -> tuple[FloatArray, BoolArray]:
    """diag of the CRB from square-root factors a [N, r, k] (F = aᵀa on k states).

    Returns (diag [N, k], ``inf`` for states that are not identifiable; rank_deficient [N],
    the pairs whose information has a numerical null space). See the module docstring; the
    compiled kernel (:func:`ris_planner.inversion._crb_jit.sqrt_diagonal`) first tries the
    Householder
    QR Â = QR: σ_min(Â) ≥ 1/‖R⁻¹‖_F and σ_max(Â) ≤ ‖Â‖_F = √k (unit columns), so where
    :data:`QR_CERT_MARGIN` · SINGULAR_SV_RTOL · √k · ‖R⁻¹‖_F < 1 no singular value can reach the
    null-space threshold, every state is identifiable and diag = Σ_j (R⁻¹)_ij² / ‖A_:,i‖² –
    the SVD's answer, with the same ε·cond(Â) accuracy (both backward stable on Â), at a
    tenth of the cost. Elsewhere the Jacobi SVD and the leak rule decide.
    """
    from ris_planner.inversion import _crb_jit

    size, _, k = a.shape
    diag = np.empty((size, k))
    deficient = np.zeros(size, dtype=bool)
    if size:
        with parallel_kernel():
            _crb_jit.sqrt_diagonal(
                np.ascontiguousarray(a, dtype=np.float64),
                SINGULAR_SV_RTOL,
                NULL_LEAK_TOL,
                QR_CERT_MARGIN,
                diag,
                deficient,
                _crb_jit.n_tasks(),
            )
    return diag, deficient


def sqrt_crb_diagonal_svd(a: FloatArray) -> tuple[FloatArray, BoolArray]:
    """:func:`sqrt_crb_diagonal` through :func:`_sqrt_svd` in numpy on :func:`svd` (every pair
    by the SVD, no QR shortcut): the tests' reference for the compiled rule."""
    d = _sqrt_svd(a)
    v2 = np.square(d.vt)  # [N, j, i] = V_ij²
    diag = np.einsum("nj,nji->ni", d.inv_s2, v2) / np.square(d.scale)
    leak = np.einsum("nj,nji->ni", d.null.astype(float), v2)
    ident = (leak <= NULL_LEAK_TOL**2) & ~d.zero
    diag[~ident] = np.inf
    return diag, np.asarray(np.any(d.null, axis=1))


def sqrt_range_whitening(a: FloatArray) -> tuple[FloatArray, BoolArray]:
    """Whitening of the range of F = aᵀa for square-root factors a [N, r, k], by the SVD of
    the column-scaled factor Â = a·D⁻¹ = U Σ Vᵀ of :func:`sqrt_crb_diagonal`'s rule.

    Returns (W [N, k, k], kept [N, k]): rows j of W are Vᵀ_j D⁻¹/σ_j for the kept singular
    values (σ_j > :data:`SINGULAR_SV_RTOL`·σ_max) and zero on the numerical null space, so
    W_kept F W_keptᵀ = I on the kept rows. For any F' whose null space contains F's and any E
    in range(F), (W E)ᵀ (W F' Wᵀ)⁻¹ (W E) over the kept rows equals Eᵀ F'⁻ E (any generalised
    inverse; the CRB of the estimable Eᵀs), because W restricted to the kept rows maps
    range(F) one-to-one onto ℝ^r.
    """
    d = _sqrt_svd(a)
    w = np.sqrt(d.inv_s2)[:, :, None] * d.vt / d.scale[:, None, :]
    return np.asarray(w), np.asarray(~d.null)


def sqrt_crb_quadratic(a: FloatArray, w: FloatArray) -> FloatArray:
    """wᵀ F⁻ w [N] for square-root factors a [N, r, k] and combinations w [N, k] of the
    states (the CRB of wᵀs); ``inf`` where wᵀs is not identifiable (its normalised leak into
    the null space exceeds :data:`NULL_LEAK_TOL`, or it involves a state with no information).
    """
    d = _sqrt_svd(a)
    # [N, j] components of the scaled combination along V's columns
    c = np.einsum("nji,ni->nj", d.vt, w / d.scale)
    out = np.einsum("nj,nj->n", d.inv_s2, np.square(c))
    norm2 = np.einsum("nj,nj->n", c, c)
    leak = np.einsum("nj,nj->n", d.null.astype(float), np.square(c))
    bad = ~(leak <= NULL_LEAK_TOL**2 * norm2) | np.any(d.zero & (w != 0.0), axis=1)
    out[bad] = np.inf
    return np.asarray(out)


def _trace_scaled_inverse(f_packed: FloatArray, n: int, diag: FloatArray) -> FloatArray:
    """[N] trace(F̂⁻¹) = Σ_i (F⁻¹)_ii F_ii; ``inf`` or NaN where the LDLᵀ declared F singular
    (its diagonal is ``inf`` there), which the callers' ``~(trace <= limit)`` sends on."""
    idx = ldl.packed_slots(n)
    with np.errstate(invalid="ignore"):  # inf · 0 on singular pairs
        trace = diag[0] * f_packed[idx[0, 0]]
        tmp = np.empty_like(trace)
        for i in range(1, n):
            np.multiply(diag[i], f_packed[idx[i, i]], out=tmp)
            trace += tmp
    return np.asarray(trace)


def fast_diagonal(
    f_packed: FloatArray, n: int, engine: Engine = "auto"
) -> tuple[FloatArray, BoolArray, FloatArray]:
    """(diag(F⁻¹) [n, N] with ``inf`` where singular, singular [N], trace(F̂⁻¹) [N]) of packed
    matrices [n(n+1)/2, N] by the scaled LDLᵀ: numpy (:mod:`ris_planner.inversion.ldl`) or the
    compiled
    twin (:func:`ris_planner.inversion._crb_jit.inverse_diagonal`), the same bits either way;
    ``"auto"`` compiles from :data:`JIT_MIN_MATRICES` on."""
    size = f_packed.shape[1]
    if engine == "numba" or (engine == "auto" and size >= JIT_MIN_MATRICES):
        from ris_planner.inversion import _crb_jit

        diag = np.empty((n, size))
        trace = np.empty(size)
        singular = np.empty(size, dtype=bool)
        f = np.ascontiguousarray(f_packed, dtype=np.float64)
        with parallel_kernel():
            _crb_jit.inverse_diagonal(f, n, diag, trace, singular, _crb_jit.n_tasks())
        return diag, singular, trace
    diag, singular = ldl.inverse_diagonal_from(f_packed, n, 0)
    return diag, singular, _trace_scaled_inverse(f_packed, n, diag)


def crb_diagonal(
    f_packed: FloatArray,
    n: int,
    factor_rows: Callable[[IntArray], FloatArray],
    engine: Engine = "auto",
) -> tuple[FloatArray, BoolArray]:
    """diag of the CRB of N state FIMs on n unknown states, batch last (the hybrid route of
    the module docstring).

    f_packed : [n(n+1)/2, N] packed F restricted to the unknown states (:func:`ldl.pack`);
    factor_rows(idx) : the square-root factors [len(idx), r, n] of the pairs idx (called
    once, for the pairs the fast path does not settle). Returns (diag [n, N] with ``inf`` for
    non-identifiable states, rank_deficient [N]). ``engine``: the LDLᵀ's (:func:`fast_diagonal`).
    """
    return _settle(*fast_diagonal(f_packed, n, engine), factor_rows)


def _settle(
    diag: FloatArray,
    singular: BoolArray,
    trace: FloatArray,
    factor_rows: Callable[[IntArray], FloatArray],
) -> tuple[FloatArray, BoolArray]:
    """The hybrid route's second half: the matrices the LDLᵀ does not settle (singular, or a
    scaled trace above :data:`FAST_TRACE_LIMIT`) by the square-root route, in place."""
    slow = np.flatnonzero(singular | ~(trace <= FAST_TRACE_LIMIT))
    rank_deficient = np.zeros(diag.shape[1], dtype=bool)
    if slow.size:
        d_slow, rank_deficient[slow] = sqrt_crb_diagonal(factor_rows(slow))
        diag[:, slow] = d_slow.T
    return diag, rank_deficient


def summed_crb_diagonal(
    base: FloatArray,
    add: FloatArray,
    base_idx: IntArray,
    add_idx: IntArray,
    n: int,
    factor_rows: Callable[[IntArray], FloatArray],
    engine: Engine = "auto",
) -> tuple[FloatArray, BoolArray]:
    """:func:`crb_diagonal` of the packed matrices ``base[base_idx[i]] + add[add_idx[i]]`` (rows
    of two tables [·, n(n+1)/2]: a layout's information and one more path's), the same bits,
    without forming the [n(n+1)/2, N] sum when the compiled LDLᵀ runs
    (:func:`ris_planner.inversion._crb_jit.summed_inverse_diagonal`)."""
    size = base_idx.shape[0]
    if engine == "numba" or (engine == "auto" and size >= JIT_MIN_MATRICES):
        from ris_planner.inversion import _crb_jit

        diag = np.empty((n, size))
        trace = np.empty(size)
        singular = np.empty(size, dtype=bool)
        with parallel_kernel():
            _crb_jit.summed_inverse_diagonal(
                np.ascontiguousarray(base),
                np.ascontiguousarray(add),
                np.ascontiguousarray(base_idx, dtype=np.int64),
                np.ascontiguousarray(add_idx, dtype=np.int64),
                n,
                diag,
                trace,
                singular,
                _crb_jit.n_tasks(),
            )
        return _settle(diag, singular, trace, factor_rows)
    f = np.ascontiguousarray((base[base_idx] + add[add_idx]).T)
    return crb_diagonal(f, n, factor_rows, "numpy")


def quadratic_form(inv_packed: FloatArray, n: int, w: FloatArray) -> FloatArray:
    """Σ_i Σ_j w_i (F⁻¹)_ij w_j [N] from packed inverses [n(n+1)/2, N] (:func:`ldl.inverse_from`)
    and w [N, n], summed term by term in row-major (i, j) order, each term (w_i·(F⁻¹)_ij)·w_j:
    the rounding of the entry-by-entry loop, in three array operations and one reduction.
    Pairs with ``inf`` inverses (singular) give ``inf`` or NaN, silently."""
    order = ldl.packed_slots(n)
    slots = np.array([[order[i, j] for j in range(n)] for i in range(n)]).ravel()
    wt = w.T  # [n, N]
    rows = np.repeat(np.arange(n), n)
    cols = np.tile(np.arange(n), n)
    with np.errstate(invalid="ignore", over="ignore"):
        # [n², N] terms in (i, j) order, summed in that order (a reduction over the leading
        # axis accumulates sequentially)
        terms = wt[rows] * inv_packed[slots]
        terms *= wt[cols]
        return np.asarray(np.add.reduce(terms, axis=0))


def crb_quadratic(
    f_packed: FloatArray, n: int, factor_rows: Callable[[IntArray], FloatArray], w: FloatArray
) -> FloatArray:
    """wᵀ F⁻¹ w [N] for combinations w [N, n] of the states, by the same hybrid route as
    :func:`crb_diagonal` (``inf`` where wᵀs is not identifiable): the packed LDLᵀ inverse and
    :func:`quadratic_form` on the fast path, :func:`sqrt_crb_quadratic` elsewhere."""
    inv, singular = ldl.inverse_from(f_packed, n)
    idx = ldl.packed_slots(n)
    diag = np.stack([inv[idx[i, i]] for i in range(n)])
    trace = _trace_scaled_inverse(f_packed, n, diag)
    out = quadratic_form(inv, n, w)
    slow = np.flatnonzero(singular | ~(trace <= FAST_TRACE_LIMIT))
    if slow.size:
        out[slow] = sqrt_crb_quadratic(factor_rows(slow), w[slow])
    return out
