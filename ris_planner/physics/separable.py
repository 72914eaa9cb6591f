"""Designed beams of a planar array as column × row factors, and their transmission Gram in
O(columns + rows) per pair and beam (docs/concepts/district-physics.md, "Beams").

On the element grid of a RIS (element n = r·cols + c at local y_c = (c − (C−1)/2)·d,
z_r = (r − (R−1)/2)·d) the steering vector of eq. RIS_equivalent_gain_xi_zeta factorises,
a_R,n(ξ, ζ) = e^{jk y_c ξ} · e^{jk z_r ζ}, and so do the DIR beam ω⁽¹⁾ = a_R*(ξ₀, ζ₀) of eq.
sum_diff_beam_1 and the unit-modulus DER beams of eqs. sum_diff_beam_2/3 (their projection
:func:`ris_planner.physics.beams.project_unit_modulus` multiplies ω⁽¹⁾ by −j·sign(y_c) or
−j·sign(z_r), the DIR phase kept on a centre line). For such a profile ω_n = col_c · row_r the
transmission products of eq. FIM_measurement separate:

    ωᵀ a_R = X(ξ)·Z(ζ),  ωᵀ ∂a_R/∂ξ = X′(ξ)·Z(ζ),  ωᵀ ∂a_R/∂ζ = X(ξ)·Z′(ζ),

with X(ξ) = Σ_c col_c e^{jk y_c ξ}, X′(ξ) = Σ_c col_c jk y_c e^{jk y_c ξ} and likewise Z, Z′
over the rows: one [G̃, C] @ [C, P] and one [G̃, R] @ [R, P] product per block of pairs
instead of the [3G̃, N] @ [N, P] of :func:`ris_planner.physics.fim.planar_transmission_gram`
(64 + 64 against 4096 multiply-adds per pair and beam on a 64 × 64 RIS). The two routes give
the same Gram to rounding (tests/test_separable_beams.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ris_planner.physics.beams import BEAM_DER_XI, BEAM_DER_ZETA, ZERO_AMPLITUDE_RTOL

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
IntArray = NDArray[np.int_]

PAIR_CHUNK = 4096
"""Pairs per block of :func:`separable_gram` (the [C + R, P] phasors and [G̃, P] products of
one block stay in cache)."""


def grid_axes(rows: int, cols: int, spacing: float) -> tuple[FloatArray, FloatArray]:
    """(y_c [C], z_r [R]) of the element grid (as :func:`ris_planner.physics.geometry.
    element_positions` lays it out)."""
    yc = (np.arange(cols) - (cols - 1) / 2) * spacing
    zr = (np.arange(rows) - (rows - 1) / 2) * spacing
    return np.asarray(yc, dtype=float), np.asarray(zr, dtype=float)


@dataclass(frozen=True)
class SeparableBlock:
    """A first block of profiles that factorise over the array's columns and rows:
    ω_g[r·C + c] = cols[g, c] · rows[g, r]."""

    cols: ComplexArray
    """[G̃, C] column factors."""
    rows: ComplexArray
    """[G̃, R] row factors."""
    beam_types: IntArray
    """[G̃] BEAM_DIR / BEAM_DER_XI / BEAM_DER_ZETA of each slot."""

    def profiles(self) -> ComplexArray:
        """[G̃, N] the profiles element by element (element n = r·cols + c)."""
        g = self.cols.shape[0]
        return np.asarray((self.rows[:, :, None] * self.cols[:, None, :]).reshape(g, -1))


def sign_factor(axis: FloatArray) -> ComplexArray:
    """[n] −j·sign(u) along an axis, 1 on its centre line (|u| at rounding level): the
    unit-modulus projection of a DER beam's factor jk·u (:func:`ris_planner.physics.beams.
    project_unit_modulus`)."""
    span = float(np.max(np.abs(axis))) if axis.size else 0.0
    centre = np.abs(axis) <= ZERO_AMPLITUDE_RTOL * span
    return np.where(centre, 1.0 + 0j, -1j * np.sign(axis))


def beam_block(
    yc: FloatArray,
    zr: FloatArray,
    xi: FloatArray,
    zeta: FloatArray,
    beam_types: IntArray,
    wavelength: float,
) -> SeparableBlock:
    """The block of beams pointing at spatial frequencies (ξ₀, ζ₀) [G̃]: slot g the DIR beam of
    eq. sum_diff_beam_1 or a projected DER beam of eqs. sum_diff_beam_2/3 (``beam_types``)."""
    k = 2 * np.pi / wavelength
    cols = np.exp(-1j * k * np.multiply.outer(xi, yc))  # [G̃, C]
    rows = np.exp(-1j * k * np.multiply.outer(zeta, zr))  # [G̃, R]
    cols[beam_types == BEAM_DER_XI] *= sign_factor(yc)
    rows[beam_types == BEAM_DER_ZETA] *= sign_factor(zr)
    return SeparableBlock(cols, rows, np.asarray(beam_types))


def separable_gram(
    block: SeparableBlock,
    weights: FloatArray,
    xi: FloatArray,
    zeta: FloatArray,
    yc: FloatArray,
    zr: FloatArray,
    wavelength: float,
) -> ComplexArray:
    """Q [P, 3, 3] = Σ_g w_g conj(t_g) t_gᵀ of the planar model, t_g = ωᵀ[∂a_R/∂ξ, ∂a_R/∂ζ,
    a_R] (the layout of :func:`ris_planner.physics.fim.transmission_gram`), for the pairs'
    spatial frequencies ξ, ζ [P] and the block's beam powers ``weights`` [G̃] (δ²).

    The distinct factors only (a DIR+DER sample's DIR and DER_ζ beams share their column
    factor, its DIR and DER_ξ beams their row factor): one [2U, C] @ [C, p] product per block
    of pairs for X and X′ over the U distinct columns, likewise rows; the phasors of the
    uniform grid by a running product along the axis (:func:`grid_phasors`)."""
    k = 2 * np.pi / wavelength
    out = np.empty((xi.size, 3, 3), dtype=complex)
    col_u, col_of = np.unique(block.cols, axis=0, return_inverse=True)
    row_u, row_of = np.unique(block.rows, axis=0, return_inverse=True)
    col_of, row_of = col_of.reshape(-1), row_of.reshape(-1)
    n_col, n_row = col_u.shape[0], row_u.shape[0]
    cy = np.concatenate([col_u, col_u * (1j * k * yc)])  # [2U, C]: X and X′
    cz = np.concatenate([row_u, row_u * (1j * k * zr)])
    w = np.asarray(weights, dtype=float)[:, None]
    for s in range(0, xi.size, PAIR_CHUNK):
        e = min(xi.size, s + PAIR_CHUNK)
        xx = cy @ grid_phasors(yc, xi[s:e], k)  # [2U, p]
        zz = cz @ grid_phasors(zr, zeta[s:e], k)
        x, x_d = xx[col_of], xx[n_col + col_of]  # [G̃, p]
        z, z_d = zz[row_of], zz[n_row + row_of]
        t = (x_d * z, x * z_d, x * z)
        conj = [np.conj(v) * w for v in t]
        q = out[s:e]
        for i in range(3):
            q[:, i, i] = np.einsum("gp,gp->p", conj[i], t[i]).real
            for j in range(i + 1, 3):
                q[:, i, j] = np.einsum("gp,gp->p", conj[i], t[j])
                q[:, j, i] = np.conj(q[:, i, j])
    return out


def grid_phasors(axis: FloatArray, freq: FloatArray, k: float) -> ComplexArray:
    """[n, p] e^{jk u_i f} on a uniform axis u [n] for the frequencies f [p]: the first row
    by its exponential, the others by the running product of the step's phasor e^{jk Δu f}
    (n − 1 products per pair instead of n exponentials; the phase error grows by one rounding
    per step, n·ε at the far end)."""
    out = np.empty((axis.size, freq.size), dtype=complex)
    if axis.size == 0:
        return out
    out[0] = np.exp(1j * k * axis[0] * freq)
    if axis.size > 1:
        out[1:] = np.exp(1j * k * (axis[1] - axis[0]) * freq)
        np.cumprod(out, axis=0, out=out)
    return out
