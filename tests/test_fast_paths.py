"""The faster bounds routes (docs/validation/speed-guard.md) against the routes they replaced, kept
here verbatim as references: bit for bit where the rounding order is the same, else to a
named tolerance (the unit-root square-root factor)."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from typing import Any

import mpmath
import numpy as np
import pytest
from test_environment_bounds import site_doc
from threadpoolctl import threadpool_limits

from ris_planner import preset_document
from ris_planner.bounds.compute import (
    compute_bounds,
    kept_states,
    los_path_information,
    los_referenced,
    masked_state_information,
    path_information,
    present_path_mask,
    ris_path_information,
    scenario_path_presence,
    stand_ins,
    ue_on_ris,
    uses_los_reference,
)
from ris_planner.environment import Scene
from ris_planner.inversion import crb, ldl
from ris_planner.inversion.ldl import pack
from ris_planner.model.scenario import load_scenario
from ris_planner.physics import fim, geometry
from ris_planner.planning import PlanDocument
from ris_planner.planning.inputs.presets import plan_preset
from ris_planner.planning.inputs.sites import expand_sites
from ris_planner.planning.inputs.ue_maps import build_map, build_pairs
from ris_planner.planning.scoring.site_cache import build_site_cache
from ris_planner.planning.scoring.visibility import pair_visibility

FACTOR_GRAM_RTOL = 1e-13
"""The unit-root factor α·R·J and the per-pair eigh factor are two square roots of the same
EFIM: their Grams AᵀA agree to a few roundings of entries of size ≤ √(F_ii F_jj) (entries
compared on that scale)."""

EPS = float(np.finfo(float).eps)

QUADRATIC_MP_RTOL = 1e-9
"""wᵀF⁻¹w on the fast path (trace(F̂⁻¹) ≤ 5e5 here) against 40 digits: the LDLᵀ's error is
≲ ε·cond(F̂) ≤ 7ε·trace(F̂⁻¹) ≤ 8e-10."""


def old_crb_quadratic(
    f_packed: Any, n: int, factor_rows: Callable[[Any], Any], w: Any
) -> Any:  # the implementation before the speed-up, verbatim
    inv, singular = ldl.inverse_from(f_packed, n)
    idx = ldl.packed_index(n)
    diag = np.stack([inv[idx[i, i]] for i in range(n)])
    trace = crb._trace_scaled_inverse(f_packed, n, diag)
    out = np.zeros(f_packed.shape[1])
    ok = ~singular
    for i in range(n):
        for j in range(n):
            out[ok] += w[ok, i] * inv[idx[i, j]][ok] * w[ok, j]
    slow = np.flatnonzero(singular | ~(trace <= crb.FAST_TRACE_LIMIT))
    if slow.size:
        out[slow] = crb.sqrt_crb_quadratic(factor_rows(slow), w[slow])
    return out


def old_transmission_vectors(profiles: Any, positions: Any, xi: Any, zeta: Any, lam: float) -> Any:
    k = 2 * np.pi / lam
    y, z = positions[:, 1], positions[:, 2]
    w3 = np.concatenate([profiles * (1j * k * y), profiles * (1j * k * z), profiles], axis=0)
    a = np.exp(1j * k * (np.outer(y, xi) + np.outer(z, zeta)))
    return np.asarray((w3 @ a).reshape(3, profiles.shape[0], -1).transpose(2, 1, 0))


def old_masked_state_information(paths: Any, mask: Any) -> Any:
    return np.sum(
        [np.where(mask[:, k, None, None], p.state_information(), 0.0) for k, p in enumerate(paths)],
        axis=0,
    )


def fig10_like(n_pairs: int, seed: int, known: list[str]) -> tuple[Any, Any, Any]:
    """LOS-referenced paths of the 3-RIS preset for random pairs, and the packed kept F."""
    sc = load_scenario(_preset("3-ris"))
    rng = np.random.default_rng(seed)
    tx = rng.uniform([-3, -3, 0], [3, 3, 0.5], (n_pairs, 3))
    rx = rng.uniform([-3, -3, 0], [3, 3, 0.5], (n_pairs, 3))
    paths, _ = path_information(sc, tx, rx, None, None)
    ref, clock = los_referenced(paths)
    keep = kept_states(known)  # type: ignore[arg-type]
    f = masked_state_information(ref, np.ones((n_pairs, len(ref)), dtype=bool))
    return ref, clock[:, keep], ldl.pack(f[:, keep][:, :, keep])


def _preset(name: str) -> dict[str, Any]:
    return preset_document(name) | {"codebook": {"kind": "expected_random"}}


def test_crb_quadratic_equals_the_old_loop_bit_for_bit() -> None:
    """Same terms (w_i·(F⁻¹)_ij)·w_j in the same (i, j) order: identical on every pair, fast
    and square-root route alike (Fig. 10-like pairs, the clock unknown, heights known too)."""
    for known in ([], ["height"]):
        paths, w, f_kept = fig10_like(400, 5, known)
        keep = kept_states(known)  # type: ignore[arg-type]

        def rows(idx: Any, paths: Any = paths, keep: Any = keep) -> Any:
            return crb.stack_factors([p.factor(idx) for p in paths])[:, :, keep]

        got = crb.crb_quadratic(f_kept, keep.size, rows, w)
        want = old_crb_quadratic(f_kept, keep.size, rows, w)
        np.testing.assert_array_equal(got, want)
    # a singular matrix among regular ones: inf from the square-root route, no warning
    a = np.random.default_rng(2).normal(size=(3, 9, 4))
    a[1, :, 3] = a[1, :, 2]
    f = ldl.pack(a.transpose(0, 2, 1) @ a)
    w4 = np.tile([0.3, -1.0, 0.5, 1.0], (3, 1))
    got = crb.crb_quadratic(f, 4, lambda idx: a[idx], w4)
    np.testing.assert_array_equal(got, old_crb_quadratic(f, 4, lambda idx: a[idx], w4))
    assert np.isinf(got[1]) and np.all(np.isfinite(got[[0, 2]]))


def test_crb_quadratic_fast_path_against_mpmath() -> None:
    rng = np.random.default_rng(8)
    scales = np.logspace(0, 4, 5)
    a = rng.normal(size=(4, 8, 5)) * scales
    a[:, :, 4] = a[:, :, 3] + 1e-3 * a[:, :, 4]  # near-dependent states: cond(F̂) ~ 1e6
    f = a.transpose(0, 2, 1) @ a
    w = rng.normal(size=(4, 5))
    diag, _ = ldl.inverse_diagonal_from(ldl.pack(f), 5)
    trace = np.einsum("in,nii->n", diag, f)
    assert np.all(trace <= 5e5) and np.all(trace > 1e3)  # the fast path, ill-conditioned
    got = crb.crb_quadratic(ldl.pack(f), 5, lambda idx: a[idx], w)
    with mpmath.workdps(40):
        for i in range(4):
            fm = mpmath.matrix(f[i].tolist())
            wm = mpmath.matrix(w[i].tolist())
            ref = float((wm.T * fm**-1 * wm)[0])
            assert got[i] == pytest.approx(ref, rel=QUADRATIC_MP_RTOL)


def test_masked_sum_and_transmission_products_equal_the_old_ones_bit_for_bit() -> None:
    sc = load_scenario(site_doc({"kind": "random", "seed": 1}, 40))
    tx, rx = sc.tx_array, sc.rx_array
    presence = scenario_path_presence(sc, tx, rx)
    paths, _ = path_information(sc, tx, rx, None, None)
    mask = present_path_mask(paths, presence)
    assert not np.all(mask)  # some paths missing for some pairs
    for m in (mask, np.ones_like(mask)):
        np.testing.assert_array_equal(
            masked_state_information(paths, m), old_masked_state_information(paths, m)
        )
    rng = np.random.default_rng(3)
    prof = np.exp(1j * rng.uniform(0, 2 * np.pi, (24, 36)))
    pos = np.column_stack([np.zeros(36), rng.uniform(-0.05, 0.05, (36, 2))])
    xi, zeta = rng.uniform(-1.5, 1.5, (2, 50))
    t = fim.transmission_vectors(prof, pos, xi, zeta, 0.01)
    assert fim.grid_axes(pos) is None  # scattered elements: the element-by-element route
    np.testing.assert_array_equal(t, old_transmission_vectors(prof, pos, xi, zeta, 0.01))


def gram_atol(t: Any, weights: Any) -> Any:
    """|ΔQ_ij| of two summation orders over g of w_g conj(t_ig) t_jg: each sum of G' products
    is within G'·ε·Σ_g w_g |t_ig||t_jg| ≤ G'·ε·√(Q_ii Q_jj) of the exact value (Cauchy–Schwarz);
    twice that between two orders, [P, m, m]."""
    d = np.sqrt(np.einsum("pgm,g->pm", np.abs(t) ** 2, weights))
    return 2 * t.shape[1] * EPS * d[:, :, None] * d[:, None, :]


def test_transmission_gram_by_rows_against_the_matrix_product() -> None:
    """The Gram formed entry by entry (sums over g along the pairs) against the old batched
    product, to the summation-order bound of :func:`gram_atol`; exactly Hermitian."""
    rng = np.random.default_rng(3)
    t = rng.normal(size=(50, 24, 3)) + 1j * rng.normal(size=(50, 24, 3))
    t[:, :, 0] *= 1e3  # columns of very different size (∂ξ ≫ the response)
    for weights in (np.ones(24), rng.uniform(0.2, 2.0, 24)):
        got = fim.transmission_gram(t, weights)
        old = np.conj(t).transpose(0, 2, 1) @ (t * weights[None, :, None])
        assert np.all(np.abs(got - old) <= gram_atol(t, weights))
        np.testing.assert_array_equal(got, np.conj(got).transpose(0, 2, 1))
        assert np.all(got.imag[:, [0, 1, 2], [0, 1, 2]] == 0.0)


def test_separable_steering_vectors_against_the_element_by_element_route() -> None:
    """On a rows × cols grid a_R,n = e^{jk z_r ζ} e^{jk y_c ξ} (two exponentials per row and
    column) against e^{jk(y_n ξ + z_n ζ)} per element: the phases differ by their roundings,
    ≤ 4ε(1 + |φ|) with |φ| ≤ k(|y||ξ| + |z||ζ|), so each t_g moves by at most that times
    Σ_n |w_gn| plus the product's own N·ε·Σ_n |w_gn| (w the derivative-weighted profile rows).
    A wrong element order would move t by O(|t|)."""
    rng = np.random.default_rng(5)
    lam, rows, cols = 0.01, 7, 9
    pos = geometry.element_positions(rows, cols, 0.4 * lam)
    axes = fim.grid_axes(pos)
    assert axes is not None
    np.testing.assert_array_equal(axes[0], pos[:cols, 1])
    np.testing.assert_array_equal(axes[1], pos[::cols, 2])
    prof = np.exp(1j * rng.uniform(0, 2 * np.pi, (16, rows * cols)))
    xi, zeta = rng.uniform(-1.9, 1.9, (2, 1100))  # > one block of STEERING_CHUNK pairs
    got = fim.transmission_vectors(prof, pos, xi, zeta, lam)
    want = old_transmission_vectors(prof, pos, xi, zeta, lam)
    k = 2 * np.pi / lam
    y, z = pos[:, 1], pos[:, 2]
    w3 = np.concatenate([prof * (1j * k * y), prof * (1j * k * z), prof], axis=0)
    phase_max = k * (np.abs(y).max() * np.abs(xi) + np.abs(z).max() * np.abs(zeta))  # [P]
    row_sum = np.abs(w3).sum(axis=1).reshape(3, 16).T  # [G̃, 3]
    atol = ((4 * EPS * (1 + phase_max) + rows * cols * EPS)[:, None, None]) * row_sum[None]
    assert np.all(np.abs(got - want) <= atol)
    assert np.max(np.abs(got - want)) > 0  # the separable route was taken
    # a permuted grid is not a row-major grid: the element-by-element route, bit for bit
    perm = rng.permutation(rows * cols)
    assert fim.grid_axes(pos[perm]) is None
    np.testing.assert_array_equal(
        fim.transmission_vectors(prof[:, perm], pos[perm], xi, zeta, lam),
        old_transmission_vectors(prof[:, perm], pos[perm], xi, zeta, lam),
    )


def test_planar_transmission_gram_equals_the_gram_of_the_vectors() -> None:
    """The block-by-block Gram of the bounds equals the Gram of the whole batch bit for bit."""
    rng = np.random.default_rng(6)
    pos = geometry.element_positions(6, 5, 0.005)
    prof = np.exp(1j * rng.uniform(0, 2 * np.pi, (12, 30)))
    xi, zeta = rng.uniform(-1, 1, (2, 1300))
    weights = rng.uniform(0.5, 1.5, 12)
    np.testing.assert_array_equal(
        fim.planar_transmission_gram(prof, pos, xi, zeta, 0.01, weights),
        fim.transmission_gram(fim.transmission_vectors(prof, pos, xi, zeta, 0.01), weights),
    )


@pytest.mark.parametrize("known", [(), ("clock",)])
def test_site_cache_skips_absent_paths_with_the_same_values(known: tuple[str, ...]) -> None:
    """The hall preset (machines block legs): sites evaluated on their present pairs only equal
    the old build (every pair evaluated, absent ones zeroed) bit for bit."""
    d = PlanDocument.model_validate(plan_preset("hall") | {"pairs": {"sample": 120, "seed": 4}})
    sites = expand_sites(d)[::4]
    pairs = build_pairs(build_map(d.tx_map, "tx"), build_map(d.rx_map, "rx"), d.pairs, 10**6)
    vis = pair_visibility(Scene.from_environment(d.environment), sites, pairs, d.system.los)
    assert 0.2 < vis.present.mean() < 0.9
    cache = build_site_cache(d.system, sites, pairs, visibility=vis, known=known)
    radio = fim.Radio.from_system(d.system)
    g = d.system.transmissions
    los = los_path_information(pairs.tx, pairs.rx, radio, float(g))
    referenced = uses_los_reference(d.system.los, known)  # type: ignore[arg-type]
    for s, site in enumerate(sites):
        bad = ue_on_ris(pairs.tx, pairs.rx, site.ris.position)
        t, r = stand_ins(pairs.tx, pairs.rx, bad)
        info, far = ris_path_information(site.ris, t, r, radio, None, 1, np.ones(g))
        if referenced:
            info = los_referenced([los, info])[0][1]
        packed = pack(info.state_information())
        packed[:, ~vis.present[s]] = 0.0
        factor = info.factor()
        factor[~vis.present[s]] = 0.0
        np.testing.assert_array_equal(cache.packed[:, s], packed)
        every = np.arange(pairs.size)
        np.testing.assert_array_equal(cache.factor_rows(np.full_like(every, s), every), factor)
        np.testing.assert_array_equal(cache.far_field[s], (far | ~vis.present[s]) & ~bad)


@pytest.mark.parametrize("pattern_exponent", [0.0, 1.5])
def test_unit_root_factor_is_a_square_root_of_the_path_information(
    pattern_exponent: float,
) -> None:
    """Expected-random planar paths: α·R·J from one unit root per RIS, against the per-pair
    eigh root of the same EFIM (crb.path_factor) and the path's state information."""
    doc = _preset("3-ris")
    doc["ris"] = [r | {"pattern_exponent": pattern_exponent} for r in doc["ris"]]
    sc = load_scenario(doc)
    rng = np.random.default_rng(6)
    tx = rng.uniform([-3, -3, 0], [3, 3, 0.5], (200, 3))
    rx = rng.uniform([-3, -3, 0], [3, 3, 0.5], (200, 3))
    paths, _ = path_information(sc, tx, rx, None, None)
    for p in paths[1:]:
        assert p.unit_root is not None
        a, b = p.factor(), crb.path_factor(p.efim, p.jacobian)
        f = p.state_information()
        scale = np.sqrt(np.einsum("pii->pi", f))
        norm = scale[:, :, None] * scale[:, None, :]
        ok = norm > 0
        for gram in (a.transpose(0, 2, 1) @ a, b.transpose(0, 2, 1) @ b):
            err = np.abs(gram - f)[ok] / norm[ok]
            assert np.max(err) <= FACTOR_GRAM_RTOL
        sub = np.array([3, 17, 150])
        np.testing.assert_array_equal(p.factor(sub), a[sub])


LIMITER_CHECK = """
import json
from threadpoolctl import threadpool_info, threadpool_limits
from ris_planner.runtime import blas
mine = {lib.filepath for lib in blas._controller().lib_controllers}
def threads():
    return [i["num_threads"] for i in threadpool_info() if i["filepath"] in mine]
with threadpool_limits(limits=2, user_api="blas"):
    before = threads()
    with blas.one_blas_thread():
        with blas.one_blas_thread():
            inner = threads()
        still = threads()
    after = threads()
print(json.dumps([before, inner, still, after]))
"""


def test_one_blas_thread_limits_and_restores() -> None:
    """In a fresh process (no other holder; numpy's BLAS only): one thread inside, nested
    holders share the limit, the count is restored after."""
    out = subprocess.run(
        [sys.executable, "-c", LIMITER_CHECK], check=True, capture_output=True, text=True
    )
    before, inner, still, after = json.loads(out.stdout.strip().splitlines()[-1])
    assert 2 in before  # a threaded BLAS to limit
    assert set(inner) == {1} and set(still) == {1}
    assert after == before


def test_bounds_do_not_depend_on_the_callers_blas_threads() -> None:
    sc = load_scenario(_preset("2-ris-L") | {"codebook": {"kind": "random", "seed": 0}})
    with threadpool_limits(limits=2, user_api="blas"):
        two = compute_bounds(sc)
    with threadpool_limits(limits=1, user_api="blas"):
        one = compute_bounds(sc)
    np.testing.assert_array_equal(two.fim, one.fim)
    np.testing.assert_array_equal(two.peb_rx, one.peb_rx)


def test_los_state_information_equals_the_matrix_product_bit_for_bit() -> None:
    """One channel parameter: (J_i Ĩ) J_j elementwise is the product's one rounded term."""
    sc = load_scenario(_preset("2-ris-L"))
    rng = np.random.default_rng(9)
    tx = rng.uniform([-3, -3, 0], [3, 3, 0.5], (300, 3))
    rx = rng.uniform([-3, -3, 0], [3, 3, 0.5], (300, 3))
    paths, _ = path_information(sc, tx, rx, None, None)
    for los in (paths[0], los_referenced(paths)[0][0]):
        want = los.jacobian.transpose(0, 2, 1) @ los.efim @ los.jacobian
        np.testing.assert_array_equal(los.state_information(), want)


def test_norms_equal_numpy_norm_bit_for_bit() -> None:
    rng = np.random.default_rng(10)
    for scale in (1e-6, 1.0, 1e4):
        v = rng.normal(size=(5000, 3)) * scale * np.exp(rng.normal(size=(5000, 3)))
        np.testing.assert_array_equal(geometry.norms(v), np.linalg.norm(v, axis=-1))
    v3 = rng.normal(size=(4, 6, 3))
    np.testing.assert_array_equal(geometry.norms(v3), np.linalg.norm(v3, axis=-1))
