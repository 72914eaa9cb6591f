"""Batched inverse diagonal of many small symmetric Fisher matrices in packed storage.

A layout's information on [p_T, p_R, B] is a sum of cached per-site 7×7 matrices (DESIGN.md,
performance model), and scoring thousands of layouts over thousands of pairs means inverting
millions of 7×7 matrices. The core's :func:`ris_planner.bounds.fim_inverse_diagonal` does this
for [P, n, n] stacks; here the matrices are already batch-last and packed (one contiguous vector
per lower-triangle entry, the entries the core's factorisation reads), buffers are reused, and
only the columns of L⁻¹ that the wanted diagonal entries need are formed
(F = L D Lᵀ, diag(F⁻¹)_i = Σ_{k≥i} (L⁻¹)_{ki}² / D_k needs columns ≥ i only).

The arithmetic is the core's, operation for operation (unit-diagonal scaling, left-looking
LDLᵀ, the same pivot rule :data:`ris_planner.bounds.SINGULAR_RCOND`, the same order of every
sum), so a cached layout score is bit-for-bit the bound ``compute_bounds`` reports. That
matters: the state FIMs of near-blind pairs have scaled condition numbers up to ~1e11, where
any other rounding order moves the bounds by ~1e-6 relative.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ris_planner.bounds import SINGULAR_RCOND

FloatArray = NDArray[np.float64]


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


def pack(f: FloatArray) -> FloatArray:
    """[..., n, n] → [n(n+1)/2, ...] lower triangle (i ≥ j), entry axis first."""
    n = f.shape[-1]
    il = np.tril_indices(n)
    return np.ascontiguousarray(np.moveaxis(f[..., il[0], il[1]], -1, 0))


def unpack(p: FloatArray, n: int) -> FloatArray:
    """[n(n+1)/2, ...] packed → [..., n, n] symmetric (lower triangle mirrored)."""
    il = np.tril_indices(n)
    out = np.empty((*p.shape[1:], n, n))
    vals = np.moveaxis(p, 0, -1)
    out[..., il[0], il[1]] = vals
    out[..., il[1], il[0]] = vals
    return out


def inverse_diagonal_from(
    f: FloatArray, n: int, first: int
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """diag(F⁻¹) of states first … n−1 of packed symmetric matrices, ``inf`` where singular.

    f : [n(n+1)/2, N] packed (lower triangle). Returns (diag [n − first, N], singular [N]),
    equal bit for bit to ``fim_inverse_diagonal(unpack(f))[0][:, first:]``.
    """
    idx = packed_index(n)
    size = f.shape[1]
    n_tri = n * (n + 1) // 2
    # one workspace: scaled entries, L, pivots, L·D products, M = L⁻¹ columns, scratch
    work = np.empty((2 * n_tri + 3 * n + 2, size))
    a, low = work[:n_tri], work[n_tri : 2 * n_tri]
    piv, ld, d_safe = (work[2 * n_tri + k * n : 2 * n_tri + (k + 1) * n] for k in range(3))
    tmp, tmp2 = work[-2], work[-1]
    d = np.stack([f[idx[j, j]] for j in range(n)])
    np.clip(d, 0.0, None, out=d)
    np.sqrt(d, out=d)
    singular = np.any(d <= 0.0, axis=0)
    np.copyto(d_safe, d)
    d_safe[d <= 0.0] = 1.0
    for i in range(n):
        for j in range(i + 1):
            np.multiply(d_safe[i], d_safe[j], out=tmp)
            np.divide(f[idx[i, j]], tmp, out=a[idx[i, j]])
    for j in range(n):
        for k in range(j):
            np.multiply(low[idx[j, k]], piv[k], out=ld[k])
        pj = tmp2
        np.copyto(pj, a[idx[j, j]])
        for k in range(j):
            np.multiply(low[idx[j, k]], ld[k], out=tmp)
            pj -= tmp
        bad = ~(pj > SINGULAR_RCOND)
        singular |= bad
        np.copyto(piv[j], pj)
        piv[j][bad] = 1.0
        for i in range(j + 1, n):
            lij = low[idx[i, j]]
            np.copyto(lij, a[idx[i, j]])
            for k in range(j):
                np.multiply(low[idx[i, k]], ld[k], out=tmp)
                lij -= tmp
            lij /= piv[j]
    inv_piv = np.divide(1.0, piv, out=piv)
    # columns j ≥ first of M = L⁻¹ (unit lower triangular), the core's recurrence; M reuses a
    m = a
    for i in range(first, n):
        for j in range(first, i):
            acc = m[idx[i, j]]
            np.negative(low[idx[i, j]], out=acc)
            for k in range(j + 1, i):
                np.multiply(low[idx[i, k]], m[idx[k, j]], out=tmp)
                acc -= tmp
    out = np.empty((n - first, size))
    for i in range(first, n):
        acc = out[i - first]
        np.copyto(acc, inv_piv[i])  # M_ii² / D_i with M_ii = 1
        for k in range(i + 1, n):
            np.square(m[idx[k, i]], out=tmp)
            tmp *= inv_piv[k]
            acc += tmp
        np.square(d_safe[i], out=tmp)
        acc /= tmp
    out[:, singular] = np.inf
    return out, singular
