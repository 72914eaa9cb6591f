"""Designed beams as column × row factors (docs/concepts/district-physics.md, "Beams"): the
factorised DIR and DER beams are the element-by-element ones of the codebook design, and their
transmission Gram is the generic route's (an [3G̃, N] @ [N, P] product) to rounding."""

from __future__ import annotations

import numpy as np
import pytest
from tolerance import assert_close

from ris_planner.model.scenario import RIS
from ris_planner.physics import fim, geometry
from ris_planner.physics.beams import (
    BEAM_DER_XI,
    BEAM_DER_ZETA,
    BEAM_DIR,
    beam_layout,
    sample_beams,
)
from ris_planner.physics.separable import beam_block, grid_axes, separable_gram

WAVELENGTH = 3e8 / 30e9


@pytest.mark.parametrize(("rows", "cols"), [(8, 8), (7, 10), (16, 5)])
def test_factorised_beams_are_the_designed_ones(rows: int, cols: int) -> None:
    """Odd and even grids: the DIR beam and both projected DER beams, element by element,
    equal :func:`sample_beams`' (the same phases: a few roundings of one exponential)."""
    rng = np.random.default_rng(1)
    ris = RIS(position=[0, 0, 3], orientation=[0.3, -0.2, 0.1], rows=rows, cols=cols)
    tx = rng.uniform([0, -5, 0], [25, 20, 2], size=(4, 3))
    rx = rng.uniform([0, -5, 0], [25, 20, 2], size=(4, 3))
    geo = geometry.ris_path_geometry(tx, rx, ris.position, ris.orientation)
    want = sample_beams(ris, tx, rx, WAVELENGTH, True)  # [S, 3, N]
    yc, zr = grid_axes(rows, cols, ris.element_spacing(WAVELENGTH))
    types = np.tile([BEAM_DIR, BEAM_DER_XI, BEAM_DER_ZETA], 4)
    block = beam_block(yc, zr, np.repeat(geo.xi, 3), np.repeat(geo.zeta, 3), types, WAVELENGTH)
    got = block.profiles().reshape(4, 3, -1)
    assert_close(got.real, want.real, ulps=64, atol=1e-12)
    assert_close(got.imag, want.imag, ulps=64, atol=1e-12)
    assert np.allclose(np.abs(got), 1.0, rtol=0, atol=1e-12)  # unit modulus


def test_the_factorised_gram_is_the_generic_one() -> None:
    """64 × 64 elements, a DIR+DER block of 30 beams with γ_P powers, 500 pairs at random
    spatial frequencies: Q by the factorised products equals Q by the element-by-element
    product (both sum the same G̃·N terms; the tolerance is their reordering, N + G̃ roundings,
    relative to the largest entry of each pair's Q)."""
    rng = np.random.default_rng(2)
    rows = cols = 64
    ris = RIS(position=[0, 0, 3], orientation=[0, 0, 0], rows=rows, cols=cols)
    spacing = ris.element_spacing(WAVELENGTH)
    yc, zr = grid_axes(rows, cols, spacing)
    index, types = beam_layout(30, 10, 3)
    xi0, zeta0 = rng.uniform(-1.5, 1.5, 10), rng.uniform(-1.5, 1.5, 10)
    block = beam_block(yc, zr, xi0[index], zeta0[index], types, WAVELENGTH)
    powers = np.where(types == BEAM_DIR, 1.0, 0.25)
    powers *= types.size / powers.sum()
    # half the pairs near the beams' own directions (large products), half anywhere
    near = rng.integers(0, 10, 250)
    xi = np.concatenate([xi0[near] + rng.normal(0, 1e-3, 250), rng.uniform(-1.9, 1.9, 250)])
    zeta = np.concatenate([zeta0[near] + rng.normal(0, 1e-3, 250), rng.uniform(-1.9, 1.9, 250)])
    got = separable_gram(block, powers, xi, zeta, yc, zr, WAVELENGTH)
    pos = geometry.element_positions(rows, cols, spacing)
    want = fim.planar_transmission_gram(block.profiles(), pos, xi, zeta, WAVELENGTH, powers)
    scale = np.abs(want).reshape(len(xi), -1).max(axis=1)[:, None, None]
    ulps = rows * cols + 30
    assert_close((got / scale).real, (want / scale).real, ulps=ulps, atol=ulps * 2.3e-16)
    assert_close((got / scale).imag, (want / scale).imag, ulps=ulps, atol=ulps * 2.3e-16)
