"""The shared batched LDLᵀ inversion against numpy's dense inverse (an independent route)."""

from __future__ import annotations

import numpy as np

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


def test_compiled_ldl_is_bit_identical_to_numpy(rng: np.random.Generator) -> None:
    """The compiled twin (ris_planner.inversion._crb_jit) repeats ldl.py's operations in order, so
    the
    diagonal, the singular flags and the trace test of crb_diagonal's fast path are the same
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
        f[45:50, 0, 0] = -1.0  # a negative diagonal: scaled as zero, singular
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
