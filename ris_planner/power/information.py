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

Besides the summed stack (one matrix product gives I(s) at any powers for every position, the
SDP's LMI) the per-path per-beam blocks F_ℓ(g̃) and maps T_ℓ are kept:

* the CRBs at given powers (:meth:`BeamInformation.state_bounds`) sum each path's blocks
  (F_ℓ(γ) = Σ_g̃ γ_g̃ F_ℓ(g̃), one product per path), eliminate its gains and take the one
  inversion route of the bounds (:func:`ris_planner.bounds.compute.bounds_from_paths`,
  docs/concepts/numerics.md), never the squared full FIM;
* the square-root factor A(γ) = stack_ℓ L_ℓ(γ)ᵀ T_ℓ with F_ℓ(γ) = L_ℓ L_ℓᵀ
  (:meth:`BeamInformation.factor`) whitens the SDP (:func:`ris_planner.power.sdp.whitening`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ris_planner.bounds import compute as bounds
from ris_planner.inversion import crb
from ris_planner.model.scenario import KnownPart, Scenario
from ris_planner.physics import beams, codebooks, fim, geometry, spherical

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]


@dataclass(frozen=True)
class PathBlocks:
    """One path's per-beam information and its map to the state.

    blocks : [P, J, m+2, m+2] F_ℓ(g̃) on the path's (channel parameters, α, β) per distinct
    beam (an absent path: ABSENT_GAIN_INFORMATION / G̃ on its gains only); maps : [P, m+2, n]
    T_ℓ on the unknown state (the kept columns); name : ``"los"``, ``"ris1"``, …;
    jacobian : [P, m, 7] ∂(channel parameters)/∂[p_T, p_R, B]; present : [P] whether the path
    exists for the position.
    """

    blocks: FloatArray
    maps: FloatArray
    name: str
    jacobian: FloatArray
    present: NDArray[np.bool_]

    def path_info(self, group_powers: FloatArray) -> bounds.PathInfo:
        """The path's equivalent FIM on its channel parameters at the given distinct-beam
        powers [J] (gains eliminated, ``fim.eliminate_nuisance``) as the bounds' PathInfo."""
        block = np.einsum("j,pjab->pab", group_powers, self.blocks)
        m = self.jacobian.shape[1]
        return bounds.PathInfo(self.name, fim.eliminate_nuisance(block, m), self.jacobian)


@dataclass(frozen=True)
class BeamInformation:
    """Stacked per-beam information for a batch of positions.

    stack : [P, J, n, n] S_j on the unknown state (kept rows of [p_T, p_R, B], then gains)
    for the J distinct beams; beam_group : [G̃] which distinct beam each first-block beam is
    (a codebook that cycles through its beams repeats them; identical beams have identical
    S, so only their total power matters); tx_index, rx_index : positions of p_T's / p_R's
    kept entries in the state (may be empty); paths : the per-path blocks of the stack,
    S_j = Σ_ℓ T_ℓᵀ F_ℓ(j) T_ℓ (:class:`PathBlocks`).
    """

    stack: FloatArray
    beam_group: NDArray[np.int_]
    tx_index: NDArray[np.int_]
    rx_index: NDArray[np.int_]
    paths: tuple[PathBlocks, ...] = ()
    known: tuple[KnownPart, ...] = ()
    n_observations: int | None = None

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

    def factor(self, powers: FloatArray, idx: NDArray[np.int_] | None = None) -> FloatArray:
        """Square-root factor A [len(idx), r, n] of :meth:`fim` at the positions idx (all by
        default): AᵀA = Σ_ℓ T_ℓᵀ F_ℓ(γ) T_ℓ with the rows L_ℓᵀ T_ℓ of each path, L_ℓ from the
        eigendecomposition of the symmetrically scaled block D⁻¹F_ℓD⁻¹ (D = √diag F_ℓ: the
        path's delay, angles and gains differ in scale by many orders, which an unscaled eigh
        would not resolve), negative rounding eigenvalues clipped
        (:func:`ris_planner.inversion.crb.path_factor`)."""
        gp = self.group_powers(powers)
        sel = np.arange(self.stack.shape[0]) if idx is None else idx
        rows = []
        for path in self.paths:
            block = np.einsum("j,pjab->pab", gp, path.blocks[sel])
            d = np.sqrt(np.diagonal(block, axis1=1, axis2=2))
            d = np.where(d > 0, d, 1.0)
            scaled = block / d[:, :, None] / d[:, None, :]
            scaled = 0.5 * (scaled + scaled.transpose(0, 2, 1))
            rows.append(crb.path_factor(scaled, path.maps[sel] * d[:, :, None]))
        return np.concatenate(rows, axis=1)

    def state_bounds(
        self, powers: FloatArray
    ) -> tuple[FloatArray | None, FloatArray, FloatArray | None]:
        """(PEB_T or ``None`` when known, PEB_R, CEB or ``None``) [P] at the given first-block
        powers by the bounds' own route (:func:`ris_planner.bounds.compute.bounds_from_paths`: each
        path's gains eliminated, the LOS-referenced clock, per-parameter identifiability), so
        the values are ``compute_bounds``' (a pair left with fewer channel parameters than
        unknown states by missing paths is ``inf`` as there)."""
        gp = self.group_powers(powers)
        paths = [p.path_info(gp) for p in self.paths]
        mask = np.stack([p.present for p in self.paths], axis=1)

        def state_fim() -> FloatArray:
            return bounds.masked_state_information(paths, mask)

        peb_tx, peb_rx, ceb, _ = bounds.bounds_from_paths(
            paths, self.known, self.n_observations, mask, state_fim
        )
        if self.n_observations is not None:
            n_unknown = int(bounds.kept_states(self.known).size)
            under, _ = bounds.underdetermined_pairs(paths, mask, n_unknown)
            for arr in (peb_tx, peb_rx, ceb):
                if arr is not None:
                    arr[under] = np.inf
        return peb_tx, peb_rx, ceb


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


def _path_blocks(blocks: FloatArray, present: NDArray[np.bool_], beams_total: int) -> FloatArray:
    """The path's per-beam blocks [P, J, m, m] with an absent path's replaced by
    ABSENT_GAIN_INFORMATION·I on its gains (the last two rows), split over the beams as 1/G̃
    each: Σ_g γ_g S_g then carries exactly that identity at every allocation with
    Σ_g γ_g = G̃ (the SDP's power constraint)."""
    if np.all(present):
        return blocks
    m = blocks.shape[-1]
    absent = np.zeros((m, m))
    absent[m - 2, m - 2] = absent[m - 1, m - 1] = ABSENT_GAIN_INFORMATION / beams_total
    return np.where(present[:, None, None, None], blocks, absent)


def beam_information(
    scenario: Scenario,
    tx: FloatArray,
    rx: FloatArray,
    profiles: list[ComplexArray],
    known: list[KnownPart] | tuple[KnownPart, ...] | None = None,
    n_blocks: int | None = None,
    presence: dict[str, NDArray[np.bool_]] | None = None,
) -> BeamInformation:
    """S_j for every distinct first-block beam and every TX–RX pair (tx, rx : [P, 3]).

    ``n_blocks``: Γ when the profiles were made for another block count than the scenario's RIS
    count gives (a district's colours, :mod:`ris_planner.planning.scoring.time_blocks`); each
    profile then has G/Γ rows. ``presence``: the paths present per pair as
    :func:`~ris_planner.bounds.compute.scenario_path_presence` gives them, when the caller
    knows them (one visibility query for many calls); else found here. A pair on a RIS or
    with TX = RX gives non-finite entries (no warning); the SDP reports that as a ``failed``
    status.
    """
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return _beam_information(scenario, tx, rx, profiles, known, n_blocks, presence)


def distinct_rows(rows: ComplexArray) -> tuple[NDArray[np.int_], NDArray[np.int_]]:
    """(first, group): the first index of each distinct row of ``rows`` [G, n], in the order
    of first occurrence, and each row's distinct row (rows compared exactly). Rows are grouped
    by a projection first and each group checked element by element (a collision falls back to
    sorting the rows), so a district's long concatenated profiles are not sorted column by
    column; the order of first occurrence makes the numbering the same for every position
    whose profiles repeat in the same slots."""
    g = rows.shape[0]
    if g == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    probe = np.random.default_rng(0).standard_normal((rows.shape[1], 2)) @ np.array([1, 1j])
    _, first_key, group_key = np.unique(rows @ probe, return_index=True, return_inverse=True)
    group_key = group_key.reshape(-1)
    if not all(np.array_equal(rows[i], rows[first_key[group_key[i]]]) for i in range(g)):
        _, first_key, group_key = np.unique(rows, axis=0, return_index=True, return_inverse=True)
        group_key = group_key.reshape(-1)
    perm = np.argsort(first_key, kind="stable")
    rank = np.empty_like(perm)
    rank[perm] = np.arange(perm.size)
    return np.asarray(first_key[perm], dtype=np.int64), np.asarray(rank[group_key], np.int64)


def _beam_information(
    scenario: Scenario,
    tx: FloatArray,
    rx: FloatArray,
    profiles: list[ComplexArray],
    known: list[KnownPart] | tuple[KnownPart, ...] | None,
    n_blocks: int | None = None,
    presence: dict[str, NDArray[np.bool_]] | None = None,
) -> BeamInformation:
    system = scenario.system
    radio = fim.Radio.from_system(system)
    n_ris = len(scenario.ris)
    # paths that exist per position (docs/concepts/environment.md): a missing path carries no
    # information, exactly as in compute_bounds; the pattern factor scales each RIS gain
    present = presence if presence is not None else bounds.scenario_path_presence(scenario, tx, rx)
    gamma = codebooks.block_count(system.transmissions, n_ris) if n_blocks is None else n_blocks
    n_paths = n_ris + (1 if system.los else 0)
    n_full = 7 + 2 * n_paths
    # distinct beams: the same profile on every RIS in the same slot (exact comparison)
    beams_total = profiles[0].shape[0]  # G̃ before merging identical beams
    first, group = distinct_rows(np.concatenate(profiles, axis=1))
    profiles = [prof[first] for prof in profiles]
    n_pos, g_tilde = tx.shape[0], first.size
    kept = bounds.kept_states(scenario.known if known is None else known)
    keep = np.concatenate([kept, np.arange(7, n_full)])
    # per path: per-beam blocks [P, G̃, m+2, m+2] and T_ℓ [P, m+2, n_full]
    parts: list[tuple[str, FloatArray, FloatArray, FloatArray]] = []
    col = 7
    if system.los:
        alpha0 = geometry.los_gain(geometry.los_distance(tx, rx), radio.wavelength)
        # every beam carries the LOS path with t_g = 1: the same block for all g̃
        block = fim.los_path_fim(float(gamma), alpha0, radio)
        blocks = np.broadcast_to(block[:, None], (n_pos, g_tilde, *block.shape[1:]))
        jac = geometry.los_jacobian(tx, rx)
        t = _path_map(jac, col, n_full)
        parts.append(("los", _path_blocks(blocks, present["los"], beams_total), t, jac))
        col += 2
    for i, (ris, prof) in enumerate(zip(scenario.ris, profiles, strict=True)):
        pos = beams.ris_element_positions(ris, radio.wavelength)
        geo = geometry.ris_path_geometry(tx, rx, ris.position, ris.orientation)
        gain = bounds.ris_path_gain(ris, geo, tx, rx, radio.wavelength)
        if system.wavefront == "spherical":
            # [P, G̃, 7] t_g = ω_gᵀ [∂a/∂p_T, ∂a/∂p_R, a] (ris_planner.physics.spherical)
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
        name = f"ris{i + 1}"
        parts.append((name, _path_blocks(block5, present[name], beams_total), t, jac))
        col += 2
    stack = np.zeros((n_pos, g_tilde, n_full, n_full))
    for _, blocks, t, _ in parts:
        stack += np.einsum("pai,pgab,pbj->pgij", t, blocks, t, optimize=True)
    stack = stack[:, :, keep][:, :, :, keep]
    stack = 0.5 * (stack + stack.transpose(0, 1, 3, 2))
    paths = tuple(
        PathBlocks(blocks, np.ascontiguousarray(t[:, :, keep]), name, jac, present[name])
        for name, blocks, t, jac in parts
    )
    pos_in_state = {int(k): i for i, k in enumerate(keep)}
    tx_index = np.array([pos_in_state[k] for k in (0, 1, 2) if k in pos_in_state], dtype=int)
    rx_index = np.array([pos_in_state[k] for k in (3, 4, 5) if k in pos_in_state], dtype=int)
    known_t = tuple(scenario.known if known is None else known)
    n_obs = bounds.n_observations(n_ris, system.los, system.wavefront)
    return BeamInformation(
        stack, np.asarray(group).ravel(), tx_index, rx_index, paths, known_t, n_obs
    )
