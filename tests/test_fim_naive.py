"""The batched bounds against the naive full K×G evaluation of eq. FIM_measurement."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import bounds_rtol, small_scenario_doc
from naive import channel_parameters, naive_bounds, naive_fim_eta, naive_state_fim

from ris_planner.bounds.compute import (
    compute_bounds,
    first_block_profiles,
    kept_states,
    path_information,
)
from ris_planner.core.units import SPEED_OF_LIGHT
from ris_planner.model.scenario import load_scenario
from ris_planner.physics import codebooks

NAIVE_RTOL = 1e-9
"""Both routes sum the same O(K·G) float64 terms in different orders (relative rounding
~1e-14); the Fisher matrices themselves must agree to this."""

BATCH_RTOL = 1e-10
"""Batched vs one-pair bounds. The G̃×N profile product runs through BLAS, whose blocking
depends on the number of pairs, so the EFIMs differ at ε level (4e-16 relative); a bound
amplifies input perturbations by its scaled condition, trace(F̂⁻¹) ≤ 2e5 in this draw, so
≤ 2e5·ε ≈ 4e-11. (The earlier 1e-12 held only because the squared-form inversion rounded the
RIS contributions away under the LOS: that bound was 2.4e-5 from its 40-digit value.)"""

CROSS_PATH_RTOL = 1e-12
"""Cross-path blocks vanish exactly in exact arithmetic (Σ_i b_ℓ,i conj(b_ℓ',i) = 0); in float64
they are rounding residue relative to the diagonal blocks."""


def full_profiles(scenario, prof):  # type: ignore[no-untyped-def]
    b = codebooks.orthogonal_code_matrix(scenario.system.transmissions, len(scenario.ris))
    return [codebooks.expand_profiles(prof[i], b[:, i + 1]) for i in range(len(scenario.ris))]


def schur(f: np.ndarray, n_keep: int) -> np.ndarray:
    a, c, d = f[:n_keep, :n_keep], f[:n_keep, n_keep:], f[n_keep:, n_keep:]
    return a - c @ np.linalg.solve(d, c.T)


CASES = [(2, True), (3, True), (3, False), (4, False)]


@pytest.mark.parametrize(("n_ris", "los"), CASES)
def test_state_fim_and_bounds_equal_naive(rng: np.random.Generator, n_ris: int, los: bool) -> None:
    for _ in range(3):
        sc = load_scenario(small_scenario_doc(rng, n_ris, los))
        prof = first_block_profiles(sc)
        assert prof is not None
        g = sc.system.transmissions
        full = naive_state_fim(
            sc, sc.tx_array[0], sc.rx_array[0], full_profiles(sc, prof), np.ones(g)
        )
        res = compute_bounds(sc)
        f7 = schur(full, 7)
        np.testing.assert_allclose(
            res.fim[0], f7, rtol=NAIVE_RTOL, atol=NAIVE_RTOL * np.abs(f7).max()
        )
        for known in ([], ["clock"], ["height"], ["tx"], ["clock", "height"]):
            r = compute_bounds(sc, known=known)  # type: ignore[arg-type]
            keep = list(kept_states(known))  # type: ignore[arg-type]
            pt, pr, cb = naive_bounds(full, keep)
            tol = bounds_rtol(
                schur(
                    full[
                        np.ix_(keep + list(range(7, len(full))), keep + list(range(7, len(full))))
                    ],
                    len(keep),
                ),
                NAIVE_RTOL,
            )
            if not np.isfinite(r.peb_rx[0]):
                pytest.fail(f"unexpected singular FIM: {r.reason[0]}")
            assert r.peb_rx[0] == pytest.approx(pr, rel=tol)
            if "tx" in known:
                assert r.peb_tx is None
            else:
                assert r.peb_tx is not None and r.peb_tx[0] == pytest.approx(pt, rel=tol)
            if "clock" in known:
                assert r.ceb is None
            else:
                assert r.ceb is not None and r.ceb[0] == pytest.approx(cb, rel=tol)


def test_cross_path_blocks_vanish_and_path_blocks_match(rng: np.random.Generator) -> None:
    sc = load_scenario(small_scenario_doc(rng, 3, True))
    prof = first_block_profiles(sc)
    assert prof is not None
    eta = np.real(channel_parameters(sc, sc.tx_array[0], sc.rx_array[0], sc.system.clock_offset_m))
    i_eta = naive_fim_eta(sc, eta, full_profiles(sc, prof), np.ones(sc.system.transmissions))
    sizes = [3, 5, 5, 5]
    starts = np.cumsum([0, *sizes])
    scale = np.sqrt(np.outer(np.diag(i_eta), np.diag(i_eta)))
    paths, _ = path_information(sc, sc.tx_array, sc.rx_array, prof)
    for a in range(4):
        for b in range(4):
            blk = (i_eta / scale)[starts[a] : starts[a + 1], starts[b] : starts[b + 1]]
            if a != b:
                assert np.abs(blk).max() < CROSS_PATH_RTOL
        # the path's own block, with τ in seconds converted to path length cτ in metres
        own = i_eta[starts[a] : starts[a + 1], starts[a] : starts[a + 1]].copy()
        t_idx = 0 if a == 0 else 2
        own[t_idx, :] /= SPEED_OF_LIGHT
        own[:, t_idx] /= SPEED_OF_LIGHT
        efim = schur(own, 1 if a == 0 else 3)
        np.testing.assert_allclose(
            paths[a].efim[0], efim, rtol=NAIVE_RTOL, atol=NAIVE_RTOL * np.abs(efim).max()
        )


def test_beam_powers_match_naive(rng: np.random.Generator) -> None:
    """Per-beam powers δ², repeated over the Γ blocks, enter eq. FIM_measurement linearly."""
    sc = load_scenario(small_scenario_doc(rng, 2, True))
    prof = first_block_profiles(sc)
    assert prof is not None
    g_tilde = codebooks.block_length(sc.system.transmissions, 2)
    w = rng.uniform(0.1, 2.0, g_tilde)
    w *= g_tilde / w.sum()
    gamma = sc.system.transmissions // g_tilde
    full = naive_state_fim(
        sc, sc.tx_array[0], sc.rx_array[0], full_profiles(sc, prof), np.tile(w, gamma)
    )
    res = compute_bounds(sc, beam_powers=w)
    f7 = schur(full, 7)
    np.testing.assert_allclose(res.fim[0], f7, rtol=NAIVE_RTOL, atol=NAIVE_RTOL * np.abs(f7).max())


def test_batched_equals_one_pair_at_a_time(rng: np.random.Generator) -> None:
    sc = load_scenario(small_scenario_doc(rng, 3, True))
    tx, rx = rng.uniform(-3, 3, (7, 3)), rng.uniform(-3, 3, (7, 3))
    batch = compute_bounds(sc, tx=tx, rx=rx)
    for i in range(7):
        one = compute_bounds(sc, tx=tx[i], rx=rx[i])
        assert one.peb_rx[0] == pytest.approx(batch.peb_rx[i], rel=BATCH_RTOL)
        assert one.peb_tx is not None and batch.peb_tx is not None
        assert one.peb_tx[0] == pytest.approx(batch.peb_tx[i], rel=BATCH_RTOL)
