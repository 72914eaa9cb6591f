"""Per-beam Fisher information on the full state, linear in the beam powers (appendix,
eq. FIM_measurement_r1_v3_): I(s) = Σ_g γ_g S_g.

Only the FULL information, nuisance gains included, is linear in γ (the Schur complement that
eliminates α, β is not), so the state here is s = [p_T, p_R, B, α0, β0, α1, β1, …] minus the
known parts. With the time-orthogonal profiles each first-block beam g̃ is used in the Γ
blocks with the same power γ_g̃ and the paths separate exactly, so

    S_g̃ = Σ_ℓ T_ℓᵀ · Γ·F_ℓ(conj(t_g̃) t_g̃ᵀ) · T_ℓ,

with F_ℓ the path's 5×5 (3×3 for LOS) block of eq. FIM_measurement built by the core
(``fim.ris_path_fim`` / ``fim.los_path_fim``) from the single beam's transmission Gram and
T_ℓ mapping (ξ, ζ, r, α, β) of the path to s (geometry Jacobian for ξ, ζ, r; identity for
its own gains).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ris_planner import beams, bounds, codebooks, fim, geometry, spherical
from ris_planner.scenario import KnownPart, Scenario

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]


@dataclass(frozen=True)
class BeamInformation:
    """Stacked per-beam information for a batch of positions.

    stack : [P, J, n, n] S_j on the unknown state (kept rows of [p_T, p_R, B], then gains)
    for the J distinct beams; beam_group : [G̃] which distinct beam each first-block beam is
    (a codebook that cycles through its beams repeats them; identical beams have identical
    S, so only their total power matters); tx_index, rx_index : positions of p_T's / p_R's
    kept entries in the state (may be empty).
    """

    stack: FloatArray
    beam_group: NDArray[np.int_]
    tx_index: NDArray[np.int_]
    rx_index: NDArray[np.int_]

    @property
    def group_sizes(self) -> NDArray[np.int_]:
        """[J] how many first-block beams share each distinct beam."""
        return np.bincount(self.beam_group, minlength=self.stack.shape[1])

    def group_powers(self, powers: FloatArray) -> FloatArray:
        """[J] total power per distinct beam from [G̃] per-beam powers."""
        weights = np.asarray(powers, dtype=float)
        return np.asarray(
            np.bincount(self.beam_group, weights=weights, minlength=self.stack.shape[1]),
            dtype=float,
        )

    def beam_powers(self, group_powers: FloatArray) -> FloatArray:
        """[G̃] per-beam powers sharing each distinct beam's total equally."""
        return np.asarray((np.asarray(group_powers) / self.group_sizes)[self.beam_group])

    def fim(self, powers: FloatArray) -> FloatArray:
        """Σ_g γ_g S_g for every position as one matrix product, [P, n, n]; powers [G̃]."""
        p, j, n, _ = self.stack.shape
        flat = self.group_powers(powers) @ self.stack.transpose(1, 0, 2, 3).reshape(j, -1)
        return np.asarray(flat.reshape(p, n, n))


def _path_map(jacobian: FloatArray, gain_col: int, n_full: int) -> FloatArray:
    """T_ℓ [P, m+2, n_full]: geometric rows from the Jacobian [P, m, 7], gains as identity."""
    p, m, _ = jacobian.shape
    t = np.zeros((p, m + 2, n_full))
    t[:, :m, :7] = jacobian
    t[:, m, gain_col] = 1.0
    t[:, m + 1, gain_col + 1] = 1.0
    return t


ABSENT_GAIN_INFORMATION = 1.0
"""Information put on the (α, β) of a path that does not exist for a position. Such gains
are decoupled from every other state (no cross terms), so any positive value leaves the
position and clock CRBs unchanged while keeping the full FIM invertible for the SDP."""


def _decouple_absent_gains(
    stack: FloatArray, absent: NDArray[np.bool_], col: int, beams_total: int
) -> None:
    """Add ABSENT_GAIN_INFORMATION·I on the gains (columns col, col+1) of the positions where
    the path is absent, split over the beams as 1/G̃ each: Σ_g γ_g S_g then carries exactly
    that identity at every allocation with Σ_g γ_g = G̃ (the SDP's power constraint)."""
    if np.any(absent):
        share = ABSENT_GAIN_INFORMATION / beams_total
        for c in (col, col + 1):
            stack[absent, :, c, c] += share


def beam_information(
    scenario: Scenario,
    tx: FloatArray,
    rx: FloatArray,
    profiles: list[ComplexArray],
    known: list[KnownPart] | tuple[KnownPart, ...] | None = None,
) -> BeamInformation:
    """S_j for every distinct first-block beam and every TX–RX pair (tx, rx : [P, 3]).

    A pair on a RIS or with TX = RX gives non-finite entries (no warning); the SDP reports
    that as a ``failed`` status.
    """
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return _beam_information(scenario, tx, rx, profiles, known)


def _beam_information(
    scenario: Scenario,
    tx: FloatArray,
    rx: FloatArray,
    profiles: list[ComplexArray],
    known: list[KnownPart] | tuple[KnownPart, ...] | None,
) -> BeamInformation:
    system = scenario.system
    radio = fim.Radio.from_system(system)
    n_ris = len(scenario.ris)
    # paths that exist per position (docs/concepts/environment.md): a missing path carries no
    # information, exactly as in compute_bounds; the pattern factor scales each RIS gain
    present = bounds.scenario_path_presence(scenario, tx, rx)
    gamma = codebooks.block_count(system.transmissions, n_ris)
    n_paths = n_ris + (1 if system.los else 0)
    n_full = 7 + 2 * n_paths
    # distinct beams: the same profile on every RIS in the same slot (exact comparison)
    beams_total = profiles[0].shape[0]  # G̃ before merging identical beams
    _, first, group = np.unique(
        np.concatenate(profiles, axis=1), axis=0, return_index=True, return_inverse=True
    )
    profiles = [prof[first] for prof in profiles]
    n_pos, g_tilde = tx.shape[0], first.size
    stack = np.zeros((n_pos, g_tilde, n_full, n_full))
    col = 7
    if system.los:
        alpha0 = geometry.los_gain(geometry.los_distance(tx, rx), radio.wavelength)
        # every beam carries the LOS path with t_g = 1: the same block for all g̃
        block = fim.los_path_fim(float(gamma), alpha0, radio)
        t = _path_map(geometry.los_jacobian(tx, rx), col, n_full)
        stack += np.where(present["los"][:, None, None], t.transpose(0, 2, 1) @ block @ t, 0.0)[
            :, None
        ]
        _decouple_absent_gains(stack, ~present["los"], col, beams_total)
        col += 2
    for i, (ris, prof) in enumerate(zip(scenario.ris, profiles, strict=True)):
        pos = beams.ris_element_positions(ris, radio.wavelength)
        geo = geometry.ris_path_geometry(tx, rx, ris.position, ris.orientation)
        gain = bounds.ris_path_gain(ris, geo, tx, rx, radio.wavelength)
        if system.wavefront == "spherical":
            # [P, G̃, 7] t_g = ω_gᵀ [∂a/∂p_T, ∂a/∂p_R, a] (ris_planner.spherical)
            tv = spherical.transmission_vectors(prof, tx, rx, ris, radio.wavelength)
            jac = spherical.jacobian(geo)
        else:
            # [P, G̃, 3] t_g = ω_gᵀ [∂a/∂ξ, ∂a/∂ζ, a]
            tv = fim.transmission_vectors(prof, pos, geo.xi, geo.zeta, radio.wavelength)
            jac = geo.jacobian()
        m = tv.shape[-1]
        # per-beam Gram Γ·conj(t_g) t_gᵀ: the path's block is linear in each beam's power
        q = gamma * np.conj(tv)[..., :, None] * tv[..., None, :]
        block5 = fim.ris_path_fim(q.reshape(-1, m, m), np.repeat(gain, g_tilde), radio).reshape(
            n_pos, g_tilde, m + 2, m + 2
        )
        t = _path_map(jac, col, n_full)
        contribution = np.einsum("pai,pgab,pbj->pgij", t, block5, t, optimize=True)
        stack += np.where(present[f"ris{i + 1}"][:, None, None, None], contribution, 0.0)
        _decouple_absent_gains(stack, ~present[f"ris{i + 1}"], col, beams_total)
        col += 2
    kept = bounds.kept_states(scenario.known if known is None else known)
    keep = np.concatenate([kept, np.arange(7, n_full)])
    stack = stack[:, :, keep][:, :, :, keep]
    stack = 0.5 * (stack + stack.transpose(0, 1, 3, 2))
    pos_in_state = {int(k): i for i, k in enumerate(keep)}
    tx_index = np.array([pos_in_state[k] for k in (0, 1, 2) if k in pos_in_state], dtype=int)
    rx_index = np.array([pos_in_state[k] for k in (3, 4, 5) if k in pos_in_state], dtype=int)
    return BeamInformation(stack, np.asarray(group).ravel(), tx_index, rx_index)
