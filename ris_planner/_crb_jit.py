"""The compiled inversion kernels (numba): the scaled LDLᵀ of :mod:`ris_planner.ldl` one chunk
of matrices at a time, the planning layout score built on it, and the one-sided Jacobi SVD of
the square-root route of :mod:`ris_planner.crb`. One module, because numba's on-disk cache of a
function does not notice edits to the functions it calls from another file.

**LDLᵀ, bit for bit.** :func:`ldl_chunk` performs the very operations of
:func:`ris_planner.ldl._factor`, :func:`~ris_planner.ldl._inverse_low_columns` and
:func:`~ris_planner.ldl.inverse_diagonal_from` (and of ``crb._trace_scaled_inverse``), in the
same order, entry by entry (a quotient stays a quotient: the channel bounds, which go through
ldl.py, are pinned bit for bit by the free-space tests), and no multiply-add is fused (numba
leaves LLVM's floating-point contraction off unless ``fastmath`` is asked for). IEEE-754
rounds every +, −, ×, ÷ and √ exactly, so the compiled and the numpy routine give identical
bits (tested on random, ill-conditioned and singular batches): ``crb.crb_diagonal`` may take
either by batch size, and the planning scorer still equals ``compute_bounds`` bit for bit. The
chunk is batch-last ([entries, CHUNK]) so every step is a short loop over contiguous values that
LLVM vectorises (``error_model="numpy"``: a Python-style zero-division check in the loops would
stop it), with the workspace in the L1 cache.

**Layout score.** :func:`score_layouts` fuses, per (layout, pair), the gather-and-add of the
cached packed information, :func:`ldl_chunk`, the fast-path test of ``crb_diagonal`` and the
metric, so the sums never leave the cache. The sum is the core's: LOS + RIS 1, then + RIS 2, …
in the layout's column order (``compute_bounds`` sums its paths in that order); the metric is
``sqrt`` of the summed diagonal entries in state order (``diag[:, cols].sum(axis=1)``) and
``np.maximum`` of PEB_T and PEB_R. Pairs that are ``inf`` anyway (a UE on a chosen site, or
fewer present channel parameters than unknown states: ``objectives.underdetermined``) are
settled first and neither summed nor factored; the pairs the fast path does not settle are
flagged for the square-root route, which the caller runs. It reads the site cache's own
storage, pair blocks [⌈P/CHUNK⌉, S, 28, CHUNK] (the kept entries through an index; no copy):
one block holds every site's entries of CHUNK pairs contiguously (≈ 2 MB for 156 sites), so it
stays in the cache while all the layouts of a call are scored on it, in parallel over blocks.
Summing straight from the [28, S, P] cache, whose rows of one pair block lie 51 KB (sites) and
8 MB (entries) apart, ran 3–6× slower (measured: ~110 ns per matrix for the gather alone,
against ~20 ns from the blocks).

**Jacobi SVD.** :func:`svd_jacobi` is the one-sided (Hestenes) Jacobi method on the columns of
each [r, k] matrix, the right rotations accumulated in V; it is the only SVD of the square-root
route (``compute_bounds`` and the scorer both call it, so they agree bit for bit there too).
Working on the columns of the column-scaled factor Â directly, it computes every singular value
to ~ε·cond(Â) relative accuracy (Demmel & Veselić 1992) – as good as LAPACK's bidiagonal route
that ``numpy.linalg.svd`` took before (the tests compare both, and mpmath).

Imported lazily (numba takes ~1 s to import; compiled code is cached next to this file).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from ris_planner.allocator import ensure_numba_cache
from ris_planner.ldl import SINGULAR_RCOND

ensure_numba_cache(__file__)  # before any @njit(cache=True): a writable cache folder

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]
UInt8Array = NDArray[np.uint8]

CHUNK = 64
"""Matrices per kernel step (batch-last workspace of ~90 rows × CHUNK float64 ≈ 45 KB: the L1/L2
cache of one core; measured on the 2-core dev machine, 32–128 are within 10 %)."""

TASKS_PER_THREAD = 4
"""Parallel kernels split their chunks into ``n_tasks`` contiguous runs, this many per thread
(:func:`n_tasks`; each run allocates its workspace once; several per thread balance a core
slowed by other load)."""


def n_tasks() -> int:
    """The ``n_tasks`` argument of the parallel kernels for numba's current thread count."""
    return TASKS_PER_THREAD * int(numba.get_num_threads())


JACOBI_TOL = 1e-15
"""A column pair (i, j) counts as orthogonal when |⟨a_i, a_j⟩| ≤ this · ‖a_i‖‖a_j‖ (≈ 4.5 ε,
the convergence test of LAPACK's dgesvj with its √m·ε for the ≤ 13 rows here). The singular
values are then accurate to a few ε·cond(Â) (relative), as in Demmel & Veselić."""

JACOBI_MAX_SWEEPS = 40
"""Cyclic sweeps at most; the method converges quadratically and takes 5–9 sweeps on the
7-column factors here (never more than 12 in the tests), so this only stops a pathological
input from looping."""


@njit(cache=True, nogil=True, error_model="numpy")
def _tri(i: int, j: int) -> int:
    """Packed slot of entry (i, j), i ≥ j (:func:`ris_planner.ldl.packed_index`)."""
    return i * (i + 1) // 2 + j


@njit(cache=True, nogil=True, error_model="numpy")
def ldl_chunk(
    a: FloatArray,
    n: int,
    t: int,
    work: FloatArray,
    diag: FloatArray,
    trace: FloatArray,
    singular: BoolArray,
) -> None:
    """diag(F⁻¹) [n, :t], trace(F̂⁻¹) [:t] and the singular flags [:t] of the packed matrices
    in the first t columns of a [n(n+1)/2, CHUNK] (overwritten: the scaled entries, then the
    columns of L⁻¹). ``work`` [:func:`work_rows`, CHUNK] is scratch. Diagonal and trace are
    ``inf`` / undefined where singular (numpy: ``inf`` diagonal, a NaN or ``inf`` trace), which
    the callers send to the square-root route; elsewhere bit for bit what ldl.py gives."""
    e_n = n * (n + 1) // 2
    low = work[:e_n]
    d = work[e_n : e_n + n]  # d_i
    piv = work[e_n + n : e_n + 2 * n]  # D_j, then 1 / D_j
    ld = work[e_n + 2 * n : e_n + 3 * n]
    fdiag = work[e_n + 3 * n : e_n + 4 * n]
    bad = work[e_n + 4 * n]  # 1.0 where singular (a float row: branch-free vector loops)
    for q in range(t):
        bad[q] = 0.0
    # d_i = sqrt(max(F_ii, 0)); a zero scale is singular and replaced by 1
    for i in range(n):
        ii = _tri(i, i)
        for q in range(t):
            v = a[ii, q]
            fdiag[i, q] = v
            s = math.sqrt(v if v >= 0.0 or v != v else 0.0)
            zero = s <= 0.0
            bad[q] = 1.0 if zero else bad[q]
            d[i, q] = 1.0 if zero else s
    for i in range(n):
        for j in range(i + 1):
            ij = _tri(i, j)
            for q in range(t):
                a[ij, q] = a[ij, q] / (d[i, q] * d[j, q])
    # left-looking LDLᵀ: pivot D_j, then column j of L (each entry's subtractions in k order)
    for j in range(n):
        for k in range(j):
            jk = _tri(j, k)
            for q in range(t):
                ld[k, q] = low[jk, q] * piv[k, q]
        jj = _tri(j, j)
        pj = ld[j]  # scratch: row j of ld is written at step j + 1
        for q in range(t):
            pj[q] = a[jj, q]
        for k in range(j):
            jk = _tri(j, k)
            for q in range(t):
                pj[q] -= low[jk, q] * ld[k, q]
        for q in range(t):
            ok = pj[q] > SINGULAR_RCOND
            bad[q] = bad[q] if ok else 1.0
            piv[j, q] = pj[q] if ok else 1.0
        for i in range(j + 1, n):
            ij = _tri(i, j)
            lij = low[ij]
            for q in range(t):
                lij[q] = a[ij, q]
            for k in range(j):
                ik = _tri(i, k)
                for q in range(t):
                    lij[q] -= low[ik, q] * ld[k, q]
            for q in range(t):
                lij[q] /= piv[j, q]
    for j in range(n):
        for q in range(t):
            piv[j, q] = 1.0 / piv[j, q]
    # M = L⁻¹ below the diagonal, into a (forward substitution, as ldl.py)
    for i in range(n):
        for j in range(i):
            ij = _tri(i, j)
            acc = a[ij]
            for q in range(t):
                acc[q] = -low[ij, q]
            for k in range(j + 1, i):
                ik = _tri(i, k)
                kj = _tri(k, j)
                for q in range(t):
                    acc[q] -= low[ik, q] * a[kj, q]
    # diag_i = (1/D_i + Σ_{k>i} M_ki² / D_k) / d_i², trace = Σ_i diag_i F_ii
    for i in range(n):
        acc = diag[i]
        for q in range(t):
            acc[q] = piv[i, q]
        for k in range(i + 1, n):
            ki = _tri(k, i)
            for q in range(t):
                m = a[ki, q]
                acc[q] += (m * m) * piv[k, q]
        for q in range(t):
            acc[q] /= d[i, q] * d[i, q]
    for q in range(t):
        trace[q] = diag[0, q] * fdiag[0, q]
    for i in range(1, n):
        for q in range(t):
            trace[q] += diag[i, q] * fdiag[i, q]
    for q in range(t):
        singular[q] = bad[q] != 0.0
    for i in range(n):
        for q in range(t):
            diag[i, q] = math.inf if singular[q] else diag[i, q]


@njit(cache=True, nogil=True, error_model="numpy")
def work_rows(n: int) -> int:
    """Rows of :func:`ldl_chunk`'s scratch for n states."""
    return n * (n + 1) // 2 + 4 * n + 1


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def inverse_diagonal(
    f: FloatArray,
    n: int,
    diag: FloatArray,
    trace: FloatArray,
    singular: BoolArray,
    n_tasks: int,
) -> None:
    """diag(F⁻¹) [n, N], trace(F̂⁻¹) [N] and singular [N] of packed matrices f [n(n+1)/2, N]
    (:func:`ris_planner.ldl.inverse_diagonal_from` with ``first=0`` and
    ``crb._trace_scaled_inverse``, bit for bit)."""
    e_n = n * (n + 1) // 2
    size = f.shape[1]
    n_chunks = (size + CHUNK - 1) // CHUNK
    n_tasks = min(n_chunks, max(1, n_tasks))
    for task in prange(n_tasks):
        a = np.empty((e_n, CHUNK))
        work = np.empty((work_rows(n), CHUNK))
        dg = np.empty((n, CHUNK))
        tr = np.empty(CHUNK)
        sg = np.empty(CHUNK, dtype=np.bool_)
        for c in range(task * n_chunks // n_tasks, (task + 1) * n_chunks // n_tasks):
            p0 = c * CHUNK
            t = min(CHUNK, size - p0)
            for e in range(e_n):
                for q in range(t):
                    a[e, q] = f[e, p0 + q]
            ldl_chunk(a, n, t, work, dg, tr, sg)
            for i in range(n):
                for q in range(t):
                    diag[i, p0 + q] = dg[i, q]
            for q in range(t):
                trace[p0 + q] = tr[q]
                singular[p0 + q] = sg[q]


@njit(cache=True, nogil=True, error_model="numpy")
def _jacobi_one(u: FloatArray, v: FloatArray, s: FloatArray) -> None:
    """One-sided Jacobi on the columns of u [r, k] (overwritten by U·Σ), v [k, k] := V,
    s [k] := Σ, unsorted. Pair (i, j) is rotated unless ⟨u_i, u_j⟩² ≤ JACOBI_TOL²‖u_i‖²‖u_j‖²
    (the squared test: no square roots per pair)."""
    r, k = u.shape
    tol2 = JACOBI_TOL * JACOBI_TOL
    for i in range(k):
        for j in range(k):
            v[i, j] = 1.0 if i == j else 0.0
    for _ in range(JACOBI_MAX_SWEEPS):
        rotated = False
        for i in range(k - 1):
            for j in range(i + 1, k):
                alpha = 0.0
                beta = 0.0
                gamma = 0.0
                for x in range(r):
                    ui = u[x, i]
                    uj = u[x, j]
                    alpha += ui * ui
                    beta += uj * uj
                    gamma += ui * uj
                if gamma * gamma <= tol2 * alpha * beta:
                    continue
                rotated = True
                zeta = (beta - alpha) / (2.0 * gamma)
                if abs(zeta) > 1e150:
                    tan = 0.5 / zeta
                else:
                    tan = math.copysign(1.0, zeta) / (abs(zeta) + math.sqrt(1.0 + zeta * zeta))
                cos = 1.0 / math.sqrt(1.0 + tan * tan)
                sin = cos * tan
                for x in range(r):
                    ui = u[x, i]
                    uj = u[x, j]
                    u[x, i] = cos * ui - sin * uj
                    u[x, j] = sin * ui + cos * uj
                for x in range(k):
                    vi = v[x, i]
                    vj = v[x, j]
                    v[x, i] = cos * vi - sin * vj
                    v[x, j] = sin * vi + cos * vj
        if not rotated:
            break
    for j in range(k):
        acc = 0.0
        for x in range(r):
            acc += u[x, j] * u[x, j]
        s[j] = math.sqrt(acc)


@njit(cache=True, nogil=True, error_model="numpy")
def svd_jacobi(a: FloatArray, s_out: FloatArray, vt_out: FloatArray) -> None:
    """Singular values s_out [N, k] (descending) and Vᵀ vt_out [N, k, k] (row j = the right
    singular vector of s_j, as ``numpy.linalg.svd``) of each a [N, r, k]; any r ≥ 1. Serial:
    only the CEB's combination (``crb.sqrt_crb_quadratic``) and the tests call it, on few
    pairs (a parallel kernel takes several times longer to compile)."""
    size, r, k = a.shape
    u = np.empty((r, k))
    v = np.empty((k, k))
    s = np.empty(k)
    for m in range(size):
        u[:, :] = a[m]
        _jacobi_one(u, v, s)
        used = np.zeros(k, dtype=np.bool_)
        for j in range(k):  # selection by descending σ (stable: the first of equals)
            best = -1
            for c in range(k):
                if not used[c] and (best < 0 or s[c] > s[best]):
                    best = c
            used[best] = True
            s_out[m, j] = s[best]
            for i in range(k):
                vt_out[m, j, i] = v[i, best]


@njit(cache=True, nogil=True, error_model="numpy")
def _qr_inverse_rows(u: FloatArray, rinv: FloatArray, work: FloatArray) -> float:
    """Householder QR of u [r, k] (r ≥ k, overwritten) and R⁻¹ into rinv [k, k] (upper);
    returns ‖R⁻¹‖_F, or ``inf`` when a diagonal entry of R is zero. work : [r] scratch."""
    r, k = u.shape
    for j in range(k):
        norm2 = 0.0
        for x in range(j, r):
            norm2 += u[x, j] * u[x, j]
        norm = math.sqrt(norm2)
        if norm == 0.0:
            return math.inf
        alpha = -norm if u[j, j] >= 0.0 else norm  # R_jj; v = u_j − alpha e_j
        for x in range(j, r):
            work[x] = u[x, j]
        work[j] -= alpha
        vnorm2 = norm2 - u[j, j] * u[j, j] + work[j] * work[j]
        u[j, j] = alpha
        for x in range(j + 1, r):
            u[x, j] = 0.0
        if vnorm2 > 0.0:
            for c in range(j + 1, k):
                dot = 0.0
                for x in range(j, r):
                    dot += work[x] * u[x, c]
                f = 2.0 * dot / vnorm2
                for x in range(j, r):
                    u[x, c] -= f * work[x]
    fro2 = 0.0
    for i in range(k - 1, -1, -1):  # back substitution, row by row of R⁻¹
        for j in range(k):
            rinv[i, j] = 0.0
        rinv[i, i] = 1.0 / u[i, i]
        for j in range(i + 1, k):
            acc = 0.0
            for c in range(i + 1, j + 1):
                acc += u[i, c] * rinv[c, j]
            rinv[i, j] = -acc / u[i, i]
        for j in range(i, k):
            fro2 += rinv[i, j] * rinv[i, j]
    return math.sqrt(fro2)


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def sqrt_diagonal(
    a: FloatArray,
    sv_rtol: float,
    leak_tol: float,
    qr_margin: float,
    diag: FloatArray,
    deficient: BoolArray,
    n_tasks: int,
) -> None:
    """The CRB diagonal diag [N, k] (``inf`` where not identifiable) and rank_deficient [N]
    of square-root factors a [N, r, k] by the rule of :func:`ris_planner.crb.sqrt_crb_diagonal`
    (its docstring): a certified QR where no singular value can be near the null-space
    threshold, the Jacobi SVD and the leak rule elsewhere."""
    size, r, k = a.shape
    n_tasks = min(size, max(1, n_tasks))
    for task in prange(n_tasks):
        u = np.empty((r, k))
        v = np.empty((k, k))
        s = np.empty(k)
        rinv = np.empty((k, k))
        work = np.empty(r)
        scale = np.empty(k)
        zero = np.empty(k, dtype=np.bool_)
        for m in range(task * size // n_tasks, (task + 1) * size // n_tasks):
            any_zero = False
            for i in range(k):
                acc = 0.0
                for x in range(r):
                    acc += a[m, x, i] * a[m, x, i]
                sc = math.sqrt(acc)
                zero[i] = not (sc > 0.0)
                any_zero |= zero[i]
                scale[i] = 1.0 if zero[i] else sc
            if r >= k and not any_zero:
                for x in range(r):
                    for i in range(k):
                        u[x, i] = a[m, x, i] / scale[i]
                fro = _qr_inverse_rows(u, rinv, work)
                # σ_min(Â) ≥ 1/‖R⁻¹‖_F and σ_max(Â) ≤ ‖Â‖_F = √k (unit columns)
                if qr_margin * sv_rtol * math.sqrt(k) * fro < 1.0:
                    for i in range(k):
                        acc = 0.0
                        for j in range(i, k):
                            acc += rinv[i, j] * rinv[i, j]
                        diag[m, i] = acc / (scale[i] * scale[i])
                    deficient[m] = False
                    continue
            for x in range(r):
                for i in range(k):
                    u[x, i] = a[m, x, i] / scale[i]
            _jacobi_one(u, v, s)
            s_max = 0.0
            for j in range(k):
                s_max = max(s_max, s[j])
            deficient[m] = False
            for j in range(k):
                if s[j] <= sv_rtol * s_max or not (s_max > 0.0):
                    deficient[m] = True
            for i in range(k):
                acc = 0.0
                leak = 0.0
                for j in range(k):
                    v2 = v[i, j] * v[i, j]
                    if s[j] <= sv_rtol * s_max or not (s_max > 0.0):
                        leak += v2
                    else:
                        acc += v2 / (s[j] * s[j])
                if leak <= leak_tol * leak_tol and not zero[i]:
                    diag[m, i] = acc / (scale[i] * scale[i])
                else:
                    diag[m, i] = math.inf


# ----- the planning scorer ---------------------------------------------------------------

SLOW = 1
"""``route`` value of a (layout, pair) the square-root route must settle (else 0)."""


BLIND, SCREENED, EXTRA, CANDIDATE, FULL = -5, -4, -3, -2, -1
"""Kinds of a pair in :func:`_score_chunk`'s ``slot`` before it gets its column (≥ 0) in the
factored batch: ``slot ≥ EXTRA`` selects the pairs left to factor (the full ones and the
candidates the screen did not settle)."""

SCREEN_PROBE = 512.0
"""Extra candidates (pairs with more RIS paths than they need) a kernel task screens before it
judges whether screening them pays."""

SCREEN_KEEP = 0.9
"""Extra candidates stay screened while at least this fraction of those screened so far were
settled: the sub-problem costs about as much as the LDLᵀ it saves at the 50–70 % settled on the
hall's 3–4 RISs (measured: 12 vs 14 M matrices/s), and pays in a city at 99 % settled (17 vs
12 M/s at 6 RISs)."""

SCREEN_PROBE_EVERY = 16
"""While extras are not screened, every 16th layout of a chunk still screens them, so a task
notices when they start to pay."""

DEGENERATE_COUNT = -(1 << 40)
"""Present-path count of a pair with a UE on a chosen site: negative after any additions."""

SCREEN_MAX_STATES = 7
"""Largest sub-problem of :func:`screen_chunk` (its scratch matrices)."""

SCREEN_PIVOT_RTOL = 1e-8
"""A sub-problem pivot below this fraction of its diagonal entry is not trusted: the pair is not
screened, so the bound's rounding stays ≲ 1e-7 relative, far inside the screen margin."""


@njit(cache=True, nogil=True, error_model="numpy")
def screen_chunk(
    a: FloatArray, t: int, sub: IntArray, m: int, mat: FloatArray, rows: FloatArray, out: FloatArray
) -> None:
    """out[:t]: a lower bound on the CRB trace of the last ``m`` states of ``sub`` for the
    packed matrices in the first t columns of a: the trace of the trailing m × m block of M⁻¹,
    M the principal sub-matrix on the states ``sub`` (positions in the packed order, ≤ 7 of
    them, the metric's last). Keeping fewer nuisance states can only add information (a Schur
    complement over a subset of the others ⪰ the one over all), so the value is ≤ the full
    CRB's trace of those states. −1 (below any limit) where M is not safely positive definite
    (a pivot ≤ :data:`SCREEN_PIVOT_RTOL` × its diagonal entry). Vectorised over the columns
    like :func:`ldl_chunk`; mat [7, 7, CHUNK] and rows [10, CHUNK] are scratch."""
    k = sub.shape[0]
    for i in range(k):
        for j in range(i + 1):
            r, c = (sub[i], sub[j]) if sub[i] >= sub[j] else (sub[j], sub[i])
            src = a[_tri(r, c)]
            dst = mat[i, j]
            for q in range(t):
                dst[q] = src[q]
    pivot, acc, bad = rows[7], rows[8], rows[9]
    for q in range(t):
        bad[q] = 0.0
    # LDLᵀ in place: L below the diagonal, D_j on it
    for j in range(k):
        for q in range(t):
            pivot[q] = mat[j, j, q]
        for u in range(j):
            for q in range(t):
                pivot[q] -= mat[j, u, q] * mat[j, u, q] * mat[u, u, q]
        for q in range(t):
            mjj = mat[j, j, q]
            if not (mjj > 0.0 and pivot[q] > SCREEN_PIVOT_RTOL * mjj):
                bad[q] = 1.0
                pivot[q] = 1.0
        for i in range(j + 1, k):
            for q in range(t):
                acc[q] = mat[i, j, q]
            for u in range(j):
                for q in range(t):
                    acc[q] -= mat[i, u, q] * mat[j, u, q] * mat[u, u, q]
            for q in range(t):
                mat[i, j, q] = acc[q] / pivot[q]
        for q in range(t):
            mat[j, j, q] = pivot[q]
    # trailing block of M⁻¹ = L22⁻ᵀ D2⁻¹ L22⁻¹: trace = Σ_r (1/d_r) Σ_col X[r, col]², with
    # X = L22⁻¹ (unit lower), one column at a time in rows[:m]
    o = k - m
    for q in range(t):
        out[q] = 0.0
    for col in range(m):
        for q in range(t):
            rows[col, q] = 1.0
            out[q] += 1.0 / mat[o + col, o + col, q]
        for r in range(col + 1, m):
            for q in range(t):
                acc[q] = -mat[o + r, o + col, q]
            for u in range(col + 1, r):
                for q in range(t):
                    acc[q] -= mat[o + r, o + u, q] * rows[u, q]
            for q in range(t):
                rows[r, q] = acc[q]
                out[q] += acc[q] * acc[q] / mat[o + r, o + r, q]
    for q in range(t):
        if bad[q] != 0.0:
            out[q] = -1.0


@njit(cache=True, nogil=True, error_model="numpy")
def _peb(diag: FloatArray, rows: IntArray, q: int) -> float:
    acc = diag[rows[0], q]
    for r in range(1, rows.shape[0]):
        acc += diag[rows[r], q]
    return math.sqrt(acc)


@njit(cache=True, nogil=True, error_model="numpy")
def to_blocks(packed: FloatArray, src: IntArray) -> FloatArray:
    """The kept entries src [E] of packed [28, S, P] as pair blocks [⌈P/CHUNK⌉, S, E, CHUNK]
    (zeros past P): one block holds every site's entries of CHUNK pairs contiguously."""
    n_s, n_p = packed.shape[1], packed.shape[2]
    e_n = src.shape[0]
    n_chunks = (n_p + CHUNK - 1) // CHUNK
    out = np.zeros((n_chunks, n_s, e_n, CHUNK))
    for s in range(n_s):
        for e in range(e_n):
            row = src[e]
            for p in range(n_p):
                out[p // CHUNK, s, e, p % CHUNK] = packed[row, s, p]
    return out


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def score_layouts(
    blocks: FloatArray,
    src: IntArray,
    los: FloatArray,
    layouts: IntArray,
    n_pairs: int,
    n: int,
    trace_limit: float,
    first: IntArray,
    second: IntArray,
    mode: int,
    degenerate: UInt8Array,
    present: UInt8Array,
    need: IntArray,
    out: FloatArray,
    route: UInt8Array,
    n_tasks: int,
    screen: IntArray,
    screen_m: int,
    screen_limit: float,
) -> None:
    """Metric out [B, P] (mode 0: PEB of ``first``; 1: max of the PEBs of ``first`` and
    ``second``) or [B, 2P] (mode 2, mirrored: PEB of ``first``, then of ``second``) of the
    layouts [B, L]; route [B, P] = SLOW where the square-root route must decide (``out`` is
    left undefined there).

    blocks : the cache's packed information as pair blocks [⌈P/CHUNK⌉, S, 28, CHUNK]
    (:attr:`ris_planner.planning.site_cache.SiteCache.blocks`, float64 or float32: a float32
    entry is widened exactly to float64 before any arithmetic); src : [E] its entries of the
    kept states in ldl.packed_index(n) order; los : the LOS information on the kept states in
    the same blocks [⌈P/CHUNK⌉, E, CHUNK] (:func:`to_blocks`), or shape (0, 0, 0) without LOS;
    degenerate [S, P] or (0, 0); present [S, P] with need [P] the RIS paths a pair
    needs, or (0, 0) without the per-pair counting rule.

    Pairs that are ``inf`` (blind) are neither summed nor factored: a chunk's present pairs
    are packed together first (the same operations per pair, so the same bits).

    screen, screen_m, screen_limit (mode 0 only; ``screen_limit`` ≤ 0 turns it off): the
    positions of a sub-problem's states among the kept ones, the last ``screen_m`` the metric's
    (:func:`screen_chunk`); a candidate pair – every present pair without the counting rule,
    else a pair with just the RIS paths it needs (its smallest identifiable count, where most
    pairs are ill-conditioned) – whose sub-problem bound exceeds ``screen_limit`` is settled
    with √bound (a value above the objective's threshold or cap, not the PEB) without the full
    factorisation."""
    n_chunks = blocks.shape[0]
    e_n = src.shape[0]
    n_tasks = min(n_chunks, max(1, n_tasks))
    for task in prange(n_tasks):
        a = np.empty((e_n, CHUNK))
        work = np.empty((work_rows(n), CHUNK))
        diag = np.empty((n, CHUNK))
        trace = np.empty(CHUNK)
        singular = np.empty(CHUNK, dtype=np.bool_)
        a2 = np.empty((e_n, CHUNK))
        slot = np.empty(CHUNK, dtype=np.int64)
        count = np.empty(CHUNK, dtype=np.int64)
        stats = np.zeros(2)  # extra candidates screened, settled (this task)
        bound = np.empty(CHUNK)
        mat = np.empty((SCREEN_MAX_STATES, SCREEN_MAX_STATES, CHUNK))
        rows = np.empty((SCREEN_MAX_STATES + 3, CHUNK))
        for c in range(task * n_chunks // n_tasks, (task + 1) * n_chunks // n_tasks):
            _score_chunk(
                blocks, src, los, layouts, n_pairs, n, trace_limit, first, second, mode,
                degenerate, present, need, out, route, c, a, work, diag, trace, singular,
                screen, screen_m, screen_limit, a2, slot, count, stats, bound, mat, rows,
            )  # fmt: skip


@njit(cache=True, nogil=True, error_model="numpy")
def _score_chunk(
    blocks: FloatArray,
    src: IntArray,
    los: FloatArray,
    layouts: IntArray,
    n_pairs: int,
    n: int,
    trace_limit: float,
    first: IntArray,
    second: IntArray,
    mode: int,
    degenerate: UInt8Array,
    present: UInt8Array,
    need: IntArray,
    out: FloatArray,
    route: UInt8Array,
    c: int,
    a: FloatArray,
    work: FloatArray,
    diag: FloatArray,
    trace: FloatArray,
    singular: BoolArray,
    screen: IntArray,
    screen_m: int,
    screen_limit: float,
    a2: FloatArray,
    slot: IntArray,
    count: IntArray,
    stats: FloatArray,
    bound: FloatArray,
    mat: FloatArray,
    rows: FloatArray,
) -> None:
    """Every layout on the pairs of block c (:func:`score_layouts`)."""
    n_b, n_l = layouts.shape
    e_n = src.shape[0]
    has_los = los.shape[0] > 0
    has_deg = degenerate.shape[0] > 0
    has_count = present.shape[0] > 0
    screening = screen_limit > 0.0
    p0 = c * CHUNK
    t = min(CHUNK, n_pairs - p0)
    for b in range(n_b):
        # each pair's kind first: blind (inf, never summed or factored), a screen candidate
        # (at its smallest identifiable count: as many present paths as it needs), an extra
        # candidate (more paths: screened only while the screen settles nearly all of them),
        # or full
        for q in range(t):
            route[b, p0 + q] = 0
        if not (has_deg or has_count):  # every pair is present: nothing to classify
            n_live = t
            n_cand = t if screening else 0
            kind = CANDIDATE if screening else FULL
            for q in range(t):
                slot[q] = kind
        else:
            for q in range(t):
                count[q] = 0
            if has_deg:  # a UE on a chosen site: blind (a count below zero whatever is added)
                for col in range(n_l):
                    drow = degenerate[layouts[b, col]]
                    for q in range(t):
                        if drow[p0 + q]:
                            count[q] = DEGENERATE_COUNT
            if has_count:
                for col in range(n_l):
                    prow = present[layouts[b, col]]
                    for q in range(t):
                        count[q] += prow[p0 + q]
            extras = screening and (
                stats[0] < SCREEN_PROBE
                or stats[1] >= SCREEN_KEEP * stats[0]
                or b % SCREEN_PROBE_EVERY == 0
            )
            n_live = 0
            n_cand = 0
            for q in range(t):
                p = p0 + q
                k = count[q]
                if k < 0 or (has_count and k < need[p]):
                    slot[q] = BLIND
                    out[b, p] = math.inf
                    if mode == 2:
                        out[b, n_pairs + p] = math.inf
                    continue
                n_live += 1
                if screening and (not has_count or k == need[p]):
                    slot[q] = CANDIDATE
                    n_cand += 1
                elif extras:
                    slot[q] = EXTRA
                    n_cand += 1
                else:
                    slot[q] = FULL
        if n_live == 0:
            continue
        s0 = layouts[b, 0]
        if has_los:
            for e in range(e_n):
                row = blocks[c, s0, src[e]]
                for q in range(t):
                    a[e, q] = los[c, e, q] + row[q]
        else:
            for e in range(e_n):
                row = blocks[c, s0, src[e]]
                for q in range(t):
                    a[e, q] = row[q]
        for col in range(1, n_l):
            s = layouts[b, col]
            for e in range(e_n):
                row = blocks[c, s, src[e]]
                for q in range(t):
                    a[e, q] += row[q]
        n_fact = n_live
        if n_cand > 0:  # screened in place, or the candidates packed to the left of a2
            sa = a
            if n_cand < t:
                sa = a2
                k = 0
                for q in range(t):
                    if slot[q] == CANDIDATE or slot[q] == EXTRA:
                        for e in range(e_n):
                            a2[e, k] = a[e, q]
                        k += 1
            screen_chunk(sa, n_cand, screen, screen_m, mat, rows, bound)
            k = 0
            for q in range(t):
                if slot[q] == CANDIDATE or slot[q] == EXTRA:
                    settled = bound[k] > screen_limit
                    if slot[q] == EXTRA:
                        stats[0] += 1.0
                        stats[1] += 1.0 if settled else 0.0
                    if settled:
                        slot[q] = SCREENED
                        out[b, p0 + q] = math.sqrt(bound[k])
                        n_fact -= 1
                    k += 1
        if n_fact == t:  # nothing left out: factor the chunk in place
            for q in range(t):
                slot[q] = q
            ldl_chunk(a, n, t, work, diag, trace, singular)
        elif n_fact > 0:  # the pairs left to factor, packed to the left of a2
            t2 = 0
            for q in range(t):
                if slot[q] >= EXTRA:
                    slot[q] = t2
                    for e in range(e_n):
                        a2[e, t2] = a[e, q]
                    t2 += 1
            ldl_chunk(a2, n, t2, work, diag, trace, singular)
        for q in range(t):
            p = p0 + q
            j = slot[q]
            if j < 0:  # blind, or settled by the screen: a lower bound above the limit
                continue
            if singular[j] or not (trace[j] <= trace_limit):
                route[b, p] = SLOW
            else:
                v1 = _peb(diag, first, j)
                if mode == 0:
                    out[b, p] = v1
                elif mode == 1:
                    v2 = _peb(diag, second, j)
                    out[b, p] = v1 if v1 >= v2 else v2
                else:
                    out[b, p] = v1
                    out[b, n_pairs + p] = _peb(diag, second, j)
