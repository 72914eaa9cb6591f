"""CRB-based bounds: PEB_T, PEB_R, CEB (eqs. PEBT, PEBR, CEB) and DEB/SEB (eqs. DEB, SEB1,
SEB2), batched over UE pairs.

Each path contributes J_ℓ^T Ĩ_ℓ J_ℓ to the information on s_N = [p_T, p_R, B] (7×7), where Ĩ_ℓ
is its equivalent FIM on (ξ, ζ, cτ) or cτ0 after eliminating its own gain (α, β) and J_ℓ is
the Jacobian of eq. crb_sidelink. Summing those is the Schur complement of J_S I(η) J_S^T
with respect to all gains, because every gain belongs to one path only.

With an ``environment`` (docs/concepts/environment.md, "Visibility rules") only
the paths that exist for a pair contribute: its other paths' 7×7 contributions are masked to
exactly zero, their channel bounds are ``inf``, and a pair left with fewer geometric channel
parameters than unknown states is ``inf`` with a reason naming the missing paths. The
time-orthogonal profiles (Γ from the layout's RIS count) do not change.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from functools import cache, cached_property
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ris_planner.bounds import advice
from ris_planner.bounds.paths import path_presence, path_presence_per_pair, pattern_factor
from ris_planner.core.io_json import finite_or_none
from ris_planner.environment import Scene
from ris_planner.environment.model import Environment
from ris_planner.inversion import crb, ldl
from ris_planner.model.scenario import (
    MIN_UE_RIS_DISTANCE_M,
    RIS,
    DirectionalCodebook,
    DirectionalDerivativeCodebook,
    ExpectedRandomCodebook,
    ExplicitCodebook,
    KnownPart,
    RandomCodebook,
    Scenario,
    Wavefront,
)
from ris_planner.physics import beams, codebooks, fim, geometry, spherical
from ris_planner.physics.separable import SeparableBlock, grid_axes, separable_gram
from ris_planner.runtime import blas
from ris_planner.runtime.provenance import provenance

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
BoolArray = NDArray[np.bool_]

REASON_UNDERDETERMINED = "underdetermined"
REASON_SINGULAR = "singular Fisher information (blind spot): the layout cannot resolve this pair"
REASON_DEGENERATE = "degenerate geometry: a UE coincides with a RIS or with the other UE"
REASON_CHANNEL_SPHERICAL = (
    "channel bounds (DEB/SEB) are defined for the planar wavefront only: the spherical model"
    " has no (ξ, ζ) parameters"
)
REASON_NOT_IDENTIFIABLE = "not identifiable"
"""Start of the reason of a pair whose PEB_R is determined but another part is not (a singular
direction of the information involves only those states, :mod:`ris_planner.inversion.crb`)."""
PART_STATES = {"tx": range(0, 3), "rx": range(3, 6), "clock": range(6, 7)}
PART_LABELS = {"tx": "PEB_T", "rx": "PEB_R", "clock": "CEB"}


def kept_states(known: list[KnownPart] | tuple[KnownPart, ...]) -> NDArray[np.int_]:
    """Indices of s_N = [p_T, p_R, B] that remain unknown (rows removed before inversion)."""
    drop: set[int] = set()
    if "tx" in known:
        drop |= {0, 1, 2}
    if "height" in known:
        drop |= {2, 5}
    if "clock" in known:
        drop.add(6)
    return np.array([i for i in range(7) if i not in drop], dtype=int)


@dataclass(frozen=True)
class PathInfo:
    """One path's equivalent FIM and Jacobian for a batch of pairs.

    efim : [P, m, m] on (ξ, ζ, cτ) (m = 3, RIS) or cτ0 (m = 1, LOS);
    jacobian : [P, m, 7] = ∂(ξ, ζ, cτ)/∂[p_T, p_R, B].
    """

    name: str
    efim: FloatArray
    jacobian: FloatArray
    unit_root: FloatArray | None = None
    """[m, m] rows R with RᵀR = Ĩ(1) when Ĩ = α² Ĩ(1) for every pair (the expected-random
    planar EFIM at unit gain, one matrix per RIS); ``None`` otherwise."""
    gain: FloatArray | None = None
    """[P] α of ``unit_root`` (Ĩ = α² RᵀR)."""

    def take(self, pairs: NDArray[np.int_]) -> PathInfo:
        """The same path for the pairs ``pairs`` only (each pair's values are its own)."""
        gain = None if self.gain is None else self.gain[pairs]
        return replace(self, efim=self.efim[pairs], jacobian=self.jacobian[pairs], gain=gain)

    def state_information(self) -> FloatArray:
        """J^T Ĩ J, the path's 7×7 contribution to the information on [p_T, p_R, B]. With one
        channel parameter (the LOS path) the products have one term each, (J_i Ĩ) J_j, formed
        elementwise: the matrix product's single rounded product per entry, without a small
        matrix product per pair."""
        if self.efim.shape[-1] == 1:
            # [P, 7] J_i Ĩ, then [P, 7, 7] (J_i Ĩ) J_j
            left = self.jacobian[:, 0, :] * self.efim[:, 0, :]
            return np.asarray(left[:, :, None] * self.jacobian[:, 0, None, :])
        # [P, 7, 7]
        return np.asarray(self.jacobian.transpose(0, 2, 1) @ self.efim @ self.jacobian)

    def factor(self, pairs: NDArray[np.int_] | slice = slice(None)) -> FloatArray:
        """Square-root rows [p, m, 7] of :meth:`state_information` for the given pairs
        (:func:`ris_planner.inversion.crb.path_factor`): α·R·J from the one unit root when the EFIM
        is
        α² Ĩ(1), else from each pair's EFIM."""
        if self.unit_root is not None and self.gain is not None:
            return np.asarray(
                self.gain[pairs, None, None] * (self.unit_root @ self.jacobian[pairs])
            )
        return crb.path_factor(self.efim[pairs], self.jacobian[pairs])

    def factor_on_channel(self, pairs: NDArray[np.int_]) -> FloatArray:
        """Square-root rows Lᵀ [p, m, m] of the EFIM itself (LLᵀ = Ĩ): α·R from the unit root
        when Ĩ = α² Ĩ(1), else by :func:`ris_planner.inversion.crb.path_factor` of each pair's
        EFIM."""
        if self.unit_root is not None and self.gain is not None:
            return np.asarray(self.gain[pairs, None, None] * self.unit_root)
        m = self.efim.shape[-1]
        return crb.path_factor(self.efim[pairs], np.broadcast_to(np.eye(m), (pairs.size, m, m)))


@dataclass(frozen=True)
class BoundsResult:
    """Bounds for a batch of pairs (arrays in pair order); ``None`` for a known state part.

    Attributes
    ----------
    peb_tx, peb_rx : [P] position error bounds [m] (over x, y only when heights are known).
    ceb : [P] clock-offset error bound [m].
    reason : [P] object array, ``None`` or why the bounds are ``inf``.
    channel : per path (``"los"``, ``"ris1"``, …) a dict of [P] arrays: ``deb_m``
        (c·sqrt(CRB_τ)), and for RIS paths ``seb_xi``, ``seb_zeta`` (unitless).
    far_field : [P, L] whether d_T d_R/(d_T + d_R) ≥ 2D²/λ for each RIS (footnote 3).
    fim : [P, 7, 7] information on [p_T, p_R, B] (gains eliminated, nothing known removed);
        NaN for the pairs whose codebook products a ``channel=False`` call left out (those the
        counting rule or a degenerate geometry settles: their bounds are ``inf`` anyway).
    known : the state parts treated as known.
    paths_present : per path (``"los"``, ``"ris1"``, …) [P] whether it exists for the pair
        (:func:`scenario_path_presence`); ``"los"`` is False throughout without ``system.los``.
    warnings : the modelling assumptions that may mislead (:mod:`ris_planner.bounds.advice`).
    """

    peb_tx: FloatArray | None
    peb_rx: FloatArray
    ceb: FloatArray | None
    reason: NDArray[np.object_]
    channel: dict[str, dict[str, FloatArray]]
    far_field: NDArray[np.bool_]
    fim_source: Callable[[], FloatArray] = field(repr=False, compare=False)
    """Computes :attr:`fim` when it is first read (most callers never read it)."""
    known: tuple[KnownPart, ...] = field(default=())
    paths_present: dict[str, BoolArray] = field(default_factory=dict)
    warnings: tuple[str, ...] = field(default=())
    wavefront: Wavefront = "planar"

    @cached_property
    def fim(self) -> FloatArray:
        """[P, 7, 7] information on [p_T, p_R, B] (gains eliminated, nothing known removed);
        NaN for the pairs a ``channel=False`` call settled without their codebook products."""
        return self.fim_source()

    @property
    def n_pairs(self) -> int:
        return int(self.peb_rx.shape[0])

    def to_json(self, batch: bool = True) -> dict[str, Any]:
        """JSON-ready dict: ``inf`` becomes ``null`` with the reason beside it."""

        def num(a: FloatArray | None) -> Any:
            if a is None:
                return None
            vals = [finite_or_none(x) for x in a]
            return vals if batch else vals[0]

        def per_pair(values: list[Any]) -> Any:
            return values if batch else values[0]

        out: dict[str, Any] = {
            "peb_tx_m": num(self.peb_tx),
            "peb_rx_m": num(self.peb_rx),
            "ceb_m": num(self.ceb),
            "reason": per_pair([None if r is None else str(r) for r in self.reason]),
            "channel": [
                {"path": name, **{k: num(v) for k, v in bounds.items()}}
                for name, bounds in self.channel.items()
            ],
            "paths_present": {
                name: per_pair([bool(x) for x in present])
                for name, present in self.paths_present.items()
            },
            "far_field": per_pair([bool(x) for x in np.all(self.far_field, axis=1)]),
            "far_field_ris": per_pair([[bool(x) for x in row] for row in self.far_field]),
            "known": list(self.known),
            "warnings": list(self.warnings),
        }
        if self.peb_tx is None:
            out["peb_tx_reason"] = "TX position is known ('tx' in known)"
        if self.ceb is None:
            out["ceb_reason"] = "clock offset is known ('clock' in known)"
        if self.wavefront == "spherical":
            out["channel_reason"] = REASON_CHANNEL_SPHERICAL
        return out


def first_block_profiles(scenario: Scenario) -> list[ComplexArray] | None:
    """The codebook's first block, one [G̃, N_ℓ] per RIS; ``None`` for ``expected_random``."""
    prof = _codebook_profiles(scenario)
    if prof is None or scenario.codebook.kind != "random":
        return prof
    return [p.copy() for p in prof]  # the caller's own (the seeded draw is shared, read-only)


def _codebook_profiles(scenario: Scenario) -> list[ComplexArray] | None:
    """:func:`first_block_profiles`, a ``random`` codebook's as the shared read-only draw of
    :func:`ris_planner.physics.codebooks.seeded_random_phases` (what :func:`compute_bounds` reads;
    the planar products of such a draw are remembered,
    :func:`ris_planner.physics.fim.planar_weighted`)."""
    cb = scenario.codebook
    n_ris = len(scenario.ris)
    g_tilde = codebooks.block_length(scenario.system.transmissions, n_ris)
    if isinstance(cb, ExpectedRandomCodebook):
        return None
    if isinstance(cb, RandomCodebook):
        elements = tuple(r.elements for r in scenario.ris)
        return list(codebooks.seeded_random_phases(n_ris, g_tilde, elements, cb.seed))
    if isinstance(cb, ExplicitCodebook):
        return codebooks.phases_to_profiles(cb.phases)
    if isinstance(cb, DirectionalCodebook | DirectionalDerivativeCodebook):
        return beams.codebook_block(scenario).profiles
    raise TypeError(f"unsupported codebook kind {cb.kind!r}")  # pragma: no cover


def los_path_information(
    tx: FloatArray, rx: FloatArray, radio: fim.Radio, total_weight: float
) -> PathInfo:
    """The LOS path's equivalent FIM on cτ0 and its Jacobian; total_weight = Σ_g δ_g² (= G)."""
    alpha0 = geometry.los_gain(geometry.los_distance(tx, rx), radio.wavelength)
    # the equivalent FIM scales with |ρ0|² (Ĩ(α) = α² Ĩ(1)): one 1×1 block at unit gain
    unit = fim.eliminate_nuisance(fim.los_path_fim(total_weight, np.ones(1), radio), 1)
    return PathInfo("los", alpha0[:, None, None] ** 2 * unit, geometry.los_jacobian(tx, rx))


def ris_path_gain(
    ris: RIS, geo: geometry.RisPathGeometry, tx: FloatArray, rx: FloatArray, wavelength: float
) -> FloatArray:
    """|ρ_ℓ| = λ²/(16π² d_T d_R) · (cos θ_T cos θ_R)^q, [P] (Simulation Parameters and the
    element pattern of environment.md; q = ``pattern_exponent``, q = 0 the paper's isotropic gain
    exactly). The one gain rule for the bounds and the signal simulator."""
    alpha = geo.gain(wavelength)
    if ris.pattern_exponent == 0.0:
        return alpha
    return np.asarray(alpha * pattern_factor(ris, tx, rx))


def ris_path_information(
    ris: RIS,
    tx: FloatArray,
    rx: FloatArray,
    radio: fim.Radio,
    profile: ComplexArray | None,
    block_count: int,
    weights: FloatArray,
    name: str = "ris",
    wavefront: Wavefront = "planar",
    present: NDArray[np.bool_] | None = None,
    separable: SeparableBlock | None = None,
) -> tuple[PathInfo, NDArray[np.bool_]]:
    """One RIS path's equivalent FIM on (ξ, ζ, cτ) (planar) or (p_T, p_R, cτ) (spherical,
    :mod:`ris_planner.physics.spherical`), its Jacobian, and far-field flags [P].

    ``separable``: the first block as column × row factors (planar only,
    :mod:`ris_planner.physics.separable`; ``profile`` is then ``None``): its Gram in
    O(columns + rows) per pair and beam, the same as the element-by-element route's.

    profile : [G̃, N] first-block profiles or ``None`` for the expected-random FIM;
    block_count : Γ; weights : [G̃] beam powers δ² repeated over the Γ blocks. The gain is
    |ρ_ℓ| = λ²/(16π² d_T d_R) · (cos θ_T cos θ_R)^q (:func:`ris_path_gain`).
    ``present`` [P]: the pairs the path exists for (:func:`scenario_path_presence`); with
    profiles, the transmission Gram – a [3G̃, N] @ [N, P] product, the cost of a codebook's
    bounds – is formed for those pairs only, and a missing pair carries the expected-random
    Gram instead (finite, and never read: a missing path contributes nothing,
    :func:`masked_state_information`, and its DEB/SEB are ``inf``).
    """
    pos = beams.ris_element_positions(ris, radio.wavelength)
    geo = geometry.ris_path_geometry(tx, rx, ris.position, ris.orientation)
    alpha = ris_path_gain(ris, geo, tx, rx, radio.wavelength)
    jacobian = geo.jacobian()
    if separable is not None:
        if wavefront != "planar":
            raise ValueError("a separable block is the planar model's")
        yc, zr = separable_axes(ris, radio.wavelength)
        gram = separable_gram(separable, weights, geo.xi, geo.zeta, yc, zr, radio.wavelength)
        efim = fim.eliminate_nuisance(fim.ris_path_fim(block_count * gram, alpha, radio), 3)
        return PathInfo(name, efim, jacobian), _far_field(ris, geo, radio)
    if wavefront == "spherical":
        if profile is None:
            # E[Q] = Σ_g δ_g² Vᴴ V per pair (it depends on the geometry here)
            gram = spherical.expected_gram(tx, rx, ris, radio.wavelength)
            q = block_count * weights.sum() * gram
        else:

            def products(idx: NDArray[np.int_]) -> ComplexArray:
                t = spherical.transmission_vectors(profile, tx[idx], rx[idx], ris, radio.wavelength)
                return fim.transmission_gram(t, weights)

            def stand_in(idx: NDArray[np.int_]) -> ComplexArray:
                return weights.sum() * spherical.expected_gram(
                    tx[idx], rx[idx], ris, radio.wavelength
                )

            q = block_count * _present_gram(tx.shape[0], present, products, stand_in)
        efim = fim.eliminate_nuisance(fim.ris_path_fim(q, alpha, radio), 7)
        jacobian = spherical.jacobian(geo)
    elif profile is None:
        # E[Q] does not depend on ξ, ζ: one 3×3 EFIM at unit gain, scaled by α² per pair
        q = fim.transmission_gram_expected(pos, radio.wavelength, block_count * weights.sum())
        unit = fim.eliminate_nuisance(fim.ris_path_fim(q, np.ones(1), radio), 3)
        efim = alpha[:, None, None] ** 2 * unit
        # its square root once (R = diag(√w) Vᵀ of the unit EFIM), α·R per pair
        root = crb.path_factor(unit, np.eye(3)[None])[0]
        return PathInfo(name, efim, jacobian, root, alpha), _far_field(ris, geo, radio)
    else:

        def planar(idx: NDArray[np.int_]) -> ComplexArray:
            return fim.planar_transmission_gram(
                profile, pos, geo.xi[idx], geo.zeta[idx], radio.wavelength, weights
            )

        def expected(idx: NDArray[np.int_]) -> ComplexArray:
            q0 = fim.transmission_gram_expected(pos, radio.wavelength, float(weights.sum()))
            return np.broadcast_to(q0, (idx.size, 3, 3))

        gram = _present_gram(tx.shape[0], present, planar, expected)
        efim = fim.eliminate_nuisance(fim.ris_path_fim(block_count * gram, alpha, radio), 3)
    return PathInfo(name, efim, jacobian), _far_field(ris, geo, radio)


def separable_axes(ris: RIS, wavelength: float) -> tuple[FloatArray, FloatArray]:
    """(y_c [C], z_r [R]) of a RIS's element grid (:func:`ris_planner.physics.separable.
    grid_axes`)."""

    return grid_axes(ris.rows, ris.cols, ris.element_spacing(wavelength))


def _present_gram(
    n_pairs: int,
    present: NDArray[np.bool_] | None,
    gram: Callable[[NDArray[np.int_]], ComplexArray],
    stand_in: Callable[[NDArray[np.int_]], ComplexArray],
) -> ComplexArray:
    """[P, m, m] transmission Grams: ``gram(idx)`` of the present pairs (all without
    ``present``), ``stand_in(idx)`` of the others (:func:`ris_path_information`)."""
    if present is None or np.all(present):
        return gram(np.arange(n_pairs))
    on, off = np.flatnonzero(present), np.flatnonzero(~present)
    first = gram(on) if on.size else stand_in(off)
    q = np.empty((n_pairs, *first.shape[1:]), dtype=complex)
    if on.size:
        q[on] = first
    if off.size:
        q[off] = stand_in(off)
    return q


def _far_field(ris: RIS, geo: geometry.RisPathGeometry, radio: fim.Radio) -> BoolArray:
    """[P] d_T d_R/(d_T + d_R) ≥ 2D²/λ (footnote 3)."""
    limit = geometry.fraunhofer_distance(
        ris.rows, ris.cols, ris.element_spacing(radio.wavelength), radio.wavelength
    )
    return np.asarray(geo.d_tx * geo.d_rx / (geo.d_tx + geo.d_rx) >= limit)


def beam_weights(
    scenario: Scenario, beam_powers: ArrayLike | None = None, *, codebook_default: bool = True
) -> FloatArray:
    """[G̃] powers δ² of the first-block beams, repeated over the Γ blocks so the
    time-orthogonal separation holds (mean 1 keeps ‖δ‖² = G): ``beam_powers`` when given, else
    what the document's codebook prescribes (γ_P of a DIR+DER codebook) when
    ``codebook_default``, else uniform. The one rule for the bounds and the signal simulator.
    """
    g_tilde = codebooks.block_length(scenario.system.transmissions, len(scenario.ris))
    if beam_powers is not None:
        weights = np.asarray(beam_powers, dtype=float)
    else:
        prescribed = beams.codebook_beam_powers(scenario) if codebook_default else None
        weights = np.ones(g_tilde) if prescribed is None else prescribed
    if weights.shape != (g_tilde,):
        raise ValueError(f"beam_powers must hold G/Γ = {g_tilde} values, got {weights.shape}")
    return weights


def path_information(
    scenario: Scenario,
    tx: FloatArray,
    rx: FloatArray,
    profiles: list[ComplexArray] | None,
    beam_powers: FloatArray | None = None,
    presence: dict[str, BoolArray] | None = None,
) -> tuple[list[PathInfo], NDArray[np.bool_]]:
    """Every path's equivalent FIM and Jacobian, and the far-field flags [P, L].

    tx, rx : [P, 3]; profiles : first-block profiles per RIS or ``None`` (expected random);
    beam_powers : [G̃] powers δ² of the first-block beams (:func:`beam_weights`); default all
    ones; presence : the paths present per pair (:func:`scenario_path_presence`), when known:
    a RIS path's codebook products are then formed for its present pairs only
    (:func:`ris_path_information`).
    """
    system = scenario.system
    radio = fim.Radio.from_system(system)
    n_ris = len(scenario.ris)
    gamma = codebooks.block_count(system.transmissions, n_ris)
    weights = beam_weights(scenario, beam_powers, codebook_default=False)
    paths: list[PathInfo] = []
    if system.los:
        paths.append(los_path_information(tx, rx, radio, float(gamma * weights.sum())))
    far = np.zeros((tx.shape[0], n_ris), dtype=bool)
    for idx, ris in enumerate(scenario.ris):
        prof = None if profiles is None else profiles[idx]
        name = f"ris{idx + 1}"
        info, far[:, idx] = ris_path_information(
            ris,
            tx,
            rx,
            radio,
            prof,
            gamma,
            weights,
            name,
            system.wavefront,
            None if presence is None else presence[name],
        )
        paths.append(info)
    return paths, far


def n_observations(n_ris: int, los: bool, wavefront: Wavefront = "planar") -> int | None:
    """Geometric channel parameters of a layout: (ξ, ζ, τ) per RIS, τ0 with LOS; ``None`` for
    the spherical model, where the counting rule does not apply (a single RIS can resolve
    range; singularity is decided numerically)."""
    if wavefront == "spherical":
        return None
    return 3 * n_ris + (1 if los else 0)


PATH_OBSERVATIONS = {"los": 1, "ris": 3}
"""Geometric channel parameters per path: τ0 for the LOS path, (ξ, ζ, τ) for a RIS path."""


def underdetermined_reason(n_observations: int, n_unknown: int, missing: Sequence[str] = ()) -> str:
    """Why a pair is ``inf`` when it has fewer geometric channel parameters than unknown
    states; ``missing`` names the layout's paths that do not exist for it (blocked or out of
    view). Starts with :data:`REASON_UNDERDETERMINED` (environment.md)."""
    head = (
        f"{REASON_UNDERDETERMINED}: {n_observations} geometric channel parameters for"
        f" {n_unknown} unknown states"
    )
    if not missing:
        return f"{head}; add RISs, the LOS path, or known parts"
    return f"{head} (missing paths: {', '.join(missing)} – blocked or out of view)"


def scenario_path_presence(
    scenario: Scenario, tx: FloatArray, rx: FloatArray
) -> dict[str, BoolArray]:
    """``{"los": [P], "ris1": [P], …}``: which paths exist for each pair (environment.md rules,
    :func:`ris_planner.environment.path_presence`); ``"los"`` is False without ``system.los``.

    The fields of view always apply (a RIS serves only UEs in front of it: ``max_angle_deg``,
    default 90°, the open front half-space); without ``environment`` no leg is blocked, so the
    paper's scenes (every UE in front of every RIS) keep exactly the paper's model.
    """
    scene = Scene.from_environment(scenario.environment)
    found = path_presence(scene, list(scenario.ris), tx, rx, scenario.system.los)
    return _los_always(found, tx)


def presence_per_pair(
    environment: Environment | None,
    rises: Sequence[RIS],
    slots: NDArray[np.int_],
    tx: FloatArray,
    rx: FloatArray,
    los: bool,
) -> dict[str, BoolArray]:
    """:func:`scenario_path_presence` where each pair has RISs of its own (pair p's path
    ``ris{j+1}`` is ``rises[slots[p, j]]``'s): every leg in one visibility query
    (:func:`ris_planner.bounds.paths.path_presence_per_pair`); ``"los"`` False without ``los``."""
    scene = Scene.from_environment(environment)
    return _los_always(path_presence_per_pair(scene, rises, slots, tx, rx, los), tx)


def _los_always(found: dict[str, BoolArray], tx: FloatArray) -> dict[str, BoolArray]:
    """The presence with ``"los"`` first and always there (all False where the system has no
    LOS path: :func:`ris_planner.bounds.paths.path_presence` leaves it out)."""
    n = np.asarray(tx).reshape(-1, 3).shape[0]
    return {"los": found.pop("los", np.zeros(n, dtype=bool))} | found


def present_path_mask(paths: Sequence[PathInfo], presence: dict[str, BoolArray]) -> BoolArray:
    """[P, len(paths)] whether each of ``paths`` exists for each pair."""
    return np.stack([presence[p.name] for p in paths], axis=1)


def masked_state_information(paths: Sequence[PathInfo], mask: BoolArray) -> FloatArray:
    """Σ over present paths of J^T Ĩ J, [P, 7, 7]: a missing path's contribution is exactly
    zero (mask : [P, len(paths)] from :func:`present_path_mask`). Summed in path order, one
    path after the other (the rounding of a sum over a stacked leading axis)."""
    total: FloatArray | None = None
    for k, p in enumerate(paths):
        part = p.state_information()
        if not np.all(mask[:, k]):
            part = np.where(mask[:, k, None, None], part, 0.0)
        if total is None:
            total = part
        else:
            total += part
    if total is None:
        return np.zeros((mask.shape[0], 7, 7))
    return total


def path_observations(names: Sequence[str]) -> NDArray[np.int_]:
    """Geometric channel parameters of each named path (:data:`PATH_OBSERVATIONS`)."""
    return np.array([PATH_OBSERVATIONS["los" if n == "los" else "ris"] for n in names])


def short_pairs(mask: BoolArray, per_path: NDArray[np.int_], n_unknown: int) -> BoolArray:
    """[P] pairs whose present paths (mask [P, n_paths]) carry fewer geometric channel
    parameters than ``n_unknown`` states while some path is missing (the planar counting
    rule per pair)."""
    n_obs = mask.astype(int) @ per_path  # [P] parameters of the paths present
    return np.asarray((n_obs < n_unknown) & ~np.all(mask, axis=1))


def underdetermined_pairs(
    paths: Sequence[PathInfo], mask: BoolArray, n_unknown: int
) -> tuple[BoolArray, NDArray[np.object_]]:
    """Pairs left with fewer geometric channel parameters than ``n_unknown`` states because
    some of the layout's ``paths`` are missing ([P] flags) and their reasons ([P] objects,
    ``None`` elsewhere). A layout that is underdetermined with all its paths keeps the reason
    of :func:`bounds_from_state_fim` (nothing is missing for it)."""
    per_path = path_observations([p.name for p in paths])
    flagged = short_pairs(mask, per_path, n_unknown)
    reason = np.full(mask.shape[0], None, dtype=object)
    if np.any(flagged):
        # one message per distinct presence pattern (few), not per pair
        patterns, inverse = unique_rows(mask[flagged])
        texts = np.array(
            [
                underdetermined_reason(
                    int(row.astype(int) @ per_path),
                    n_unknown,
                    [p.name for p, ok in zip(paths, row, strict=True) if not ok],
                )
                for row in patterns
            ],
            dtype=object,
        )
        reason[flagged] = texts[inverse.ravel()]
    return flagged, reason


def unique_rows(flags: BoolArray) -> tuple[BoolArray, NDArray[np.int_]]:
    """``np.unique(flags, axis=0, return_inverse=True)`` of [P, K] flags (the same sorted
    patterns and indices): each row read as a K-bit integer (a sort of P integers instead of a
    lexicographic sort of rows) when K ≤ 62, else by rows."""
    k = flags.shape[1]
    if k > 62:
        patterns, inverse = np.unique(flags, axis=0, return_inverse=True)
        return patterns, inverse.ravel()
    # bit k−1−j for column j: integer order = the rows' lexicographic order (False < True)
    codes = flags.astype(np.int64) @ (np.int64(1) << np.arange(k - 1, -1, -1, dtype=np.int64))
    values, inverse = np.unique(codes, return_inverse=True)
    patterns = ((values[:, None] >> np.arange(k - 1, -1, -1, dtype=np.int64)) & 1).astype(bool)
    return patterns, inverse.ravel()


def mask_channel_bounds(
    chan: dict[str, dict[str, FloatArray]], presence: dict[str, BoolArray]
) -> None:
    """A missing path's DEB/SEBs become ``inf`` (``null`` in JSON), in place."""
    for name, bounds in chan.items():
        for values in bounds.values():
            values[~presence[name]] = np.inf


def bounds_from_state_fim(
    f: FloatArray,
    known: list[KnownPart] | tuple[KnownPart, ...],
    n_observations: int | None,
    factors: Callable[[NDArray[np.int_]], FloatArray] | None = None,
    clock: FloatArray | None = None,
) -> tuple[FloatArray | None, FloatArray, FloatArray | None, NDArray[np.object_]]:
    """PEB_T, PEB_R, CEB and reasons from [P, 7, 7] information on [p_T, p_R, B].

    ``n_observations`` is the number of geometric channel parameters (3L, +1 with LOS); fewer
    than the unknown states makes every pair singular with an explicit reason (``None``: no
    counting rule, the spherical model). ``factors(idx)`` gives the stacked square-root
    factors [len(idx), n_obs, 7] of the pairs
    idx (:func:`path_factor_rows`); without it they are taken from F itself (correct
    identifiability, but the accuracy of the squared form). The inversion is
    :func:`ris_planner.inversion.crb.crb_diagonal`. ``clock`` [P, 7]: the clock offset as a
    combination
    of the states of F when F is on other coordinates than [p_T, p_R, B] (the LOS-referenced
    clock of :func:`los_referenced`); default the last state.
    """
    keep = kept_states(known)
    n_pairs = f.shape[0]
    reason = np.full(n_pairs, None, dtype=object)
    underdetermined = n_observations is not None and n_observations < keep.size
    if underdetermined:
        assert n_observations is not None
        reason[:] = underdetermined_reason(n_observations, keep.size)
        diag = np.full((n_pairs, keep.size), np.inf)
    else:
        rows = factors if factors is not None else _factors_of_fim(f)
        everything = keep.size == f.shape[-1]  # nothing known: F as it is
        memo: dict[bytes, FloatArray] = {}

        def kept_rows(idx: NDArray[np.int_]) -> FloatArray:
            # the diagonal and the clock route ask for the same slow pairs: factor them once
            key = idx.tobytes()
            if key not in memo:
                memo[key] = rows(idx)[:, :, keep]
            return memo[key]

        f_kept = ldl.pack(f if everything else f[:, keep][:, :, keep])
        d, _ = crb.crb_diagonal(f_kept, keep.size, kept_rows)
        diag = d.T
        if clock is not None and 6 in keep:
            diag[:, -1] = crb.crb_quadratic(f_kept, keep.size, kept_rows, clock[:, keep])

    def part(name: str) -> FloatArray | None:
        cols = [i for i, k in enumerate(keep) if k in PART_STATES[name]]
        if not cols:
            return None
        # Σ over the part's states, added left to right (a row sum's order) column by column
        total = diag[:, cols[0]].copy()
        for c in cols[1:]:
            total += diag[:, c]
        return np.asarray(np.sqrt(total))

    bounds = {name: part(name) for name in PART_STATES}
    peb_rx = bounds["rx"]
    assert peb_rx is not None  # RX is never known
    if not underdetermined:
        reason[np.isinf(peb_rx)] = REASON_SINGULAR
        missing = [(PART_LABELS[name], np.isinf(b)) for name, b in bounds.items() if b is not None]
        for i in np.flatnonzero(np.isfinite(peb_rx) & np.any([m for _, m in missing], axis=0)):
            labels = ", ".join(label for label, m in missing if m[i])
            reason[i] = (
                f"{REASON_NOT_IDENTIFIABLE}: {labels} (a singular direction of the Fisher"
                " information involves only these states; the finite bounds are exact)"
            )
    return bounds["tx"], peb_rx, bounds["clock"], reason


def los_referenced(paths: list[PathInfo]) -> tuple[list[PathInfo], FloatArray]:
    """The paths on the LOS-referenced coordinates s' = [p_T, p_R, B'] with B' = B + d_TR
    (the LOS pseudo-range), and the clock B = B' − ∇d_TRᵀp as a combination [P, 7] of s'.

    The LOS measures d_TR + B far more precisely than the RIS paths measure anything, so F on
    [p_T, p_R, B] has a strong direction that is not a coordinate and its scaled condition
    number is huge (median 2e7 over the Fig. 10 planning pairs); on s' the LOS row is e_B' and
    the median is 250 (``examples/crb_accuracy.py``). A linear change of variables: the CRB of
    the positions is unchanged, J' = J T with T = I except T[6, :6] = −∇d_TR
    (:func:`to_los_reference`). ``paths[0]`` must be the LOS path.
    """
    grad = los_gradient(paths[0])
    out = [to_los_reference(p, grad) for p in paths]
    out[0].jacobian[:, 0, :6] = 0.0  # exactly e_B'
    clock = np.concatenate([-grad, np.ones((grad.shape[0], 1))], axis=1)
    return out, clock


def los_gradient(los: PathInfo) -> FloatArray:
    """∇d_TR w.r.t. [p_T, p_R], [P, 6]: the LOS path's Jacobian row (a view of it)."""
    return los.jacobian[:, 0, :6]


def to_los_reference(path: PathInfo, grad: FloatArray) -> PathInfo:
    """One path on the LOS-referenced coordinates of :func:`los_referenced`: J' = J T, i.e.
    J'[:, :, :6] = J[:, :, :6] − J[:, :, 6] ∇d_TRᵀ (grad [P, 6] from :func:`los_gradient`)."""
    jac = path.jacobian.copy()
    jac[:, :, :6] -= jac[:, :, 6:7] * grad[:, None, :]
    return replace(path, jacobian=jac)


def uses_los_reference(los: bool, known: list[KnownPart] | tuple[KnownPart, ...]) -> bool:
    """Whether the bounds are computed on the LOS-referenced coordinates (LOS present and the
    clock unknown; :func:`los_referenced`); the planning site cache follows the same rule."""
    return los and "clock" not in known


def bounds_from_paths(
    paths: list[PathInfo],
    known: list[KnownPart] | tuple[KnownPart, ...],
    n_observations: int | None,
    present: NDArray[np.bool_],
    state_fim: Callable[[], FloatArray],
) -> tuple[FloatArray | None, FloatArray, FloatArray | None, NDArray[np.object_]]:
    """PEB_T, PEB_R, CEB and reasons from the paths' equivalent FIMs and Jacobians (the one
    inversion of :func:`compute_bounds` and the planning scorer).

    ``present`` [P, n_paths]: paths missing for a pair contribute nothing; ``state_fim()``
    [P, 7, 7] is :func:`masked_state_information` of ``paths`` (the reported FIM), inverted
    as it is unless the LOS-referenced clock applies (then the referenced paths' sum is, and
    ``state_fim`` is not called).
    """
    clock = None
    if paths and paths[0].name == "los" and uses_los_reference(True, known):
        paths, clock = los_referenced(paths)
        f = masked_state_information(paths, present)
    else:
        f = state_fim()
    return bounds_from_state_fim(f, known, n_observations, path_factor_rows(paths, present), clock)


def live_bounds(
    paths: list[PathInfo],
    known: list[KnownPart] | tuple[KnownPart, ...],
    n_observations: int | None,
    present: NDArray[np.bool_],
    state_fim: Callable[[], FloatArray],
    settled: NDArray[np.bool_],
) -> tuple[FloatArray | None, FloatArray, FloatArray | None, NDArray[np.object_]]:
    """:func:`bounds_from_paths` of the pairs not ``settled`` ([P] flags: pairs whose bounds
    are ``inf`` whatever the inversion says – underdetermined by the paths they have, or
    degenerate – and whose reason the caller sets); settled pairs get ``inf`` and no reason.
    Each pair's inversion is its own, so the live pairs' values are those of the whole batch;
    in a blind area most pairs are settled and cost nothing."""
    if not np.any(settled):
        return bounds_from_paths(paths, known, n_observations, present, state_fim)
    live = np.flatnonzero(~settled)
    sub = [p.take(live) for p in paths]
    mask = present[live]
    parts = bounds_from_paths(
        sub, known, n_observations, mask, lambda: masked_state_information(sub, mask)
    )
    n = settled.shape[0]

    def spread(values: FloatArray | None) -> FloatArray | None:
        if values is None:
            return None
        out = np.full(n, np.inf)
        out[live] = values
        return out

    peb_tx, peb_rx, ceb = (spread(v) for v in parts[:3])
    reason = np.full(n, None, dtype=object)
    reason[live] = parts[3]
    assert peb_rx is not None  # RX is never known
    return peb_tx, peb_rx, ceb, reason


def _factors_of_fim(f: FloatArray) -> Callable[[NDArray[np.int_]], FloatArray]:
    """Square-root factors [p, 7, 7] of F itself (a symmetric square root by eigh)."""

    def rows(idx: NDArray[np.int_]) -> FloatArray:
        return crb.path_factor(f[idx], np.broadcast_to(np.eye(7), (idx.size, 7, 7)))

    return rows


def path_factor_rows(
    paths: list[PathInfo], present: NDArray[np.bool_] | None = None
) -> Callable[[NDArray[np.int_]], FloatArray]:
    """``factors(idx)``: the paths' stacked square-root factors [len(idx), n_obs, 7] of the
    pairs idx, in path order (``present`` [P, n_paths] zeroes a missing path's rows)."""

    def rows(idx: NDArray[np.int_]) -> FloatArray:
        mask = None if present is None else present[idx]
        return crb.stack_factors([p.factor(idx) for p in paths], mask)

    return rows


def channel_bounds(paths: list[PathInfo]) -> dict[str, dict[str, FloatArray]]:
    """DEB [m] and SEBs per path (eqs. DEB, SEB1, SEB2) from the equivalent FIMs, by the one
    inversion route of the bounds (:func:`ris_planner.inversion.crb.crb_diagonal` on each path's m×m
    EFIM with its square root L_ℓ as the factor): a parameter is ``inf`` only when it is not
    identifiable, so a linear (one-row) RIS, whose ζ is unobservable, keeps a finite DEB and
    SEB_ξ (docs/concepts/numerics.md)."""
    out: dict[str, dict[str, FloatArray]] = {}
    for p in paths:
        m = p.efim.shape[-1]
        diag, _ = crb.crb_diagonal(ldl.pack(p.efim), m, p.factor_on_channel)
        sd = np.sqrt(diag)
        if m == 1:
            out[p.name] = {"deb_m": sd[0]}
        else:
            out[p.name] = {"deb_m": sd[2], "seb_xi": sd[0], "seb_zeta": sd[1]}
    return out


def ue_on_ris(tx: FloatArray, rx: FloatArray, position: ArrayLike) -> NDArray[np.bool_]:
    """[P] pairs with a UE within MIN_UE_RIS_DISTANCE_M of the RIS at ``position``."""
    p = np.asarray(position, dtype=float)
    near_tx = geometry.norms(tx - p) < MIN_UE_RIS_DISTANCE_M
    return np.asarray(near_tx | (geometry.norms(rx - p) < MIN_UE_RIS_DISTANCE_M))


def stand_ins(
    tx: FloatArray, rx: FloatArray, bad: NDArray[np.bool_]
) -> tuple[FloatArray, FloatArray]:
    """The pairs with harmless stand-in positions where ``bad`` (degenerate pairs are evaluated
    there so the batch stays finite, and their bounds are then reported inf)."""
    if not np.any(bad):
        return tx, rx
    tx, rx = tx.copy(), rx.copy()
    tx[bad] += np.array([0.31, 0.17, 0.13])
    rx[bad] += np.array([-0.23, 0.29, -0.11])
    return tx, rx


def _degenerate_pairs(scenario: Scenario, tx: FloatArray, rx: FloatArray) -> NDArray[np.bool_]:
    bad = np.zeros(tx.shape[0], dtype=bool)
    if scenario.system.los:
        bad |= geometry.los_distance(tx, rx) < MIN_UE_RIS_DISTANCE_M
    for r in scenario.ris:
        bad |= ue_on_ris(tx, rx, r.position)
    return bad


def compute_bounds(
    scenario: Scenario,
    tx: ArrayLike | None = None,
    rx: ArrayLike | None = None,
    *,
    profiles: list[ComplexArray] | str | None = "codebook",
    beam_powers: ArrayLike | None = None,
    known: list[KnownPart] | None = None,
    presence: dict[str, BoolArray] | None = None,
    channel: bool = True,
) -> BoundsResult:
    """PEB_T, PEB_R, CEB, DEB/SEB for arrays of TX–RX pairs (no JSON round trip).

    scenario : the layout, system and codebook; tx, rx : [P, 3] or [3] positions overriding the
    document's; profiles : first-block profiles per RIS, ``None`` for the expected-random FIM,
    or ``"codebook"`` (default) to draw them from the document's codebook; beam_powers : [G̃]
    powers of the first-block beams (default: the codebook's γ_P powers for a DIR+DER
    codebook with ``gamma_p``, else uniform); known : overrides the document's ``known``;
    presence : the paths present per pair as :func:`scenario_path_presence` gives them, when
    the caller has them already (the planner's per-point bounds derive them from each point's
    visibility once for every layout, docs/concepts/planning.md); degenerate pairs are
    reported ``inf`` whatever their entry; channel : ``False`` leaves the per-path DEB/SEB out
    (``channel`` empty: a caller that needs the PEBs only, such as the planner's per-point
    bounds and objective checks, skips their inversions, and the codebook products of the
    pairs whose bounds are ``inf`` by the counting rule; the PEBs are the same).

    Pairs with a UE on a RIS (or TX = RX with LOS) get ``inf`` with a reason, never NaN.
    With ``scenario.environment`` only the paths present for a pair contribute
    (:func:`scenario_path_presence`, :func:`masked_state_information`). BLAS runs on one
    thread meanwhile (:mod:`ris_planner.runtime.blas`).
    """
    with blas.one_blas_thread():
        return _compute_bounds(scenario, tx, rx, profiles, beam_powers, known, presence, channel)


def _compute_bounds(
    scenario: Scenario,
    tx: ArrayLike | None,
    rx: ArrayLike | None,
    profiles: list[ComplexArray] | str | None,
    beam_powers: ArrayLike | None,
    known: list[KnownPart] | None,
    given: dict[str, BoolArray] | None = None,
    channel: bool = True,
) -> BoundsResult:
    tx_a = scenario.tx_array if tx is None else np.atleast_2d(np.asarray(tx, dtype=float))
    rx_a = scenario.rx_array if rx is None else np.atleast_2d(np.asarray(rx, dtype=float))
    if tx_a.shape != rx_a.shape or tx_a.ndim != 2 or tx_a.shape[1] != 3:
        raise ValueError(f"tx and rx must both be [P, 3] arrays, got {tx_a.shape} and {rx_a.shape}")
    if not (np.all(np.isfinite(tx_a)) and np.all(np.isfinite(rx_a))):
        raise ValueError("tx and rx must be finite coordinates")
    known_t: tuple[KnownPart, ...] = tuple(scenario.known if known is None else known)
    bad = _degenerate_pairs(scenario, tx_a, rx_a)
    tx_a, rx_a = stand_ins(tx_a, rx_a, bad)  # evaluated there, reported inf below
    if given is None:
        presence = scenario_path_presence(scenario, tx_a, rx_a)
    else:
        names = ["los"] + [f"ris{i + 1}" for i in range(len(scenario.ris))]
        if set(given) != set(names) or any(given[k].shape != (tx_a.shape[0],) for k in names):
            raise ValueError(f"presence must hold [P] flags for exactly {names}")
        presence = {k: np.array(given[k], dtype=bool) for k in names}
    prof = _codebook_profiles(scenario) if isinstance(profiles, str) else profiles
    powers = beam_weights(scenario, beam_powers, codebook_default=isinstance(profiles, str))
    system = scenario.system
    products, withheld = presence, np.zeros(tx_a.shape[0], dtype=bool)
    if not channel and system.wavefront == "planar":
        # a pair the counting rule settles (inf whatever its information) needs no codebook
        # products: only the per-path DEB/SEB, left out here, would read them
        names = [k for k in presence if k != "los" or system.los]  # the paths that count
        short = short_pairs(
            np.stack([presence[n] for n in names], axis=1),
            path_observations(names),
            int(kept_states(known_t).size),
        )
        withheld = short | bad
        if np.any(withheld):
            products = {k: v & ~withheld for k, v in presence.items()}
    paths, far = path_information(scenario, tx_a, rx_a, prof, powers, products)
    mask = present_path_mask(paths, presence)

    @cache
    def state_fim() -> FloatArray:  # on [p_T, p_R, B], as reported: once, when first needed
        with blas.one_blas_thread():
            f = masked_state_information(paths, mask)
        f[withheld] = np.nan  # settled pairs whose products were not formed
        return f

    n_obs = n_observations(len(scenario.ris), system.los, system.wavefront)
    if system.wavefront == "planar":
        # the counting rule of the planar model, per pair with the paths it has
        under, under_reason = underdetermined_pairs(paths, mask, int(kept_states(known_t).size))
    else:
        under = np.zeros(tx_a.shape[0], dtype=bool)
        under_reason = np.full(tx_a.shape[0], None, dtype=object)
    peb_tx, peb_rx, ceb, reason = live_bounds(paths, known_t, n_obs, mask, state_fim, under | bad)
    if system.wavefront == "planar":
        chan = channel_bounds(paths) if channel else {}
        mask_channel_bounds(chan, presence)
    else:  # null with REASON_CHANNEL_SPHERICAL in JSON; singularity decided numerically
        inf = np.full(tx_a.shape[0], np.inf)
        keys = {"los": ("deb_m",)}
        chan = {
            p.name: {k: inf.copy() for k in keys.get(p.name, ("deb_m", "seb_xi", "seb_zeta"))}
            for p in (paths if channel else [])
        }
    for flags, why in ((under, under_reason), (bad, REASON_DEGENERATE)):
        if np.any(flags):
            for arr in (peb_tx, peb_rx, ceb):
                if arr is not None:
                    arr[flags] = np.inf
            reason[flags] = why if isinstance(why, str) else why[flags]
    if np.any(bad):
        for arr in (v for c in chan.values() for v in c.values()):
            arr[bad] = np.inf
        far[bad] = False
    return BoundsResult(
        peb_tx=peb_tx,
        peb_rx=peb_rx,
        ceb=ceb,
        reason=reason,
        channel=chan,
        far_field=far,
        fim_source=state_fim,
        known=known_t,
        paths_present=presence,
        warnings=tuple(bounds_warnings(scenario, expected=prof is None, far=far)),
        wavefront=system.wavefront,
    )


def bounds_warnings(scenario: Scenario, *, expected: bool, far: NDArray[np.bool_]) -> list[str]:
    """The warnings of a bounds result: expected-random optimism (when the expected FIM was
    used), grating lobes, near-field majority (far : [P, L] far-field flags)."""
    system = scenario.system
    out = []
    if expected:
        out.append(advice.expected_random_warning(system.transmissions, len(scenario.ris)))
    wavelength = fim.Radio.from_system(system).wavelength
    names = [f"ris{i + 1}" for i in range(len(scenario.ris))]
    out.extend(advice.spacing_warnings(scenario.ris, wavelength, names))
    if far.size and system.wavefront == "planar":
        out.append(advice.near_field_warning(float(np.mean(np.all(far, axis=1)))))
    return [w for w in out if w is not None]


def bounds_document(scenario: Scenario) -> dict[str, Any]:
    """The result document of ``ris-planner bounds`` and ``POST /v1/bounds``: the bounds of
    the scenario's pairs (:meth:`BoundsResult.to_json`) and their provenance
    (:mod:`ris_planner.runtime.provenance`)."""
    out = compute_bounds(scenario).to_json(batch=scenario.is_batch)
    return out | {"provenance": provenance(scenario)}
