"""Warnings that state a result's modelling assumptions (bounds and plans, ``"warnings"``).

* Expected-random optimism: the CRB of the expected FIM (``expected_random``) is below the
  expected CRB of random codebooks (Jensen); the gap grows as G/Γ shrinks.
* Grating lobes: element spacing above λ/2 makes the spatial frequencies ξ, ζ ambiguous
  modulo λ/d, which the local (CRB) bound does not see.
* Near field: pairs inside a RIS's Fraunhofer distance are scored with the far-field model.
"""

from __future__ import annotations

from collections.abc import Sequence

from ris_planner.model.scenario import RIS
from ris_planner.physics import codebooks

EXPECTED_RANDOM_MIN_BLOCK = 16
"""Below this G/Γ the expected-random bound is more than ~10 % optimistic. Measured with
``examples/codebook_optimism.py`` (2-RIS L, 100 Fig. 10 pairs, 10 seeds; median over pairs of
mean_seeds PEB_R(random) / PEB_R(expected)): 8.2 at G/Γ = 2, 1.40 at 4, 1.15 at 8, 1.065 at
16, 1.030 at 32, 1.016 at 64."""

NEAR_FIELD_MAJORITY = 0.5
"""Near-field advice when the far-field pairs are a minority (weighted fraction below this)."""


def expected_random_warning(transmissions: int, n_ris: int) -> str | None:
    """The optimism warning for ``expected_random`` with G transmissions and L RISs, if any."""
    g_tilde = codebooks.block_length(transmissions, n_ris)
    if g_tilde >= EXPECTED_RANDOM_MIN_BLOCK:
        return None
    gamma = transmissions // g_tilde
    return (
        f"expected_random optimism: G/Γ = {transmissions}/{gamma} = {g_tilde} beams per RIS"
        f" and block is below {EXPECTED_RANDOM_MIN_BLOCK}; the bound of the expected FIM is"
        " then more than ~10 % below what random codebooks reach on average (1.15× at G/Γ ="
        " 8, 1.4× at 4); use more transmissions or evaluate 'random' codebooks"
    )


def spacing_warnings(ris: Sequence[RIS], wavelength: float, names: Sequence[str]) -> list[str]:
    """A grating-lobe warning for each RIS whose element spacing exceeds λ/2."""
    out = []
    for r, name in zip(ris, names, strict=True):
        d = r.element_spacing(wavelength)
        if d > wavelength / 2 * (1 + 1e-9):
            out.append(
                f"grating lobes: {name} has element spacing {d:.4g} m > λ/2 = {wavelength / 2:.4g}"
                f" m; ξ, ζ are ambiguous modulo λ/d = {wavelength / d:.3g}, which the CRB does"
                " not see (it rewards the larger aperture)"
            )
    return out


def near_field_warning(far_fraction: float) -> str | None:
    """Advice when far-field pairs are a minority (the planar model is used for all pairs)."""
    if far_fraction >= NEAR_FIELD_MAJORITY:
        return None
    return (
        f"near field: only {100 * far_fraction:.0f} % of the pairs are in the far field of every"
        " RIS (d_T d_R/(d_T + d_R) ≥ 2D²/λ); the planar (far-field) model is approximate for the"
        " others: use system.wavefront = 'spherical'"
    )
