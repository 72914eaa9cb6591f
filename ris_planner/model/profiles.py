"""The time-orthogonal profile structure of the contract (docs/concepts/conventions.md,
"Profiles"): G transmissions are Γ blocks of G̃ = G/Γ profiles, Γ the smallest divisor of G that
is ≥ L+1 (eq. orthogonal_profiles). Documents check it when they are validated; the codebooks
(:mod:`ris_planner.physics.codebooks`) build the profiles on it."""

from __future__ import annotations


def block_count(transmissions: int, n_ris: int) -> int:
    """Γ: the smallest divisor of G that is ≥ L+1.

    Raises ValueError when G has no such divisor (G < L+1).
    """
    for gamma in range(n_ris + 1, transmissions + 1):
        if transmissions % gamma == 0:
            return gamma
    raise ValueError(
        f"G = {transmissions} transmissions cannot hold L+1 = {n_ris + 1} time-orthogonal"
        " blocks; use G ≥ L+1"
    )


def block_length(transmissions: int, n_ris: int) -> int:
    """G̃ = G/Γ, the number of beams per RIS in the first block."""
    return transmissions // block_count(transmissions, n_ris)
