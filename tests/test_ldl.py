"""The shared batched LDLᵀ inversion against numpy's dense inverse (an independent route)."""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np
import pytest
from waits import HANG_S

from ris_planner.inversion import ldl

INVERSE_RTOL = 1e-11
"""The test matrices have scaled condition numbers ≤ ~1e3; two backward-stable inversions then
agree to cond·ε ≈ 1e-13, with two orders of margin."""


def spd_batch(rng: np.random.Generator, count: int, n: int = 7) -> np.ndarray:
    a = rng.normal(size=(count, n, 3 * n))
    scale = np.exp(rng.uniform(-6, 6, size=(count, n)))  # wildly different units per state
    f = (a @ a.transpose(0, 2, 1)) * scale[:, :, None] * scale[:, None, :]
    return (f + f.transpose(0, 2, 1)) / 2  # exactly symmetric


def test_packing_round_trip(rng: np.random.Generator) -> None:
    f = spd_batch(rng, 5)
    np.testing.assert_array_equal(ldl.unpack(ldl.pack(f), 7), f)
    idx = ldl.packed_index(7)
    assert idx[(6, 2)] == idx[(2, 6)] and sorted(set(idx.values())) == list(range(28))


def test_inverse_and_diagonal_match_dense_inverse(rng: np.random.Generator) -> None:
    f = spd_batch(rng, 200)
    ref = np.linalg.inv(f)
    inv, singular = ldl.inverse_from(ldl.pack(f), 7)
    assert not singular.any()
    # an off-diagonal entry is accurate relative to its natural scale sqrt(inv_ii·inv_jj)
    # (|inv_ij| ≤ that), not to itself: it may be the small difference of large terms
    d = np.sqrt(np.diagonal(ref, axis1=1, axis2=2))
    scale = d[:, :, None] * d[:, None, :]
    np.testing.assert_allclose(ldl.unpack(inv, 7) / scale, ref / scale, rtol=0, atol=INVERSE_RTOL)
    diag, _ = ldl.inverse_diagonal_from(ldl.pack(f), 7)
    np.testing.assert_allclose(diag.T, np.diagonal(ref, axis1=1, axis2=2), rtol=INVERSE_RTOL)


def test_partial_diagonal_is_bit_identical_and_singular_detected(rng: np.random.Generator) -> None:
    f = spd_batch(rng, 500)
    f[::50, 6, :] = f[::50, :, 6] = 0.0  # no clock information
    f[1::50] = np.outer(np.arange(1.0, 8.0), np.arange(1.0, 8.0))  # rank one
    full, sing = ldl.inverse_diagonal_from(ldl.pack(f), 7)
    expected = np.zeros(500, bool)
    expected[::50] = expected[1::50] = True
    np.testing.assert_array_equal(sing, expected)
    assert np.all(np.isinf(full[:, sing])) and not np.any(np.isnan(full))
    for first in (3, 6):
        part, _ = ldl.inverse_diagonal_from(ldl.pack(f), 7, first)
        np.testing.assert_array_equal(part, full[first:])


def test_power_of_two_scaling_changes_no_rounding(rng: np.random.Generator) -> None:
    """The factorisation is not equilibrated because a symmetric scaling by powers of two,
    C F C, scales every intermediate exactly: diag((CFC)⁻¹) is diag(F⁻¹) / c_i² bit for bit
    (numpy and compiled routes), ill-conditioned and singular matrices included."""
    f = np.concatenate([spd_batch(rng, 100), ldl.unpack(unrolled_inputs(rng, 60), 7)])
    c = np.exp2(rng.integers(-40, 41, size=(f.shape[0], 7))).astype(float)
    g = f * c[:, :, None] * c[:, None, :]  # exact: products by powers of two
    for route in ("numpy", "compiled"):
        if route == "numpy":
            d_f, s_f = ldl.inverse_diagonal_from(ldl.pack(f), 7)
            d_g, s_g = ldl.inverse_diagonal_from(ldl.pack(g), 7)
        else:
            (d_f, _, s_f), (d_g, _, s_g) = (kernel_chunks(ldl.pack(x), "unrolled") for x in (f, g))
        np.testing.assert_array_equal(s_g, s_f)
        ok = ~s_f
        np.testing.assert_array_equal(d_g[:, ok], d_f[:, ok] / (c.T[:, ok] ** 2))
        assert np.isinf(d_g[:, ~ok]).all()


def test_singularity_rule_is_scale_free(rng: np.random.Generator) -> None:
    """A pivot ≤ SINGULAR_RCOND · F_jj is the unit-diagonal matrix's pivot ≤ SINGULAR_RCOND:
    F = L D Lᵀ with a last pivot of 1e-10 · F_66 (kept) or 1e-15 · F_66 (singular), rounding
    ~1e-16 · F_66 either way, keeps its verdict under any diagonal scaling (units from 1e-6 to
    1e6), in every route."""
    low = np.tril(rng.normal(size=(200, 7, 7)), -1) + np.eye(7)
    d = np.ones((200, 7))
    f66 = 1.0 + (low[:, 6, :6] ** 2).sum(axis=1)  # F_66 without the last pivot
    ratio = np.where(np.arange(200) % 2 == 0, 1e-10, 1e-15)
    d[:, 6] = ratio * f66 / (1.0 - ratio)  # D_6 / F_66 = ratio
    f = (low * d[:, None, :]) @ low.transpose(0, 2, 1)
    f = (f + f.transpose(0, 2, 1)) / 2
    expected = np.arange(200) % 2 == 1
    for scale_range in (0.0, 6.0):
        s = 10.0 ** rng.uniform(-scale_range, scale_range, size=(200, 7))
        fp = ldl.pack(f * s[:, :, None] * s[:, None, :])
        np.testing.assert_array_equal(ldl.inverse_diagonal_from(fp, 7)[1], expected)
        for kernel in ("unrolled", "loop"):
            np.testing.assert_array_equal(kernel_chunks(fp, kernel)[2], expected)


def test_compiled_ldl_is_bit_identical_to_numpy(rng: np.random.Generator) -> None:
    """The compiled twin (ris_planner.inversion._crb_jit) repeats ldl.py's operations in order,
    so the diagonal, the singular flags and the trace test of crb_diagonal's fast path are the same
    bits: well and ill conditioned (scaled cond up to ~1e15), singular (a state without
    information, rank one), every state count the known parts leave, and a batch that is not
    a multiple of the kernel's chunk."""
    from ris_planner.inversion.crb import fast_diagonal

    for n in (3, 4, 6, 7):
        f = spd_batch(rng, 333, n)
        x = rng.normal(size=(50, n, n - 1))  # rank n − 1, perturbed: cond 1e6 … 1e15
        eps = np.exp(rng.uniform(np.log(1e-8), np.log(1e-3), 50))[:, None, None]
        f[:50] = x @ x.transpose(0, 2, 1) + eps**2 * np.eye(n)
        f[50:60, -1, :] = f[50:60, :, -1] = 0.0
        f[60:70] = np.outer(np.arange(1.0, n + 1), np.arange(1.0, n + 1))
        fp = ldl.pack(f)
        d_np, s_np, t_np = fast_diagonal(fp, n, "numpy")
        d_jit, s_jit, t_jit = fast_diagonal(fp, n, "numba")
        assert s_np[50:70].all() and not s_np[70:].any()
        np.testing.assert_array_equal(s_jit, s_np)
        np.testing.assert_array_equal(d_jit, d_np)  # inf on the singular ones in both
        np.testing.assert_array_equal(t_jit[~s_np], t_np[~s_np])


def test_summed_diagonal_is_the_diagonal_of_the_sums(rng: np.random.Generator) -> None:
    """summed_crb_diagonal (a layout's information plus one more path's, summed inside the
    compiled kernel as it reads them) gives the bits of crb_diagonal on the sums formed first,
    with either engine: well and ill conditioned sums, singular ones (a state without
    information), indices repeated and out of order, a batch not a multiple of the chunk."""
    from ris_planner.inversion.crb import crb_diagonal, summed_crb_diagonal

    for n in (4, 5, 7):
        base = spd_batch(rng, 40, n)
        base[:5, -1, :] = base[:5, :, -1] = 0.0
        x = rng.normal(size=(300, n, 2))  # rank-two paths: sums near singular
        add = x @ x.transpose(0, 2, 1)
        add[:7] *= 1e-12
        add[7:10, -1, :] = add[7:10, :, -1] = 0.0
        b_idx = rng.integers(0, 40, 777)
        a_idx = rng.integers(0, 300, 777)
        sums = base[b_idx] + add[a_idx]

        def rows(i: np.ndarray, sums: np.ndarray = sums) -> np.ndarray:
            w, v = np.linalg.eigh(sums[i])  # square-root rows R with RᵀR = the sum
            return np.sqrt(np.maximum(w, 0.0))[..., :, None] * v.transpose(0, 2, 1)

        want, want_rd = crb_diagonal(ldl.pack(sums), n, rows, "numpy")
        bp = np.ascontiguousarray(ldl.pack(base).T)
        ap = np.ascontiguousarray(ldl.pack(add).T)
        for engine in ("numpy", "numba"):
            got, got_rd = summed_crb_diagonal(bp, ap, b_idx, a_idx, n, rows, engine)  # type: ignore[arg-type]
            np.testing.assert_array_equal(got, want)
            np.testing.assert_array_equal(got_rd, want_rd)


def test_float_route_of_small_batches_is_bit_identical_to_numpy(rng: np.random.Generator) -> None:
    """Batches of up to ldl.SCALAR_MAX_BATCH matrices run the same operations on Python floats
    (a single pair's call costs a numpy call per operation otherwise): every matrix of a large
    batch (the vector route) gives the same bits alone and in small batches (the float route) –
    well and ill conditioned, singular, every state count, partial diagonals, the full inverse."""
    for n in (1, 3, 4, 6, 7):
        f = spd_batch(rng, 120, n)
        if n > 1:
            x = rng.normal(size=(30, n, n - 1))  # rank n − 1, perturbed: cond 1e6 … 1e15
            eps = np.exp(rng.uniform(np.log(1e-8), np.log(1e-3), 30))[:, None, None]
            f[:30] = x @ x.transpose(0, 2, 1) + eps**2 * np.eye(n)
        f[30:40, -1, :] = f[30:40, :, -1] = 0.0  # no information on the last state
        f[40:45] = np.outer(np.arange(1.0, n + 1), np.arange(1.0, n + 1))  # rank one
        f[45:50, 0, 0] = -1.0  # a negative diagonal: singular
        fp = ldl.pack(f)
        assert fp.shape[1] > ldl.SCALAR_MAX_BATCH  # the vector route
        inv, sing = ldl.inverse_from(fp, n)
        assert sing[30:40].all() and sing[45:50].all() and (n == 1 or sing[40:45].all())
        for first in range(n):
            diag, sing_d = ldl.inverse_diagonal_from(fp, n, first)
            np.testing.assert_array_equal(sing_d, sing)
            for s in range(0, 120, 7):  # batches of 7, then 1 (≤ SCALAR_MAX_BATCH)
                part, sing_p = ldl.inverse_diagonal_from(fp[:, s : s + 7], n, first)
                np.testing.assert_array_equal(part, diag[:, s : s + 7])
                np.testing.assert_array_equal(sing_p, sing[s : s + 7])
        for b in range(120):
            one, sing_1 = ldl.inverse_from(fp[:, b : b + 1], n)
            np.testing.assert_array_equal(one[:, 0], inv[:, b])
            assert sing_1[0] == sing[b]


def unrolled_inputs(rng: np.random.Generator, count: int) -> np.ndarray:
    """7 × 7 batches for the unrolled kernel: well conditioned, nearly rank-deficient (scaled
    cond 1e6 … 1e15), a state without information, rank one, all zero, a negative and a NaN
    diagonal entry (a corrupted input must be flagged the same way)."""
    f = spd_batch(rng, count, 7)
    x = rng.normal(size=(40, 7, 6))
    eps = np.exp(rng.uniform(np.log(1e-8), np.log(1e-3), 40))[:, None, None]
    f[:40] = x @ x.transpose(0, 2, 1) + eps**2 * np.eye(7)
    f[40:50, 4, :] = f[40:50, :, 4] = 0.0
    f[50:55] = np.outer(np.arange(1.0, 8.0), np.arange(1.0, 8.0))
    f[55] = 0.0
    f[56, 2, 2] = -1.0
    f[57, 5, 5] = np.nan
    return ldl.pack(f)


def kernel_chunks(fp: np.ndarray, fn: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(diag [7, N], trace [N], singular [N]) by ``_crb_jit.ldl_chunk`` (``"loop"``) or
    ``_crb_jit.factor_chunk`` (the unrolled kernel), chunk by chunk as the scorer calls them
    (the last chunk partly filled)."""
    from ris_planner.inversion import _crb_jit as jit

    size, c = fp.shape[1], jit.CHUNK
    diag, trace, sing = np.empty((7, size)), np.empty(size), np.empty(size, bool)
    work = np.empty((jit.work_rows(7), c))
    dg, tr, sg = np.empty((7, c)), np.empty(c), np.empty(c, bool)
    for p0 in range(0, size, c):
        t = min(c, size - p0)
        a = np.zeros((28, c))
        a[:, :t] = fp[:, p0 : p0 + t]
        kernel = jit.ldl_chunk if fn == "loop" else jit.factor_chunk
        kernel(a, 7, t, work, dg, tr, sg)
        diag[:, p0 : p0 + t], trace[p0 : p0 + t], sing[p0 : p0 + t] = dg[:, :t], tr[:t], sg[:t]
    return diag, trace, sing


def test_unrolled_ldl_is_bit_identical_to_the_loop_kernel(rng: np.random.Generator) -> None:
    """The generated straight-line kernel (n = 7, vectorised across pairs) performs the loop
    kernel's operations in the same order: the same bits on every kind of input, and the same
    singular flags (a NaN or negative diagonal, a zero row, rank one: blind, ``inf``)."""
    fp = unrolled_inputs(rng, 301)
    d_loop, t_loop, s_loop = kernel_chunks(fp, "loop")
    d_new, t_new, s_new = kernel_chunks(fp, "unrolled")
    assert s_loop[40:58].all() and not s_loop[58:].any()
    np.testing.assert_array_equal(s_new, s_loop)
    np.testing.assert_array_equal(d_new, d_loop)  # inf on the singular ones in both
    np.testing.assert_array_equal(t_new[~s_loop], t_loop[~s_loop])
    d_np, s_np = ldl.inverse_diagonal_from(fp, 7)  # and so numpy's route
    np.testing.assert_array_equal(s_new, s_np)
    np.testing.assert_array_equal(d_new, d_np)


@pytest.mark.parametrize("block_dtype", [np.float64, np.float32])
def test_summed_kernel_is_bit_identical_to_factoring_the_stored_sum(
    rng: np.random.Generator, block_dtype: type
) -> None:
    """``factor_summed_7`` (the scorer's last site summed inside the factorisation, in calls of
    ``PREFETCH_PAIRS`` pairs framed by prefetches of the next blocks) gives the bits of
    ``a = base + block`` stored and factored by ``factor_chunk``: on every kind of input
    (singular, negative and NaN diagonals included), with a float32 block (widened exactly), a
    partly filled last chunk (t not a multiple of PREFETCH_PAIRS), and any blocks ahead (none,
    one or two)."""
    from ris_planner.inversion import _crb_jit as jit

    c = jit.CHUNK
    fp = unrolled_inputs(rng, 301)
    part = np.abs(rng.normal(size=fp.shape)) * np.abs(fp).max(axis=0)  # a site's share
    part[:, 40:58] = 0.0  # the flagged inputs stay as they are
    block_all = (part * 0.3).astype(block_dtype)
    base_all = fp - block_all  # base + block ≈ fp: the same kinds of matrices
    work = np.empty((jit.work_rows(7), c))
    ends = [min(p0 + c, fp.shape[1]) for p0 in range(0, fp.shape[1], c)]
    assert (ends[-1] - ends[-2]) % jit.PREFETCH_PAIRS != 0  # the short call is exercised
    for p0, end in zip(range(0, fp.shape[1], c), ends, strict=True):
        t = end - p0
        base, block = np.zeros((28, c)), np.zeros((28, c), dtype=block_dtype)
        base[:, :t], block[:, :t] = base_all[:, p0:end], block_all[:, p0:end]
        ahead = np.stack([block, block[:, ::-1]])  # any blocks: only prefetched
        sites = np.arange(min(p0 // c, 2), dtype=np.int64)  # none, one, both
        got = np.empty((7, c)), np.empty(c), np.empty(c, bool)
        jit.factor_summed_7(base, block, ahead, sites, t, *got)
        want = np.empty((7, c)), np.empty(c), np.empty(c, bool)
        jit.factor_chunk(base + block, 7, t, work, *want)
        np.testing.assert_array_equal(got[2][:t], want[2][:t])
        np.testing.assert_array_equal(got[0][:, :t], want[0][:, :t])
        regular = ~want[2][:t]
        np.testing.assert_array_equal(got[1][:t][regular], want[1][:t][regular])
        if p0 == 0:  # the flagged inputs and the well-conditioned ones, in this chunk
            assert want[2][40:58].all() and regular[58:].all()
        else:
            assert regular.all()


def test_unrolled_ldl_against_mpmath(rng: np.random.Generator) -> None:
    """The unrolled kernel's diagonal of F⁻¹ against a 40-digit inversion (an independent
    route): within the tolerance rule's ulps · ε · cond on every regular matrix, cond up to
    ~1e15 included; ``inf`` exactly where the reference is singular to working precision."""
    import mpmath
    from tolerance import assert_close, fim_cond

    fp = unrolled_inputs(rng, 120)
    diag, _, sing = kernel_chunks(fp, "unrolled")
    f = ldl.unpack(fp, 7)
    for m in range(fp.shape[1]):
        if sing[m]:
            assert np.isinf(diag[:, m]).all()
            assert m >= 40 or fim_cond(f[m]) > 1 / ldl.SINGULAR_RCOND / 10
            continue
        with mpmath.workdps(40):
            inv = mpmath.inverse(mpmath.matrix(f[m].tolist()))
            want = np.array([float(inv[i, i]) for i in range(7)])
        assert_close(diag[:, m], want, cond=fim_cond(f[m]), where=f"matrix {m}")


def test_generated_kernels_are_up_to_date() -> None:
    """_crb_jit.py's generated block is what scripts/gen_ldl_kernels.py writes."""
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parent.parent / "scripts" / "gen_ldl_kernels.py"
    done = subprocess.run(
        [sys.executable, str(script), "--check"], capture_output=True, text=True, timeout=HANG_S
    )
    assert done.returncode == 0, done.stderr


class _Counted:
    """A float that counts the arithmetic done on it (for the FLOP model's check)."""

    ops: ClassVar[dict[str, int]] = {}

    def __init__(self, v: float) -> None:
        self.v = float(v)

    @classmethod
    def _op(cls, name: str, v: float) -> _Counted:
        cls.ops[name] = cls.ops.get(name, 0) + 1
        return cls(v)

    @staticmethod
    def _val(x: object) -> float:
        return x.v if isinstance(x, _Counted) else float(x)  # type: ignore[arg-type]

    def __add__(self, o: object) -> _Counted:
        return self._op("+", self.v + self._val(o))

    __radd__ = __add__

    def __sub__(self, o: object) -> _Counted:
        return self._op("-", self.v - self._val(o))

    def __rsub__(self, o: object) -> _Counted:
        return self._op("-", self._val(o) - self.v)

    def __mul__(self, o: object) -> _Counted:
        return self._op("*", self.v * self._val(o))

    __rmul__ = __mul__

    def __truediv__(self, o: object) -> _Counted:
        return self._op("/", self.v / self._val(o))

    def __rtruediv__(self, o: object) -> _Counted:
        return self._op("/", self._val(o) / self.v)

    def __neg__(self) -> _Counted:
        return _Counted(-self.v)  # a sign flip: not counted

    def __lt__(self, o: object) -> bool:
        return self.v < self._val(o)

    def __le__(self, o: object) -> bool:
        return self.v <= self._val(o)

    def __gt__(self, o: object) -> bool:
        return self.v > self._val(o)

    def __ge__(self, o: object) -> bool:
        return self.v >= self._val(o)

    def __ne__(self, o: object) -> bool:
        return self.v != self._val(o)

    def __eq__(self, o: object) -> bool:
        return self.v == self._val(o)

    __hash__ = None  # type: ignore[assignment]

    def __float__(self) -> float:
        return self.v


class _CountingMath:
    inf = np.inf

    @staticmethod
    def sqrt(x: object) -> _Counted:
        return _Counted._op("sqrt", np.sqrt(_Counted._val(x)))


def test_flop_model_matches_an_instrumented_count(
    rng: np.random.Generator, monkeypatch: pytest.MonkeyPatch
) -> None:
    """ldl.ldl_flops (the benchmark's FLOP model) equals the operations counted by running the
    kernels' Python source (numba's ``py_func``) on one matrix of counting floats: the loop
    kernel for every state count, the unrolled one for n = 7; the divisions separately (what
    bounds the kernel: docs/validation/benchmarks.md)."""
    from ris_planner.inversion import _crb_jit as jit

    monkeypatch.setattr(jit, "math", _CountingMath)
    c = jit.CHUNK
    for n in range(2, 8):
        e_n = n * (n + 1) // 2
        fp = ldl.pack(spd_batch(rng, 1, n))
        runs = [("loop", n)] + ([("unrolled", n)] if n == 7 else [])
        for kind, _ in runs:
            a = np.full((e_n, c), _Counted(0.0), dtype=object)
            a[:, 0] = [_Counted(v) for v in fp[:, 0]]
            diag = np.empty((n, c), dtype=object)
            trace = np.empty(c, dtype=object)
            sing = np.zeros(c, dtype=bool)
            _Counted.ops = {}
            if kind == "loop":
                work = np.empty((jit.work_rows.py_func(n), c), dtype=object)
                jit.ldl_chunk.py_func(a, n, 1, work, diag, trace, sing)
            else:
                jit.ldl_pairs_7.py_func(a.reshape(-1), 1, diag.reshape(-1), trace, sing)
            model = ldl.ldl_flops(n)
            assert sum(_Counted.ops.values()) == sum(model.values()), (kind, n, _Counted.ops)
            if kind == "unrolled":  # summed: the same plus one addition per packed entry
                before = dict(_Counted.ops)
                _Counted.ops = {}
                zero = np.full((e_n, c), _Counted(0.0), dtype=object)
                summed = np.empty((n, c), dtype=object)
                jit.ldl_sum_pairs_7.py_func(
                    a.reshape(-1), zero.reshape(-1), 1, summed.reshape(-1), trace, sing
                )
                assert _Counted.ops == {**before, "+": before.get("+", 0) + e_n}
                assert [float(v) for v in summed[:, 0]] == [float(v) for v in diag[:, 0]]
            assert _Counted.ops["/"] == n  # 1/D_j: the other quotients are products
            assert "sqrt" not in _Counted.ops
            assert not sing[0]
            want, _ = ldl.inverse_diagonal_from(fp, n)
            assert [float(v) for v in diag[:, 0]] == want[:, 0].tolist()  # same bits
    assert jit.score_flops(7, 3, True, (3,)) == 3 * 28 + 314 + 3
    assert jit.score_flops(7, 2, False, (3, 3)) == 28 + 314 + 6


def test_bench_scorer_flops_smoke(capsys: pytest.CaptureFixture[str]) -> None:
    """benchmarks/planning/bench_scorer.py --sections flops on a small hall (200 pairs, 2 layouts,
    one repeat): it runs, and every run reports a fraction of the peak measured in the same run (no
    timing is asserted: the machine may be loaded)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks" / "planning"))
    from bench_scorer import flops

    got = flops(2, 1, n_pairs=200, reps=20)
    assert len(got) == 2 * 6 + 2 and all(0.0 < v < math.inf for v in got.values()), got
    assert "of the peak" in capsys.readouterr().out


def test_bench_scorer_refuses_more_layouts_than_the_search_run_has() -> None:
    """--flops-layouts above C(24, 2) would leave rows of the L = 2 search run unscored (and
    miscounted): refused before any work, with the limit in the message."""
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parent.parent / "benchmarks" / "planning" / "bench_scorer.py"
    cmd = [sys.executable, str(script), "--sections", "flops", "--flops-layouts", "277"]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=HANG_S, check=False)
    assert res.returncode == 2 and "1 … 276" in res.stderr, res.stderr


def test_bench_scorer_counts_the_blocks_the_kernel_adds() -> None:
    """The benchmark's FLOP count of a batch follows the kernel's partial sums: a layout adds
    the site blocks after the prefix it shares with the layout before (a chunk's first layout
    all of them); with LOS every added block is E additions, without it the first is a copy."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks" / "planning"))
    from bench_scorer import batch_flops, summed_columns

    from ris_planner.inversion import _crb_jit as jit

    lay = np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3], [1, 2, 4]])
    assert summed_columns(lay) == 3 + 1 + 2 + 3 + 1
    assert summed_columns(lay[:1]) == 3 and summed_columns(lay[:0]) == 0
    ldl_and_metric = jit.score_flops(7, 0, True, (3,))
    assert ldl_and_metric == sum(ldl.ldl_flops(7).values()) + 3  # LDLᵀ and one PEB, no block
    assert batch_flops(lay, 7, True, (3,)) == 5 * ldl_and_metric + 10 * 28
    assert batch_flops(lay, 7, False, (3,)) == 5 * ldl_and_metric + 9 * 28
    # every block added (random layouts sharing no prefix): score_flops' own count
    spread = np.array([[0, 1, 2], [3, 4, 5]])
    assert batch_flops(spread, 7, True, (3,)) == 2 * jit.score_flops(7, 3, True, (3,))
