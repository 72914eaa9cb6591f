"""Received-signal simulator of section II-B (eqs. signal_model, channel_LOS_MP, channel_RIS_MP)
and the time-orthogonal path separation of eq. ytilde.

Y[k, g] = √P x_k δ_g Σ_m ρ_m d_k(τ_m) c_{m,g} + n_{k,g},  n ~ CN(0, σ²),  σ² = W·N0·NF,

with d_k(τ) = exp(−j κ_k r), κ_k = 2πkΔf/c and r = cτ the path length (k = 1..K), c_{m,g} = 1
for uncontrolled paths (LOS, TX–SP–RX) and ω_{ℓ,g}^T a_R(ξ_m, ζ_m) for paths through RIS ℓ. The
radio constants, profiles, codes and steering vectors come from the core (``fim.Radio``,
``codebooks``, ``geometry``, ``bounds.first_block_profiles``), so that the simulated signal is
the one whose Fisher information the bounds compute. With an ``environment`` the paths are
those of ``bounds.scenario_path_presence`` for the scenario's pair: a blocked LOS is the
LOS-blocked mode, a blocked or out-of-view RIS path is absent from the signal (its code column
stays: Γ is the layout's), and RIS path gains carry the pattern factor as in the bounds.

With ``multipath.site_reflections`` the first-order specular reflections off the environment's
faces (:func:`ris_planner.environment.reflections.specular_paths`, image method) join the
signal as multipath (:func:`site_reflection_paths`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from ris_planner.bounds.compute import (
    beam_weights,
    first_block_profiles,
    ris_path_gain,
    scenario_path_presence,
)
from ris_planner.bounds.paths import in_field_of_view, ris_serves
from ris_planner.core.units import SPEED_OF_LIGHT
from ris_planner.environment.reflections import specular_paths
from ris_planner.environment.scene import Scene
from ris_planner.model.scenario import Scenario
from ris_planner.model.simulation import Multipath
from ris_planner.physics import beams, codebooks, geometry
from ris_planner.physics.fim import Radio, subcarrier_wavenumbers

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
IntArray = NDArray[np.int_]


@dataclass(frozen=True)
class RisArray:
    """Pose and element grid of one RIS (local element positions [N, 3], rotation [3, 3])."""

    position: FloatArray
    rotation: FloatArray
    orientation: FloatArray
    elements: FloatArray
    rows: int
    cols: int
    spacing: float

    def period(self, wavelength: float) -> float:
        """Period λ/d of ξ and ζ in a_R (eq. RIS_equivalent_gain_xi_zeta); 2 at d = λ/2."""
        return wavelength / self.spacing


def ris_arrays(scenario: Scenario) -> tuple[RisArray, ...]:
    """Pose and element grid of every RIS (element spacing λ/2 unless given)."""
    lam = scenario.system.wavelength
    return tuple(
        RisArray(
            position=np.asarray(r.position, dtype=float),
            rotation=geometry.rotation_matrix(r.orientation),
            orientation=np.asarray(r.orientation, dtype=float),
            elements=beams.ris_element_positions(r, lam),
            rows=r.rows,
            cols=r.cols,
            spacing=r.element_spacing(lam),
        )
        for r in scenario.ris
    )


@dataclass(frozen=True)
class SignalSetup:
    """Everything the simulator and the estimator share for one scenario (SI units).

    ``profiles[ℓ]`` is RIS ℓ's first block [G̃, N]; ``full_profiles[ℓ]`` the sequence [G, N] of
    eq. orthogonal_profiles; ``code`` is B [Γ, L+1]; ``delta`` [G] the amplitudes δ_g;
    ``present`` [L+1] which paths exist for the scenario's pair (entry 0 the LOS, ℓ RIS ℓ).
    """

    scenario: Scenario
    radio: Radio
    ris: tuple[RisArray, ...]
    profiles: tuple[ComplexArray, ...]
    full_profiles: tuple[ComplexArray, ...]
    code: ComplexArray
    delta: FloatArray
    pilots: ComplexArray
    kappa: FloatArray
    tx_power_w: float
    noise_variance_w: float
    present: NDArray[np.bool_]

    @property
    def n_ris(self) -> int:
        return len(self.ris)

    @property
    def ris_present(self) -> tuple[int, ...]:
        """Indices (0-based) of the RISs whose path exists for the pair."""
        return tuple(int(i) for i in np.flatnonzero(self.present[1:]))

    @property
    def gamma(self) -> int:
        return int(self.code.shape[0])

    @property
    def g_tilde(self) -> int:
        return self.delta.shape[0] // self.gamma

    @property
    def subcarriers(self) -> int:
        return int(self.kappa.shape[0])

    @property
    def los(self) -> bool:
        """Whether the LOS path exists (``system.los`` and, in an environment, a clear leg)."""
        return bool(self.present[0])

    @property
    def wavelength(self) -> float:
        return self.radio.wavelength

    @property
    def delay_period_m(self) -> float:
        """c/Δf: path lengths are identifiable modulo this (d_k(r) is periodic in r)."""
        return SPEED_OF_LIGHT / self.scenario.system.subcarrier_spacing

    @cached_property
    def beam_weights(self) -> FloatArray:
        """δ² of the first block, [G̃] (the powers the core's ``beam_powers`` takes)."""
        return np.asarray(self.delta[: self.g_tilde] ** 2)


def signal_setup(
    scenario: Scenario,
    *,
    beam_powers: FloatArray | None = None,
    pilot_seed: int = 0,
) -> SignalSetup:
    """Profiles, codes, pilots and radio constants for a scenario.

    beam_powers : [G̃] powers δ² of the first-block beams (repeated over the Γ blocks, as the
    bounds assume); default the codebook's (:func:`ris_planner.bounds.compute.beam_weights`: γ_P
    powers
    of a DIR+DER codebook, else uniform), so the simulated signal and its bounds agree.
    Pilots x_k are unit-modulus with seeded random phases.
    """
    system = scenario.system
    n_ris = len(scenario.ris)
    code = codebooks.orthogonal_code_matrix(system.transmissions, n_ris)
    gamma = code.shape[0]
    g_tilde = system.transmissions // gamma
    profiles = first_block_profiles(scenario)
    if profiles is None:
        raise ValueError(
            "codebook.kind = 'expected_random' is an expectation, not profiles a RIS can apply;"
            " use 'random' (seeded) or 'explicit' for simulation"
        )
    weights = beam_weights(scenario, beam_powers)
    if np.any(weights < 0):
        raise ValueError(f"beam_powers must hold G/Γ = {g_tilde} values ≥ 0")
    arrays = ris_arrays(scenario)
    presence = scenario_path_presence(scenario, scenario.tx_array[:1], scenario.rx_array[:1])
    names = ["los", *(f"ris{i + 1}" for i in range(n_ris))]
    present = np.array([bool(presence[name][0]) for name in names])  # [L+1]
    full = tuple(codebooks.expand_profiles(profiles[i], code[:, i + 1]) for i in range(n_ris))
    rng = np.random.default_rng(pilot_seed)
    return SignalSetup(
        scenario=scenario,
        radio=Radio.from_system(system),
        ris=arrays,
        profiles=tuple(profiles),
        full_profiles=full,
        code=code,
        delta=np.tile(np.sqrt(weights), gamma),
        pilots=np.exp(1j * rng.uniform(0, 2 * np.pi, system.subcarriers)),
        kappa=subcarrier_wavenumbers(system),
        tx_power_w=system.tx_power_w,
        noise_variance_w=system.noise_variance_w,
        present=present,
    )


@dataclass(frozen=True)
class Paths:
    """The propagation paths of one realisation, [M] arrays.

    ``ris`` is 0 for uncontrolled paths (LOS, TX–SP–RX) and ℓ ≥ 1 for paths through RIS ℓ;
    ``length`` is c·τ including the clock offset B [m]; ``gain`` the complex ρ; ``xi``,
    ``zeta`` the spatial frequencies (0 for uncontrolled paths); ``direct`` marks the LOS and
    the L RIS paths (the ones the estimator looks for), the others are multipath.
    """

    ris: IntArray
    length: FloatArray
    gain: ComplexArray
    xi: FloatArray
    zeta: FloatArray
    direct: NDArray[np.bool_]

    def __add__(self, other: Paths) -> Paths:
        return Paths(
            *(np.concatenate([a, b]) for a, b in zip(self.astuple(), other.astuple(), strict=True))
        )

    def astuple(self) -> tuple[NDArray[np.generic], ...]:
        return (self.ris, self.length, self.gain, self.xi, self.zeta, self.direct)


def direct_paths(
    setup: SignalSetup,
    tx: FloatArray,
    rx: FloatArray,
    clock_offset_m: float,
    phases: FloatArray,
    amplitudes: FloatArray | None = None,
) -> Paths:
    """The LOS path (if present) and one path per present RIS (eqs. channel_LOS_MP,
    channel_RIS_MP); paths missing for the pair (``setup.present``) are left out.

    phases : [L+1] phases β of ρ = α e^{−jβ} (entry 0 for the LOS path, ℓ for RIS ℓ; entries
    of missing paths are ignored); amplitudes : [L+1] |ρ| overriding the Simulation-Parameters
    gains (for derivative checks).
    """
    tx2, rx2 = np.atleast_2d(tx), np.atleast_2d(rx)
    lam = setup.wavelength
    ris_idx, length, alpha, xi, zeta = [], [], [], [], []
    if setup.los:
        d0 = geometry.los_distance(tx2, rx2)
        ris_idx.append(0)
        length.append(float(d0[0]) + clock_offset_m)
        alpha.append(float(geometry.los_gain(d0, lam)[0]))
        xi.append(0.0)
        zeta.append(0.0)
    for i in setup.ris_present:
        arr, ris = setup.ris[i], setup.scenario.ris[i]
        geo = geometry.ris_path_geometry(tx2, rx2, arr.position, arr.orientation)
        ris_idx.append(i + 1)
        length.append(float(geo.path_length(clock_offset_m)[0]))
        alpha.append(float(ris_path_gain(ris, geo, tx2, rx2, lam)[0]))
        xi.append(float(geo.xi[0]))
        zeta.append(float(geo.zeta[0]))
    # [M] path index m (0 = LOS, ℓ = RIS ℓ) of each present path
    idx = np.asarray(ris_idx, dtype=int)
    ph = np.asarray(phases, dtype=float)[idx]
    amp = np.asarray(alpha if amplitudes is None else np.asarray(amplitudes, dtype=float)[idx])
    return Paths(
        ris=idx,
        length=np.asarray(length),
        gain=amp * np.exp(-1j * ph),
        xi=np.asarray(xi),
        zeta=np.asarray(zeta),
        direct=np.ones(idx.size, dtype=bool),
    )


def scatterer_paths(
    setup: SignalSetup,
    tx: FloatArray,
    rx: FloatArray,
    clock_offset_m: float,
    sp: FloatArray,
    rcs: FloatArray,
    tx_side: NDArray[np.bool_],
    phases: FloatArray,
) -> Paths:
    """Multipath of S scattering points: one TX–SP–RX path and, per RIS, one TX–SP–RIS–RX
    (``tx_side``) or TX–RIS–SP–RX path each (eqs. channel_LOS_MP, channel_RIS_MP).

    Gains (Simulation Parameters): |ρ_0,m| = √(4πc) λ / (16π² d_T,m d_R,m) and
    |ρ_ℓ,m| = √(4πc) λ² / (64π³ d_T,m d_ℓ,m d_R,ℓ) (TX side; RX side with d_T,ℓ d_ℓ,m d_R,m).
    sp : [S, 3]; rcs : [S] m²; tx_side : [S]; phases : [S, L+1] random phases β.
    """
    lam = setup.wavelength
    tx1, rx1 = np.asarray(tx, float).reshape(3), np.asarray(rx, float).reshape(3)
    d_t = np.linalg.norm(sp - tx1, axis=-1)
    d_r = np.linalg.norm(sp - rx1, axis=-1)
    scale = np.sqrt(4 * np.pi * rcs)
    ris_idx = [np.zeros(len(sp), dtype=int)]
    length = [d_t + d_r + clock_offset_m]
    alpha = [scale * lam / (16 * np.pi**2 * d_t * d_r)]
    xi, zeta = [np.zeros(len(sp))], [np.zeros(len(sp))]
    for i, arr in enumerate(setup.ris):
        # the RIS sees the SP instead of the UE on the SP's side: t from the RIS to the SP
        far_ue = np.where(tx_side[:, None], rx1[None, :], tx1[None, :])
        geo = geometry.ris_path_geometry(sp, far_ue, arr.position, arr.orientation)
        d_ue = np.where(tx_side, d_t, d_r)  # UE–SP hop
        ris_idx.append(np.full(len(sp), i + 1))
        length.append(d_ue + geo.d_tx + geo.d_rx + clock_offset_m)
        alpha.append(scale * lam**2 / (64 * np.pi**3 * d_ue * geo.d_tx * geo.d_rx))
        xi.append(geo.xi)
        zeta.append(geo.zeta)
    # [S, L+1] -> path order (uncontrolled first, then RIS 1..L), matching the lists above
    ph = np.asarray(phases, dtype=float).T.ravel()
    return Paths(
        ris=np.concatenate(ris_idx),
        length=np.concatenate(length),
        gain=np.concatenate(alpha) * np.exp(-1j * ph),
        xi=np.concatenate(xi),
        zeta=np.concatenate(zeta),
        direct=np.zeros(len(ph), dtype=bool),
    )


def site_reflection_paths(
    setup: SignalSetup,
    tx: FloatArray,
    rx: FloatArray,
    clock_offset_m: float,
    phases: FloatArray,
) -> Paths:
    """First-order specular reflections off the environment's faces (image method,
    docs/concepts/environment.md "Reflections"; docs/guides/estimation.md), as multipath
    (``direct`` False).

    * LOS (only with ``system.los``): per face reflecting the TX–RX leg, a copy of the LOS path
      with the image geometry: length L' = |p_R − p_T'| (+ B), gain R · λ/(4π L').
    * TX–RIS ℓ leg: the RIS sees the TX's image p_T' (the wave arrives from it): ξ, ζ, the
      pattern factor and the length |p_T' − p_ℓ| + |p_ℓ − p_R| (+ B) are those of a TX at p_T',
      the gain R · |ρ_ℓ(p_T', p_R)|; it exists when the image is in the RIS's field of view and
      the RIS serves the RX (the other leg clear).
    * RIS ℓ–RX leg: the same with the RX's image p_R'.

    R is the face's Fresnel coefficient at the incidence angle. Phases: a reflected copy of
    path m carries path m's random phase β_m (``phases`` [L+1]) and the carrier phase of its
    extra length, e^{−j 2π (L' − L)/λ} (L the direct path's length; the delay vectors d_k hold
    only the subcarrier offsets κ_k): the direct and the reflected copy interfere as on site.
    """
    sc = setup.scenario
    lam = setup.wavelength
    tx1 = np.asarray(tx, dtype=float).reshape(1, 3)
    rx1 = np.asarray(rx, dtype=float).reshape(1, 3)
    scene = Scene.from_environment(sc.environment)
    centres = np.array([arr.position for arr in setup.ris]).reshape(-1, 3)
    n_ris = centres.shape[0]
    # one batched query: TX→RX, TX→RIS ℓ, RX→RIS ℓ (the image is the source's)
    sources = np.concatenate([tx1, np.repeat(tx1, n_ris, 0), np.repeat(rx1, n_ris, 0)])
    sinks = np.concatenate([rx1, centres, centres])
    spec = specular_paths(scene, sources, sinks, sc.system.carrier_hz)
    ris_idx: list[int] = []
    length: list[float] = []
    gain: list[complex] = []
    xi: list[float] = []
    zeta: list[float] = []
    if setup.scenario.system.los:
        d0 = float(geometry.los_distance(tx1, rx1)[0])
        for k in np.flatnonzero(spec.valid[0]):
            lk = float(spec.length[0, k])
            extra = np.exp(-2j * np.pi * (lk - d0) / lam)
            ris_idx.append(0)
            length.append(lk + clock_offset_m)
            gain.append(complex(spec.coefficient[0, k] * lam / (4 * np.pi * lk) * extra))
            xi.append(0.0)
            zeta.append(0.0)
    for i, arr in enumerate(setup.ris):
        ris = sc.ris[i]
        direct = geometry.ris_path_geometry(tx1, rx1, arr.position, arr.orientation)
        r_direct = float(direct.d_tx[0] + direct.d_rx[0])
        serves_rx = bool(ris_serves(scene, ris, rx1)[0])
        serves_tx = bool(ris_serves(scene, ris, tx1)[0])
        for row, other_ok, tx_side in ((1 + i, serves_rx, True), (1 + n_ris + i, serves_tx, False)):
            if not other_ok:
                continue
            for k in np.flatnonzero(spec.valid[row]):
                image = spec.image[row, k][None, :]
                if not in_field_of_view(ris, image)[0]:
                    continue
                a, b = (image, rx1) if tx_side else (tx1, image)
                geo = geometry.ris_path_geometry(a, b, arr.position, arr.orientation)
                r = float(geo.d_tx[0] + geo.d_rx[0])
                alpha = float(ris_path_gain(ris, geo, a, b, lam)[0])
                extra = np.exp(-2j * np.pi * (r - r_direct) / lam)
                ris_idx.append(i + 1)
                length.append(r + clock_offset_m)
                gain.append(complex(spec.coefficient[row, k] * alpha * extra))
                xi.append(float(geo.xi[0]))
                zeta.append(float(geo.zeta[0]))
    idx = np.asarray(ris_idx, dtype=int)
    ph = np.asarray(phases, dtype=float)[idx]
    return Paths(
        ris=idx,
        length=np.asarray(length, dtype=float),
        gain=np.asarray(gain, dtype=complex) * np.exp(-1j * ph),
        xi=np.asarray(xi, dtype=float),
        zeta=np.asarray(zeta, dtype=float),
        direct=np.zeros(idx.size, dtype=bool),
    )


def draw_scatterers(
    multipath: Multipath, rng: np.random.Generator
) -> tuple[FloatArray, FloatArray, NDArray[np.bool_]]:
    """Positions [S, 3], RCS [S] and TX-side flags [S] of one realisation's SPs (clusters are
    uniform in their disks: radius √u·R, angle uniform)."""
    pos = [np.asarray(s.position, float) for s in multipath.scatterers]
    rcs = [s.rcs_m2 for s in multipath.scatterers]
    side = [s.side == "tx" for s in multipath.scatterers]
    for c in multipath.clusters:
        rad = c.radius_m * np.sqrt(rng.uniform(size=c.count))
        ang = rng.uniform(0, 2 * np.pi, size=c.count)
        centre = np.asarray(c.center, dtype=float)
        pts = np.stack(
            [
                centre[0] + rad * np.cos(ang),
                centre[1] + rad * np.sin(ang),
                np.full(c.count, centre[2]),
            ],
            axis=-1,
        )
        pos.extend(pts)
        rcs.extend([c.rcs_m2] * c.count)
        side.extend([c.side == "tx"] * c.count)
    if not pos:
        return np.zeros((0, 3)), np.zeros(0), np.zeros(0, dtype=bool)
    return np.asarray(pos), np.asarray(rcs, dtype=float), np.asarray(side, dtype=bool)


def realisation_paths(setup: SignalSetup, multipath: Multipath, rng: np.random.Generator) -> Paths:
    """The true paths of one random realisation: uniform gain phases, the site's reflections
    (``multipath.site_reflections``: deterministic, with the phases of their direct paths),
    SPs drawn per cluster. The random draws are the same with and without reflections."""
    sc = setup.scenario
    tx, rx = sc.tx_array[0], sc.rx_array[0]
    b = sc.system.clock_offset_m
    direct_phases = rng.uniform(0, 2 * np.pi, setup.n_ris + 1)
    paths = direct_paths(setup, tx, rx, b, direct_phases)
    if multipath.site_reflections:
        paths = paths + site_reflection_paths(setup, tx, rx, b, direct_phases)
    if not multipath.scatterers and not multipath.clusters:
        return paths
    sp, rcs, side = draw_scatterers(multipath, rng)
    phases = rng.uniform(0, 2 * np.pi, (len(sp), setup.n_ris + 1))
    return paths + scatterer_paths(setup, tx, rx, b, sp, rcs, side, phases)


def transmission_factors(setup: SignalSetup, paths: Paths) -> ComplexArray:
    """c_{m,g}: 1 for uncontrolled paths, ω_{ℓ,g}^T a_R(ξ_m, ζ_m) through RIS ℓ, [M, G]."""
    out = np.ones((len(paths.ris), setup.delta.shape[0]), dtype=complex)
    for i, arr in enumerate(setup.ris):
        sel = paths.ris == i + 1
        if np.any(sel):
            # [M_ℓ, N] steering vectors (eq. RIS_equivalent_gain_xi_zeta) -> [M_ℓ, G]
            a = geometry.steering_vector(
                arr.elements, paths.xi[sel], paths.zeta[sel], setup.wavelength
            )
            out[sel] = a @ setup.full_profiles[i].T
    return out


def noise_free_signal(setup: SignalSetup, paths: Paths) -> ComplexArray:
    """μ = √P (x δ^T) ⊙ Σ_m ρ_m d(τ_m) c_m^T (eqs. signal_model without N), [K, G]."""
    # [K, M] delay vectors of eq. delay_matrix, gains folded in
    d = np.exp(-1j * np.outer(setup.kappa, paths.length)) * paths.gain[None, :]
    y = d @ transmission_factors(setup, paths)
    return np.asarray(np.sqrt(setup.tx_power_w) * setup.pilots[:, None] * y * setup.delta[None, :])


def complex_noise(
    shape: tuple[int, ...], variance: float, rng: np.random.Generator
) -> ComplexArray:
    """Circular complex Gaussian noise CN(0, variance)."""
    scale = np.sqrt(variance / 2)
    return np.asarray(scale * (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)))


def received_signal(setup: SignalSetup, paths: Paths, rng: np.random.Generator) -> ComplexArray:
    """Y = μ + N with n_{k,g} ~ CN(0, σ²), σ² = W·N0·NF (eq. signal_model), [K, G]."""
    mu = noise_free_signal(setup, paths)
    return mu + complex_noise(mu.shape, setup.noise_variance_w, rng)


def separate_paths(setup: SignalSetup, y: ComplexArray) -> ComplexArray:
    """Ỹ_ℓ = (1/Γ) Σ_i b_{ℓ,i} Y^(i) for ℓ = 0..L (eq. ytilde), [L+1, K, G̃].

    Y^(i) is the i-th block of G̃ transmissions; the noise of Ỹ_ℓ is CN(0, σ²/Γ).
    """
    k = y.shape[0]
    blocks = y.reshape(k, setup.gamma, setup.g_tilde)
    return np.asarray(np.einsum("kig,il->lkg", blocks, setup.code) / setup.gamma)
