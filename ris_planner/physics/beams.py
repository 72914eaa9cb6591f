"""DIR and DIR+DER RIS profiles from a position prior (section IV-A).

* DIR beam (eq. RIS_profile_sum_beam / sum_diff_beam_1): ω⁽¹⁾ = a_R*(ξ, ζ), which makes
  ω⁽¹⁾ᵀ a_R(ξ, ζ) = N, the largest gain a unit-modulus profile can have at (ξ, ζ).
* DER beams (eqs. sum_diff_beam_2, sum_diff_beam_3): ω⁽²⁾ = ∂a_R*/∂ξ = ω⁽¹⁾ ⊙ (−jk·y),
  ω⁽³⁾ = ω⁽¹⁾ ⊙ (−jk·z), k = 2π/λ. They are not unit modulus; the paper maps them to the
  closest unit-amplitude profile by gradient projection. For min_x ‖x − v‖² over |x_n| = 1,
  one gradient step of length 1/2 from any start lands on v and the projection onto the
  unit-modulus set gives x_n = v_n/|v_n|, a fixed point of the iteration — so the gradient
  projection's answer is that closed form (:func:`project_unit_modulus`). For the DER beams
  it flips the DIR phase by ∓π/2 on the two halves of the array (a monopulse difference beam
  with a null at (ξ, ζ)). Elements where v_n = 0 (the centre column/row of an odd-sized
  array) have no closest phase; they keep the DIR phase.
* Codebook (eqs. DIR_codebook, DER_codebook): beams per sampled pair in the order
  [ω⁽¹⁾₁, ω⁽²⁾₁, ω⁽³⁾₁, ω⁽¹⁾₂, …]; when the beams are fewer than G̃ the first block cycles
  through them (the paper's G = 192, L = 2 gives G̃ = 64, not a multiple of 3).
* Power control by γ_P (eq. opt_formulation_3): DIR beams get amplitude ∝ 1, DER beams
  ∝ γ_P, normalised so the first block's powers sum to G̃ (‖δ‖² = G over the Γ blocks); with
  whole triples this is the paper's 3/(1+2γ_P²) and 3γ_P²/(1+2γ_P²).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.errors import RisPlannerError
from ris_planner.model import priors
from ris_planner.model.scenario import (
    RIS,
    DirectionalCodebook,
    DirectionalDerivativeCodebook,
    Scenario,
)
from ris_planner.physics import codebooks, geometry

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

BEAM_DIR, BEAM_DER_XI, BEAM_DER_ZETA = 0, 1, 2
"""Beam types in :attr:`CodebookBlock.beam_types`."""

ZERO_AMPLITUDE_RTOL = 1e-12
"""An element of a DER beam with |v_n| below this fraction of max|v| has no defined phase
(it lies on the array's centre line, y or z = 0 up to rounding of the element grid)."""


def ris_element_positions(ris: RIS, wavelength: float) -> FloatArray:
    """Local element positions of a RIS, [N, 3] (spacing λ/2 unless given)."""
    return geometry.element_positions(ris.rows, ris.cols, ris.element_spacing(wavelength))


def directional_beams(
    positions: FloatArray, xi: FloatArray, zeta: FloatArray, wavelength: float
) -> ComplexArray:
    """ω⁽¹⁾ = a_R*(ξ, ζ) (eq. sum_diff_beam_1), [S, N] for S target spatial frequencies."""
    return np.conj(geometry.steering_vector(positions, xi, zeta, wavelength))


def derivative_beams(
    positions: FloatArray, xi: FloatArray, zeta: FloatArray, wavelength: float
) -> tuple[ComplexArray, ComplexArray]:
    """The raw DER beams ∂a_R*/∂ξ and ∂a_R*/∂ζ (eqs. sum_diff_beam_2, 3), each [S, N]."""
    k = 2 * np.pi / wavelength
    w1 = directional_beams(positions, xi, zeta, wavelength)
    return w1 * (-1j * k * positions[None, :, 1]), w1 * (-1j * k * positions[None, :, 2])


def project_unit_modulus(v: ComplexArray, fallback: ComplexArray) -> ComplexArray:
    """Closest unit-modulus profile to v elementwise, v_n/|v_n|; ``fallback`` where v_n ≈ 0.

    v, fallback : [S, N] (fallback already unit modulus).
    """
    mag = np.abs(v)
    zero = mag <= ZERO_AMPLITUDE_RTOL * mag.max(axis=-1, keepdims=True)
    return np.where(zero, fallback, v / np.where(zero, 1.0, mag))


@dataclass(frozen=True)
class CodebookBlock:
    """The first block of a prior-based codebook.

    profiles : per RIS [G̃, N_ℓ] unit-modulus profiles; beam_types : [G̃] BEAM_DIR/DER_*;
    sample_index : [G̃] which sampled pair each beam serves; tx, rx : [S, 3] the samples.
    """

    profiles: list[ComplexArray]
    beam_types: NDArray[np.int_]
    sample_index: NDArray[np.int_]
    tx: FloatArray
    rx: FloatArray


def beam_layout(
    g_tilde: int, samples: int, per_sample: int
) -> tuple[NDArray[np.int_], NDArray[np.int_]]:
    """(sample_index, beam_types), each [G̃]: slot g̃ holds beam (g̃ mod S·b) of eq.
    DER_codebook's order, b = beams per sample (the block cycles through the codebook)."""
    if samples < 1 or samples * per_sample > g_tilde:
        raise RisPlannerError(
            f"{samples} samples × {per_sample} beams do not fit the first block G/Γ = {g_tilde}"
        )
    sample_index, beam_types = np.divmod(np.arange(g_tilde) % (samples * per_sample), per_sample)
    return sample_index, beam_types


def _layout(scenario: Scenario) -> tuple[int, NDArray[np.int_], NDArray[np.int_]]:
    cb = scenario.codebook
    if not isinstance(cb, DirectionalCodebook | DirectionalDerivativeCodebook):
        raise RisPlannerError(f"codebook {cb.kind!r} is not built from a prior")
    per_sample = cb.beams_per_sample
    g_tilde = codebooks.block_length(scenario.system.transmissions, len(scenario.ris))
    samples = cb.prior.samples or g_tilde // per_sample
    return (samples, *beam_layout(g_tilde, samples, per_sample))


def codebook_block(scenario: Scenario) -> CodebookBlock:
    """The first block of a ``directional`` or ``directional_derivative`` codebook."""
    samples, sample_index, beam_types = _layout(scenario)
    cb = scenario.codebook
    assert isinstance(cb, DirectionalCodebook | DirectionalDerivativeCodebook)
    with_der = isinstance(cb, DirectionalDerivativeCodebook)
    tx, rx = priors.sample_pairs(cb.prior, scenario, samples)
    wavelength = scenario.system.wavelength
    profiles = [
        sample_beams(ris, tx, rx, wavelength, with_der)[sample_index, beam_types]
        for ris in scenario.ris
    ]
    return CodebookBlock(profiles, beam_types, sample_index, tx, rx)


def sample_beams(
    ris: RIS, tx: FloatArray, rx: FloatArray, wavelength: float, with_der: bool
) -> ComplexArray:
    """The beams one RIS points at sampled pairs (tx, rx : [S, 3]) in eq. DER_codebook order:
    [S, 1, N] DIR beams, or [S, 3, N] DIR and the two projected DER beams per pair."""
    pos = ris_element_positions(ris, wavelength)
    geo = geometry.ris_path_geometry(tx, rx, ris.position, ris.orientation)
    w1 = directional_beams(pos, geo.xi, geo.zeta, wavelength)
    if not with_der:
        return np.asarray(w1[:, None, :])
    d_xi, d_zeta = derivative_beams(pos, geo.xi, geo.zeta, wavelength)
    return np.stack([w1, project_unit_modulus(d_xi, w1), project_unit_modulus(d_zeta, w1)], axis=1)


def gamma_p_powers(beam_types: NDArray[np.int_], gamma_p: float) -> FloatArray:
    """Beam powers δ² of the first block for the DER/DIR amplitude ratio γ_P, [G̃], sum G̃.

    DIR beams get power ∝ 1 and DER beams ∝ γ_P² (eq. opt_formulation_3's coefficients
    √3/√(1+2γ_P²) and √3γ_P/√(1+2γ_P²) for whole triples).
    """
    if not np.isfinite(gamma_p) or gamma_p < 0:
        raise RisPlannerError(f"gamma_p must be a finite number ≥ 0, got {gamma_p}")
    raw = np.where(beam_types == BEAM_DIR, 1.0, float(gamma_p) ** 2)
    return np.asarray(raw * (beam_types.size / raw.sum()))


def codebook_beam_powers(scenario: Scenario) -> FloatArray | None:
    """The powers the document's codebook prescribes (γ_P of a DIR+DER codebook), or None."""
    cb = scenario.codebook
    if not isinstance(cb, DirectionalDerivativeCodebook) or cb.gamma_p is None:
        return None
    return gamma_p_powers(_layout(scenario)[2], cb.gamma_p)
