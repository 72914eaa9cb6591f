"""Priors and the DIR / DIR+DER codebooks (section IV-A): derivative beams against finite
differences, the unit-modulus projection against brute force, sampling statistics, γ_P
powers against the paper's coefficients, and bad input."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from pydantic import ValidationError

from ris_planner.bounds.compute import compute_bounds
from ris_planner.model import priors
from ris_planner.model.scenario import load_scenario, preset_document
from ris_planner.physics import beams, geometry

WAVELENGTH = 0.01


def der_doc(**codebook: Any) -> dict[str, Any]:
    doc = preset_document("paper-table1")
    doc["codebook"] = {"kind": "directional_derivative", "prior": {"sigma_m": 0.1}} | codebook
    return doc


def test_derivative_beams_match_finite_differences() -> None:
    """ω⁽²⁾, ω⁽³⁾ = ∂a_R*/∂ξ, ∂a_R*/∂ζ. Central differences with h = 1e-6 have truncation
    error (k·y·h)²/6 ≈ 1e-10 and rounding ≈ ε/h ≈ 2e-10 relative to k·y ≈ 1.5e3: rtol 1e-7."""
    pos = geometry.element_positions(5, 6, WAVELENGTH / 2)
    xi, zeta, h = np.array([-0.44, 1.3]), np.array([-0.5, 0.2]), 1e-6
    d_xi, d_zeta = beams.derivative_beams(pos, xi, zeta, WAVELENGTH)

    def dir_beam(x: np.ndarray, z: np.ndarray) -> np.ndarray:
        return beams.directional_beams(pos, x, z, WAVELENGTH)

    fd_xi = (dir_beam(xi + h, zeta) - dir_beam(xi - h, zeta)) / (2 * h)
    fd_zeta = (dir_beam(xi, zeta + h) - dir_beam(xi, zeta - h)) / (2 * h)
    scale = 2 * np.pi / WAVELENGTH * np.abs(pos[:, 1:]).max()
    np.testing.assert_allclose(d_xi, fd_xi, rtol=0, atol=1e-7 * scale)
    np.testing.assert_allclose(d_zeta, fd_zeta, rtol=0, atol=1e-7 * scale)


def test_projection_is_the_closest_unit_modulus_profile(rng: np.random.Generator) -> None:
    """Brute force over 7200 phases per element: the projection's distance to v is never
    larger than the grid optimum, and its phases are within half a grid step of it."""
    v = rng.normal(size=(3, 8)) + 1j * rng.normal(size=(3, 8))
    x = beams.project_unit_modulus(v, np.ones_like(v))
    phases = np.linspace(0, 2 * np.pi, 7200, endpoint=False)
    # [3, 8, 7200] distances of every candidate phase
    dist = np.abs(np.exp(1j * phases)[None, None, :] - v[..., None])
    best = np.exp(1j * phases[np.argmin(dist, axis=-1)])
    assert np.all(np.abs(x - v) <= dist.min(axis=-1) + 1e-12)
    assert np.max(np.abs(np.angle(x / best))) <= np.pi / 7200 + 1e-12
    np.testing.assert_allclose(np.abs(x), 1.0, rtol=1e-15)


def test_dir_beam_peaks_at_target_and_der_beams_null_it() -> None:
    """DIR: |ωᵀa_R| = N at (ξ, ζ), the maximum over a grid; DER (even-sized array): a null at
    (ξ, ζ) (the ±π/2 halves cancel exactly) and unit modulus."""
    pos = geometry.element_positions(10, 10, WAVELENGTH / 2)
    xi, zeta = np.array([-0.4443]), np.array([-0.5039])
    w1 = beams.directional_beams(pos, xi, zeta, WAVELENGTH)
    d_xi, d_zeta = beams.derivative_beams(pos, xi, zeta, WAVELENGTH)
    w2, w3 = beams.project_unit_modulus(d_xi, w1), beams.project_unit_modulus(d_zeta, w1)
    a = geometry.steering_vector(pos, xi, zeta, WAVELENGTH)[0]
    assert abs(w1[0] @ a) == pytest.approx(100, rel=1e-12)
    assert abs(w2[0] @ a) < 1e-9 and abs(w3[0] @ a) < 1e-9
    gx, gz = np.meshgrid(np.linspace(-2, 2, 81), np.linspace(-2, 2, 81))
    grid = geometry.steering_vector(pos, gx.ravel(), gz.ravel(), WAVELENGTH)
    assert np.max(np.abs(grid @ w1[0])) <= 100 + 1e-9
    # the DER beam splits along ξ: its two largest lobes straddle the target in ξ
    pattern = np.abs(grid @ w2[0]).reshape(gx.shape)
    iz = int(np.argmin(np.abs(gz[:, 0] - zeta[0])))
    row = pattern[iz]
    left, right = row[gx[0] < xi[0]].max(), row[gx[0] > xi[0]].max()
    assert min(left, right) > 0.5 * 100


def test_prior_samples_are_seeded_and_have_the_prior_statistics() -> None:
    """4096 samples: mean within 5σ/√n, covariance within 5·√(2/n) of Σ̄ (Gaussian)."""
    cov3 = np.array([[0.04, 0.01, 0.0], [0.01, 0.09, 0.02], [0.0, 0.02, 0.01]])
    doc = der_doc(prior={"covariance": cov3.tolist(), "samples": 21, "seed": 3})
    sc = load_scenario(doc)
    prior = sc.codebook.prior  # type: ignore[union-attr]
    tx1, rx1 = priors.sample_pairs(prior, sc, 4096)
    tx2, _ = priors.sample_pairs(prior, sc, 4096)
    np.testing.assert_array_equal(tx1, tx2)
    s = np.concatenate([tx1, rx1], axis=1)
    mean = np.array([-2, -4, 0, 2, 3, 0.0])
    full = np.kron(np.eye(2), cov3)
    sd = np.sqrt(np.diag(full))
    assert np.all(np.abs(s.mean(axis=0) - mean) < 5 * sd / 64)
    emp = np.cov(s.T)
    assert np.all(np.abs(emp - full) < 5 * np.sqrt(2 / 4096) * np.outer(sd, sd))


def test_singular_covariance_samples_stay_in_its_range() -> None:
    """A PSD but singular 6×6 covariance (RX exactly known): RX samples equal the mean."""
    cov = np.zeros((6, 6))
    cov[:3, :3] = 0.25 * np.eye(3)
    sc = load_scenario(der_doc(prior={"covariance": cov.tolist()}))
    tx, rx = priors.sample_pairs(sc.codebook.prior, sc, 50)  # type: ignore[union-attr]
    np.testing.assert_allclose(rx, np.array([[2, 3, 0.0]] * 50), atol=1e-12)
    assert np.std(tx) > 0.1


@pytest.mark.parametrize("gamma_p", [0.0, 0.1, 0.5, 5.0])
def test_gamma_p_powers_are_the_papers_coefficients(gamma_p: float) -> None:
    """Whole triples: DIR power 3/(1+2γ²), DER power 3γ²/(1+2γ²) (eq. opt_formulation_3)."""
    types = np.tile([0, 1, 2], 16)
    p = beams.gamma_p_powers(types, gamma_p)
    g2 = gamma_p**2
    np.testing.assert_allclose(p[types == 0], 3 / (1 + 2 * g2), rtol=1e-14)
    np.testing.assert_allclose(p[types > 0], 3 * g2 / (1 + 2 * g2), rtol=1e-14, atol=1e-300)
    assert p.sum() == pytest.approx(48, rel=1e-14)


def test_codebook_layout_and_bounds_through_the_explicit_route() -> None:
    """The DIR+DER first block (G̃ = 64, 21 triples + 1 cycled beam) gives the same bounds as
    the same phases passed as an explicit codebook, and the document's γ_P equals passing its
    powers as beam_powers."""
    doc = der_doc(gamma_p=0.5)
    sc = load_scenario(doc)
    block = beams.codebook_block(sc)
    assert block.beam_types.tolist()[:6] == [0, 1, 2, 0, 1, 2]
    assert block.beam_types[63] == 0 and block.sample_index[63] == 0
    assert block.tx.shape == (21, 3)
    explicit = doc | {
        "codebook": {"kind": "explicit", "phases": [np.angle(p).tolist() for p in block.profiles]}
    }
    powers = beams.gamma_p_powers(block.beam_types, 0.5)
    got = compute_bounds(sc)
    ref = compute_bounds(load_scenario(explicit), beam_powers=powers)
    np.testing.assert_allclose(got.peb_rx, ref.peb_rx, rtol=1e-9)
    np.testing.assert_allclose(got.fim, ref.fim, rtol=1e-9)
    uniform = compute_bounds(load_scenario(explicit))
    assert abs(uniform.peb_rx[0] - got.peb_rx[0]) > 1e-3 * got.peb_rx[0]


@pytest.mark.parametrize(
    ("prior", "field"),
    [
        ({}, "exactly one of sigma_m or covariance"),
        ({"sigma_m": 0.1, "samples": 0}, "samples"),
        ({"sigma_m": -1.0}, "sigma_m"),
        ({"covariance": [[1, 0, 0], [0, -1, 0], [0, 0, 1]]}, "positive semidefinite"),
        ({"covariance": [[1, 0.5, 0], [0, 1, 0], [0, 0, 1]]}, "symmetric"),
        ({"covariance": [[1, 0], [0, 1]]}, "3×3 or 6×6"),
        ({"sigma_m": 0.1, "samples": 22}, "first block holds G/Γ = 64"),
        ({"sigma_m": 0.1, "covariance": np.eye(3).tolist()}, "exactly one"),
    ],
)
def test_bad_prior_is_a_clear_error(prior: dict[str, Any], field: str) -> None:
    with pytest.raises(ValidationError, match=field):
        load_scenario(der_doc(prior=prior))


def test_bad_codebook_documents() -> None:
    with pytest.raises(ValidationError, match="gamma_p"):
        load_scenario(der_doc(gamma_p=-0.5))
    with pytest.raises(ValidationError, match="prior"):
        load_scenario(der_doc() | {"codebook": {"kind": "directional"}})
    tiny = der_doc() | {"system": {"transmissions": 6}}  # Γ = 3, G̃ = 2 < 3 beams per sample
    with pytest.raises(ValidationError, match="first block holds only G/Γ = 2"):
        load_scenario(tiny)
    batch = der_doc() | {"tx": [[-2, -4, 0], [0, -4, 0]], "rx": [[2, 3, 0], [1, 3, 0]]}
    with pytest.raises(ValidationError, match="tx_mean is required"):
        load_scenario(batch)
    ok = batch | {
        "codebook": {
            "kind": "directional",
            "prior": {"sigma_m": 0.1, "tx_mean": [-2, -4, 0], "rx_mean": [2, 3, 0], "samples": 64},
        }
    }
    assert compute_bounds(load_scenario(ok)).peb_rx.shape == (2,)


def test_odd_array_der_beams_keep_the_dir_phase_on_the_centre_line() -> None:
    """5×5: the centre column (y = 0) has no DER phase; it keeps ω⁽¹⁾, the rest is ω⁽¹⁾·(∓j)."""
    pos = geometry.element_positions(5, 5, WAVELENGTH / 2)
    xi, zeta = np.array([0.3]), np.array([-0.2])
    w1 = beams.directional_beams(pos, xi, zeta, WAVELENGTH)
    d_xi, _ = beams.derivative_beams(pos, xi, zeta, WAVELENGTH)
    w2 = beams.project_unit_modulus(d_xi, w1)[0]
    centre = np.isclose(pos[:, 1], 0.0, atol=1e-15)
    assert centre.sum() == 5
    np.testing.assert_allclose(w2[centre], w1[0, centre], rtol=1e-15)
    side = np.sign(pos[~centre, 1])
    np.testing.assert_allclose(w2[~centre], w1[0, ~centre] * (-1j * side), rtol=1e-14)
