"""Each candidate site's designed first block: DIR or DIR+DER beams pointing at the pairs the
site serves, with the γ_P power split (section IV-A; docs/concepts/district-physics.md,
"Beams").

A site's beams are designed from its own served pairs, the map analogue of the prior of eq.
DIR_codebook (as :func:`ris_planner.planning.beams.design_beams` designs a layout's): pairs
drawn ∝ their plan weight among those the site serves (both UEs in its field of view with
clear legs), seeded per site, G̃ = G/Γ samples for DIR (one beam each) and ⌊G̃/3⌋ for DIR+DER
(a DIR and two DER beams each, eq. DER_codebook), the block cycling through them
(:func:`ris_planner.physics.beams.beam_layout`). The powers are γ_P's (eq.
opt_formulation_3, :func:`ris_planner.physics.beams.gamma_p_powers`): per slot of the block,
so the same for every RIS – δ is the transmitting UE's power per transmission, which every RIS
the pair hears shares. The beams are column × row factors
(:mod:`ris_planner.physics.separable`): a site's information on its pairs costs O(columns +
rows) per pair and beam.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.errors import RisPlannerError
from ris_planner.model.plan import PlanCodebook
from ris_planner.model.scenario import RIS
from ris_planner.physics import geometry
from ris_planner.physics.beams import beam_layout, gamma_p_powers
from ris_planner.physics.separable import SeparableBlock, beam_block, grid_axes

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int_]


@dataclass(frozen=True)
class SiteBeams:
    """One site's designed first block."""

    block: SeparableBlock
    powers: FloatArray
    """[G̃] beam powers δ² (sum G̃)."""
    samples: IntArray
    """[S] the served pairs (indices into the caller's arrays) its beams point at."""
    xi: FloatArray
    """[G̃] the spatial frequency ξ₀ each slot's beam points at."""
    zeta: FloatArray
    """[G̃] likewise ζ₀."""


def beams_per_block(transmissions: int, blocks: int, kind: str) -> int:
    """G̃ = G/Γ, checked for the codebook's beams per sample (3 for DIR+DER)."""
    g_tilde = transmissions // blocks
    need = 3 if kind == "directional_derivative" else 1
    if g_tilde < need:
        raise RisPlannerError(
            f"a {kind} codebook needs G/Γ ≥ {need} beams per block; G = {transmissions} with"
            f" Γ = {blocks} blocks gives {g_tilde}: raise system.transmissions or lower"
            " codebook.blocks"
        )
    return g_tilde


def design_site(
    ris: RIS,
    tx: FloatArray,
    rx: FloatArray,
    weights: FloatArray,
    spec: PlanCodebook,
    g_tilde: int,
    wavelength: float,
    rng: np.random.Generator,
) -> SiteBeams:
    """The site's block for its served pairs (tx, rx [P, 3], weights [P] > 0 where a pair may
    be drawn): samples ∝ weight (with replacement only when there are fewer pairs than
    samples), then DIR or DIR+DER beams at their spatial frequencies."""
    per_sample = 3 if spec.kind == "directional_derivative" else 1
    n_samples = g_tilde // per_sample
    live = np.flatnonzero(weights > 0)
    if live.size == 0:
        raise RisPlannerError("a site's beams need a served pair of positive weight")
    p = weights[live] / weights[live].sum()
    pick = live[rng.choice(live.size, size=n_samples, replace=live.size < n_samples, p=p)]
    index, types = beam_layout(g_tilde, n_samples, per_sample)
    geo = geometry.ris_path_geometry(tx[pick], rx[pick], ris.position, ris.orientation)
    yc, zr = grid_axes(ris.rows, ris.cols, ris.element_spacing(wavelength))
    xi, zeta = geo.xi[index], geo.zeta[index]
    block = beam_block(yc, zr, xi, zeta, types, wavelength)
    return SiteBeams(block, slot_powers(spec, types), np.asarray(pick), xi, zeta)


def slot_powers(spec: PlanCodebook, beam_types: IntArray) -> FloatArray:
    """[G̃] the powers δ² of the block's slots: γ_P's split for DIR+DER, uniform for DIR."""
    if spec.kind == "directional_derivative":
        return gamma_p_powers(beam_types, spec.gamma)
    return np.ones(beam_types.size)
