"""RIS codebooks and the time-orthogonal profile expansion (section IV-A).

A codebook supplies the first block of profiles, G̃ = G/Γ beams per RIS; the full sequence of
G profiles follows eq. orthogonal_profiles, ω_{ℓ,(i−1)G̃+g̃} = b*_{ℓ,i} ω_{ℓ,g̃}, with B the
first L+1 columns of the Γ-point DFT matrix (column 0, all ones, for the LOS path) and Γ the
smallest divisor of G that is ≥ L+1 (docs/concepts/conventions.md).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from ris_planner.model.profiles import block_count, block_length

__all__ = [
    "block_count",
    "block_length",
]  # the profile structure, re-exported for the codebooks' users

ComplexArray = NDArray[np.complex128]


def orthogonal_code_matrix(transmissions: int, n_ris: int) -> ComplexArray:
    """B: the first L+1 columns of the Γ-point DFT matrix, [Γ, L+1]; |B_ij| = 1.

    B^H B = Γ·I (orthogonal columns; the paper's normalisation B^H B = I cannot hold with unit
    amplitude entries, and only the orthogonality matters).
    """
    gamma = block_count(transmissions, n_ris)
    i = np.arange(gamma)[:, None]
    col = np.arange(n_ris + 1)[None, :]
    return np.asarray(np.exp(-2j * np.pi * i * col / gamma))


def expand_profiles(first_block: ComplexArray, code_column: ComplexArray) -> ComplexArray:
    """Full profile sequence of one RIS by eq. orthogonal_profiles.

    first_block : [G̃, N] profiles ω_{ℓ,g̃}; code_column : [Γ] the vector b_ℓ.
    Returns [G, N] with row (i−1)G̃ + g̃ equal to b*_{ℓ,i} ω_{ℓ,g̃}.
    """
    # [Γ, G̃, N] -> [G, N]
    full = np.conj(code_column)[:, None, None] * first_block[None, :, :]
    return full.reshape(-1, first_block.shape[1])


def random_phases(
    n_ris: int, beams: int, elements: list[int], rng: np.random.Generator
) -> list[ComplexArray]:
    """Unit-modulus profiles with phases ~ U[0, 2π) (Random Codebook), one [G̃, N_ℓ] per RIS."""
    return [np.exp(1j * rng.uniform(0.0, 2 * np.pi, size=(beams, n))) for n in elements[:n_ris]]


RANDOM_PHASES_CACHE_ENTRIES = 250_000
"""Largest draw (total profile entries G̃·ΣN_ℓ, 16 bytes each) :func:`seeded_random_phases`
keeps; it keeps the last 8 such draws (≤ 32 MB in the worst case, 200 kB for Table I; a
larger draw is small next to the work of the batch that needs it)."""


def seeded_random_phases(
    n_ris: int, beams: int, elements: tuple[int, ...], seed: int
) -> tuple[ComplexArray, ...]:
    """:func:`random_phases` drawn with ``numpy.random.default_rng(seed)``, remembered for
    small draws (read-only arrays: copy before changing them). The draw of exp(jφ) for Table I
    (2 × 64 × 100 phases) costs more than the rest of a single pair's bounds, and a seeded
    codebook draws the same phases on every call."""
    if beams * sum(elements[:n_ris]) > RANDOM_PHASES_CACHE_ENTRIES:
        rng = np.random.default_rng(seed)
        return tuple(random_phases(n_ris, beams, list(elements), rng))
    return _seeded_random_phases(n_ris, beams, elements, seed)


@lru_cache(maxsize=8)
def _seeded_random_phases(
    n_ris: int, beams: int, elements: tuple[int, ...], seed: int
) -> tuple[ComplexArray, ...]:
    out = []
    for p in random_phases(n_ris, beams, list(elements), np.random.default_rng(seed)):
        p.flags.writeable = False
        out.append(p[...])  # a view of a read-only array: cannot be made writeable again
    return tuple(out)


def phases_to_profiles(phases: list[list[list[float]]]) -> list[ComplexArray]:
    """Explicit phases [rad] to unit-modulus profiles exp(jφ), one [G̃, N] per RIS."""
    return [np.exp(1j * np.asarray(p, dtype=float)) for p in phases]
