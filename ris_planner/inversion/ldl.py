"""Batched LDLᵀ of many small symmetric Fisher matrices: the single inversion routine of the
engine (bounds, power allocation and layout scoring all go through it).

Matrices are stored packed and batch-last: one contiguous vector over the batch per
lower-triangle entry (row-major, i ≥ j), so every step of the factorisation is one vector
operation over all pairs (or all layout-pair combinations), and buffers are reused.

The factorisation F = L D Lᵀ is left-looking and keeps the products U_ij = L_ij D_j of the
entries below the diagonal: column j is U_ij = F_ij − Σ_{k<j} U_ik L_jk (i > j), with the pivot
D_j = F_jj − Σ_{k<j} U_jk² / D_k and row j of L, L_jk = U_jk / D_k, formed as soon as 1/D_k is
known. A pivot thus waits for one product and one subtraction after the previous division; that
chain is what bounds the compiled kernels (docs/concepts/scoring.md, "The pivot chain").

No equilibration is applied: scaling F symmetrically by powers of two would change no rounding
at all (every intermediate is scaled exactly), and a scaling by √F_ii only reorders roundings of
the same size (the accuracy tests against mpmath hold either way). Only magnitudes beyond
~1e150, far from any information in 1/m², could overflow U_jk²; a pivot that overflows is NaN
or −∞ and is declared singular (the square-root route then decides). A matrix is singular (a
blind spot) when a diagonal entry is not positive or a pivot D_j ≤ :data:`SINGULAR_RCOND` ·
F_jj: the pivot of F scaled to unit diagonal is D_j / F_jj, so this is "a pivot of the
unit-diagonal matrix below 1e-12". A kept pivot is positive: while the earlier ones are,
D_j ≤ F_jj, so D_j > 1e-12 · F_jj needs F_jj > 0 (the explicit test of the diagonal states the
rule; it never decides alone).

diag(F⁻¹)_i = Σ_{k≥i} (L⁻¹)_{ki}² / D_k needs only the columns ≥ i of L⁻¹, so
:func:`inverse_diagonal_from` forms just the columns the wanted entries need; layout scoring
asks for the p_R (or p_T) block only. Because the core and the planner call the same code, a
cached layout score equals ``compute_bounds`` bit for bit even for near-blind pairs (scaled
condition numbers up to ~1e11, where another rounding order moves a bound by ~1e-6).
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import cache
from types import MappingProxyType
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

SINGULAR_RCOND = 1e-12
"""A Fisher matrix is singular when a pivot of its LDLᵀ factorisation is ≤ this fraction of
its diagonal entry, D_j ≤ 1e-12 · F_jj: D_j / F_jj is the pivot of the matrix scaled to unit
diagonal, and every such pivot is ≥ λ_min of the scaled matrix, so a pivot this small means
cond ≥ 1e12: the inverse would be dominated by rounding (float64 ε ≈ 2.2e-16 times a 7×7
accumulation leaves ≥ 3 orders of margin)."""


def packed_index(n: int) -> dict[tuple[int, int], int]:
    """Position of entry (i, j) in the row-major lower-triangle packing (i ≥ j) of an n×n
    symmetric matrix; (j, i) maps to the same slot."""
    out: dict[tuple[int, int], int] = {}
    e = 0
    for i in range(n):
        for j in range(i + 1):
            out[(i, j)] = out[(j, i)] = e
            e += 1
    return out


@cache
def packed_slots(n: int) -> Mapping[tuple[int, int], int]:
    """:func:`packed_index` computed once per n, read-only (the per-call loops use it)."""
    return MappingProxyType(packed_index(n))


@cache
def _tril(n: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    il = np.tril_indices(n)
    il[0].flags.writeable = False
    il[1].flags.writeable = False
    return il[0], il[1]


def pack(f: FloatArray) -> FloatArray:
    """[..., n, n] → [n(n+1)/2, ...] lower triangle (i ≥ j), entry axis first."""
    n = f.shape[-1]
    il = _tril(n)
    return np.ascontiguousarray(np.moveaxis(f[..., il[0], il[1]], -1, 0))


def unpack(p: FloatArray, n: int) -> FloatArray:
    """[n(n+1)/2, ...] packed → [..., n, n] symmetric (lower triangle mirrored)."""
    il = _tril(n)
    out = np.empty((*p.shape[1:], n, n))
    vals = np.moveaxis(p, 0, -1)
    out[..., il[0], il[1]] = vals
    out[..., il[1], il[0]] = vals
    return out


class _Factor(NamedTuple):
    """The factorisation of packed matrices, batch last (see module docstring)."""

    low: FloatArray  # [n(n+1)/2, N]: L_ij in the packed slot of (i, j), i > j
    inv_piv: FloatArray  # [n, N]: 1 / D_j (pivots of singular matrices replaced by 1)
    singular: NDArray[np.bool_]  # [N]
    m: FloatArray  # [n(n+1)/2, N] workspace for the columns of L⁻¹
    tmp: FloatArray  # [N] scratch


def _factor(f: FloatArray, n: int) -> _Factor:
    """LDLᵀ of packed symmetric matrices f [n(n+1)/2, N] (left-looking, the products
    U_ij = L_ij D_j kept: see the module docstring)."""
    idx = packed_slots(n)
    size = f.shape[1]
    n_tri = n * (n + 1) // 2
    # one workspace: U = L·D (later L⁻¹), L, inverse pivots, scratch
    work = np.empty((2 * n_tri + n + 2, size))
    u, low = work[:n_tri], work[n_tri : 2 * n_tri]
    inv_piv = work[2 * n_tri : 2 * n_tri + n]
    tmp, pj = work[-2], work[-1]
    singular = np.zeros(size, dtype=bool)
    for j in range(n):
        fjj = f[idx[j, j]]
        singular |= ~(fjj > 0.0)
        np.copyto(pj, fjj)
        for k in range(j):
            np.square(u[idx[j, k]], out=tmp)
            tmp *= inv_piv[k]
            pj -= tmp
        np.multiply(fjj, SINGULAR_RCOND, out=tmp)
        bad = ~(pj > tmp)
        singular |= bad
        pj[bad] = 1.0
        np.divide(1.0, pj, out=inv_piv[j])
        for k in range(j):
            np.multiply(u[idx[j, k]], inv_piv[k], out=low[idx[j, k]])
        for i in range(j + 1, n):
            uij = u[idx[i, j]]
            np.copyto(uij, f[idx[i, j]])
            for k in range(j):
                np.multiply(u[idx[i, k]], low[idx[j, k]], out=tmp)
                uij -= tmp
    return _Factor(low, inv_piv, singular, u, tmp)


def _inverse_low_columns(fac: _Factor, n: int, first: int) -> None:
    """Columns j ≥ first of M = L⁻¹ (unit lower triangular, M_ii = 1 implicit) into fac.m by
    forward substitution."""
    idx = packed_slots(n)
    m, low, tmp = fac.m, fac.low, fac.tmp
    for i in range(first, n):
        for j in range(first, i):
            acc = m[idx[i, j]]
            np.negative(low[idx[i, j]], out=acc)
            for k in range(j + 1, i):
                np.multiply(low[idx[i, k]], m[idx[k, j]], out=tmp)
                acc -= tmp


SCALAR_MAX_BATCH = 8
"""Up to this many matrices, :func:`inverse_diagonal_from` and :func:`inverse_from` run the
same operations on Python floats, one matrix at a time (:func:`_scalar_factor`): a single
pair's 7×7 LDLᵀ is ~150 vector operations of length one, each costing a numpy call (~1 µs),
against ~20 µs for the whole matrix on floats. Python's float +, −, ×, ÷ and ``math.sqrt``
are the IEEE-754 operations numpy applies elementwise, so both routes give the same bits
(tests/test_ldl.py checks them against each other)."""


def _scalar_route(f: FloatArray) -> bool:
    """Small finite batches take the float route (non-finite entries keep numpy's
    propagation rules, and a zero product of scales keeps numpy's division by zero)."""
    return f.shape[1] <= SCALAR_MAX_BATCH and bool(np.isfinite(f).all())


class _ScalarFactor(NamedTuple):
    """:class:`_Factor` of one matrix on Python floats: M = L⁻¹ (columns ≥ first filled)."""

    m: list[float]
    inv_piv: list[float]
    singular: bool


def _scalar_factor(f: list[float], n: int, first: int) -> _ScalarFactor:
    """:func:`_factor` then :func:`_inverse_low_columns` of one packed matrix, operation by
    operation in the same order. Raises ZeroDivisionError where numpy would divide by 0 (no
    divisor here can be 0: kept for the contract of the float route)."""
    idx = packed_slots(n)
    singular = False
    u = [0.0] * len(f)
    low = [0.0] * len(f)
    inv_piv = [0.0] * n
    for j in range(n):
        fjj = f[idx[j, j]]
        singular = singular or not fjj > 0.0
        pj = fjj
        for k in range(j):
            pj -= (u[idx[j, k]] * u[idx[j, k]]) * inv_piv[k]
        bad = not pj > fjj * SINGULAR_RCOND
        singular = singular or bad
        inv_piv[j] = 1.0 / (1.0 if bad else pj)
        for k in range(j):
            low[idx[j, k]] = u[idx[j, k]] * inv_piv[k]
        for i in range(j + 1, n):
            uij = f[idx[i, j]]
            for k in range(j):
                uij -= u[idx[i, k]] * low[idx[j, k]]
            u[idx[i, j]] = uij
    m = u  # U's storage holds L⁻¹ from here on, as in _factor
    for i in range(first, n):
        for j in range(first, i):
            acc = -low[idx[i, j]]
            for k in range(j + 1, i):
                acc -= low[idx[i, k]] * m[idx[k, j]]
            m[idx[i, j]] = acc
    return _ScalarFactor(m, inv_piv, singular)


def _scalar_inverse_diagonal(
    f: FloatArray, n: int, first: int
) -> tuple[FloatArray, NDArray[np.bool_]]:
    idx = packed_slots(n)
    out = np.empty((n - first, f.shape[1]))
    singular = np.zeros(f.shape[1], dtype=bool)
    for b, col in enumerate(f.T.tolist()):
        fac = _scalar_factor(col, n, first)
        m, inv_piv = fac.m, fac.inv_piv
        for i in range(first, n):
            acc = inv_piv[i]
            for k in range(i + 1, n):
                acc += (m[idx[k, i]] * m[idx[k, i]]) * inv_piv[k]
            out[i - first, b] = acc
        singular[b] = fac.singular
    out[:, singular] = np.inf
    return out, singular


def _scalar_inverse(f: FloatArray, n: int) -> tuple[FloatArray, NDArray[np.bool_]]:
    idx = packed_slots(n)
    out = np.empty_like(f)
    singular = np.zeros(f.shape[1], dtype=bool)
    for b, col in enumerate(f.T.tolist()):
        fac = _scalar_factor(col, n, 0)
        m, inv_piv = fac.m, fac.inv_piv
        for i in range(n):
            for j in range(i + 1):
                acc = 0.0
                for k in range(i, n):
                    mki = 1.0 if k == i else m[idx[k, i]]
                    mkj = 1.0 if k == j else m[idx[k, j]]
                    acc += (mki * mkj) * inv_piv[k]
                out[idx[i, j], b] = acc
        singular[b] = fac.singular
    out[:, singular] = np.inf
    return out, singular


def inverse_diagonal_from(
    f: FloatArray, n: int, first: int = 0
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """diag(F⁻¹) of states first … n−1 of packed symmetric matrices, ``inf`` where singular.

    f : [n(n+1)/2, N] packed (lower triangle). Returns (diag [n − first, N], singular [N]).
    Small batches run on floats (:data:`SCALAR_MAX_BATCH`), with the same bits.
    """
    if _scalar_route(f):
        try:
            return _scalar_inverse_diagonal(f, n, first)
        except ZeroDivisionError:
            pass
    idx = packed_slots(n)
    fac = _factor(f, n)
    _inverse_low_columns(fac, n, first)
    m, inv_piv, tmp = fac.m, fac.inv_piv, fac.tmp
    out = np.empty((n - first, f.shape[1]))
    for i in range(first, n):
        acc = out[i - first]
        np.copyto(acc, inv_piv[i])  # M_ii² / D_i with M_ii = 1
        for k in range(i + 1, n):
            np.square(m[idx[k, i]], out=tmp)
            tmp *= inv_piv[k]
            acc += tmp
    out[:, fac.singular] = np.inf
    return out, fac.singular


def inverse_from(f: FloatArray, n: int) -> tuple[FloatArray, NDArray[np.bool_]]:
    """F⁻¹ of packed symmetric matrices, packed the same way; ``inf`` where singular.

    f : [n(n+1)/2, N]. (F⁻¹)_ij = Σ_{k ≥ max(i,j)} M_ki M_kj / D_k with M = L⁻¹.
    Small batches run on floats (:data:`SCALAR_MAX_BATCH`), with the same bits.
    """
    if _scalar_route(f):
        try:
            return _scalar_inverse(f, n)
        except ZeroDivisionError:
            pass
    idx = packed_slots(n)
    fac = _factor(f, n)
    _inverse_low_columns(fac, n, 0)
    m, inv_piv, tmp = fac.m, fac.inv_piv, fac.tmp

    def m_entry(k: int, i: int) -> FloatArray | float:
        return 1.0 if k == i else m[idx[k, i]]

    out = np.empty_like(f)
    for i in range(n):
        for j in range(i + 1):
            acc = out[idx[i, j]]
            acc[:] = 0.0
            for k in range(i, n):
                np.multiply(m_entry(k, i), m_entry(k, j), out=tmp)
                tmp *= inv_piv[k]
                acc += tmp
    out[:, fac.singular] = np.inf
    return out, fac.singular


def ldl_flops(n: int) -> dict[str, int]:
    """Floating-point operations of one n × n matrix through the LDLᵀ and the inverse's
    diagonal and trace as :func:`inverse_diagonal_from` (``first=0``) and the compiled kernels
    (:mod:`ris_planner.inversion._crb_jit`) perform them, step by step: every +, −, ×, ÷ and √
    counts one; comparisons, selections and sign flips (−L_ij) count none. Per column j:

    * ``factor`` – the pivot, 3j + 1 (each U_jk² / D_k as a square, a product by 1/D_k and a
      subtraction; the threshold SINGULAR_RCOND · F_jj), row j of L, j products U_jk · (1/D_k),
      and 2j for each of the n − 1 − j entries U_ij below the pivot: Σ_j [4j + 1 + 2j(n−1−j)];
    * ``inverse`` – 1/D_j and the columns of L⁻¹ by forward substitution: n + Σ_{i>j} 2(i−j−1);
    * ``diagonal`` – 1/D_i + Σ_{k>i} M_ki² / D_k (a square, a product, an addition): 3·n(n−1)/2;
    * ``trace`` – Σ_i diag_i F_ii: 2n − 1.

    n = 7: 161 + 77 + 63 + 13 = 314, of them 7 divisions (1/D_j: every other quotient is a
    product by one of them) and no square root."""
    return {
        "factor": sum(4 * j + 1 + 2 * j * (n - 1 - j) for j in range(n)),
        "inverse": n + sum(2 * (i - j - 1) for i in range(n) for j in range(i)),
        "diagonal": 3 * n * (n - 1) // 2,
        "trace": 2 * n - 1,
    }
