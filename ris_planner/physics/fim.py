"""Per-path Fisher information of eq. FIM_measurement, batched over UE pairs.

With unit-modulus pilots x_k, the same pilot in every transmission and powers δ_g², every
derivative of μ_{k,g} factors into a subcarrier part and a transmission part (docs/concepts/
model.md, "Fisher information"), so a path's block is

    I_ab = (2P/σ²) · Re{ S_ab · conj(c_a) c_b · Q_{i(a) i(b)} },

with S_ab the subcarrier sum (K, ∓jΣκ_k or Σκ_k², κ_k = 2πkΔf/c for the path length r = cτ),
c_a the gain factor of parameter a (ρ, e^{−jβ} or −jρ) and Q the transmission Gram matrix
Q = Σ_g δ_g² conj(t_g) t_g^T of t_g = ω_g^T [∂a_R/∂ξ, ∂a_R/∂ζ, a_R]. Cross-path blocks vanish
under the time-orthogonal profiles, so the FIM of η is block-diagonal by path; each path's
nuisance gain (α, β) is eliminated by a Schur complement, leaving an equivalent FIM on
(ξ, ζ, r) for a RIS path and on r0 for the LOS path.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.units import SPEED_OF_LIGHT
from ris_planner.model.scenario import SystemParams

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

DEGENERATE_GAIN_RTOL = 1e-14
"""A nuisance block whose determinant is below this fraction of the product of its diagonal
is treated as carrying no information (a beam pattern with a null on the path): the Schur
complement then uses the pseudo-inverse, which for that block is zero."""


def subcarrier_wavenumbers(system: SystemParams) -> FloatArray:
    """κ_k = 2πkΔf/c [rad/m], k = 1..K: d_k(τ) = exp(−jκ_k·cτ) for a path length cτ."""
    k = np.arange(1, system.subcarriers + 1, dtype=float)
    return np.asarray(2 * np.pi * k * system.subcarrier_spacing / SPEED_OF_LIGHT)


@dataclass(frozen=True)
class Radio:
    """The radio constants every FIM block needs (SI)."""

    wavelength: float
    snr_scale: float
    """2P/σ² [1/W·W] – the factor of eq. FIM_measurement."""
    subcarrier_sums: tuple[float, float, float]
    """(S0, S1, S2) = (K, Σκ_k, Σκ_k²) with κ_k = 2πkΔf/c [rad/m], k = 1..K."""
    transmissions: int

    @classmethod
    def from_system(cls, system: SystemParams) -> Radio:
        kappa = subcarrier_wavenumbers(system)
        return cls(
            wavelength=system.wavelength,
            snr_scale=2 * system.tx_power_w / system.noise_variance_w,
            subcarrier_sums=(
                float(system.subcarriers),
                float(kappa.sum()),
                float((kappa**2).sum()),
            ),
            transmissions=system.transmissions,
        )

    def subcarrier_matrix(self, delay_flags: NDArray[np.bool_]) -> ComplexArray:
        """S_ab for parameters whose derivative carries −jκ_k (flag True) or 1 (False)."""
        s0, s1, s2 = self.subcarrier_sums
        f = np.asarray(delay_flags, dtype=bool)
        return np.where(
            f[:, None] & f[None, :],
            s2,
            np.where(f[:, None], 1j * s1, np.where(f[None, :], -1j * s1, s0)),
        ).astype(complex)


# LOS path parameters (r0, α0, β0)
_LOS_DELAY = np.array([True, False, False])


def steering_gram(positions: FloatArray, wavelength: float) -> ComplexArray:
    """V^H V for V = [∂a_R/∂ξ, ∂a_R/∂ζ, a_R] – independent of ξ, ζ, [3, 3].

    With ∂a_R/∂ξ = jk·y ⊙ a_R, ∂a_R/∂ζ = jk·z ⊙ a_R and |a_R,n| = 1 (k = 2π/λ).
    """
    k = 2 * np.pi / wavelength
    y, z = positions[:, 1], positions[:, 2]
    return np.array(
        [
            [k**2 * (y @ y), k**2 * (y @ z), -1j * k * y.sum()],
            [k**2 * (y @ z), k**2 * (z @ z), -1j * k * z.sum()],
            [1j * k * y.sum(), 1j * k * z.sum(), float(len(y))],
        ],
        dtype=complex,
    )


def transmission_gram_expected(
    positions: FloatArray, wavelength: float, total_weight: float
) -> ComplexArray:
    """E[Q] over uniform random phases: Σ_g δ_g² · V^H V, [3, 3] (E[conj(ω^T u) ω^T v] = u^H v)."""
    return total_weight * steering_gram(positions, wavelength)


STEERING_CHUNK = 512
"""Pairs per block of :func:`transmission_vectors` and :func:`planar_transmission_gram`: a
block's steering matrix [N, 512] and product [3G̃, 512] stay in cache while they are used
(measured ≈ 1.4× faster than one pass over the 4753 Fig. 10 pairs)."""


def grid_axes(positions: FloatArray) -> tuple[FloatArray, FloatArray] | None:
    """(y of each column [cols], z of each row [rows]) when ``positions`` [N, 3] is a row-major
    grid – element n = r·cols + c at (·, y_c, z_r), the order of
    :func:`ris_planner.physics.geometry.element_positions` – else ``None`` (checked exactly)."""
    y, z = positions[:, 1], positions[:, 2]
    n = y.shape[0]
    changes = np.flatnonzero(z != z[0])
    cols = int(changes[0]) if changes.size else n
    if n % cols:
        return None
    yc, zr = y[:cols], z[::cols]
    if np.array_equal(y, np.tile(yc, n // cols)) and np.array_equal(z, np.repeat(zr, cols)):
        return yc, zr
    return None


PLANAR_MEMO_BYTES = 32 << 20
"""Most bytes of derivative-weighted profiles :func:`planar_weighted` keeps (read-only profiles
only; the least recently used go first): Table I's two RISs take 0.6 MB."""

_PLANAR_MEMO: OrderedDict[
    tuple[int, bytes, float],
    tuple[ComplexArray, ComplexArray, tuple[FloatArray, FloatArray] | None],
] = OrderedDict()
_PLANAR_LOCK = threading.Lock()


def planar_weighted(
    profiles: ComplexArray, positions: FloatArray, wavelength: float
) -> tuple[ComplexArray, tuple[FloatArray, FloatArray] | None]:
    """The [3G̃, N] derivative-weighted profiles [ω ⊙ jky; ω ⊙ jkz; ω] of
    :class:`_PlanarProducts` and the grid axes (:func:`grid_axes`) of ``positions``.

    Remembered (up to :data:`PLANAR_MEMO_BYTES`) when ``profiles`` is read-only through
    and through (the shared seeded draw of
    :func:`ris_planner.physics.codebooks.seeded_random_phases`:
    nobody can change it, so the same object has the same values): forming them is a fresh
    [3G̃, N] array per call, the largest allocation of a single pair's bounds. The values are
    those computed on every call."""
    key = None
    base = profiles.base
    if (
        not profiles.flags.writeable
        and isinstance(base, np.ndarray)
        and base.flags.owndata
        and not base.flags.writeable
    ):
        key = (id(profiles), positions.tobytes(), float(wavelength))
        with _PLANAR_LOCK:
            hit = _PLANAR_MEMO.get(key)
            if hit is not None and hit[0] is profiles:
                _PLANAR_MEMO.move_to_end(key)
                return hit[1], hit[2]
    k = 2 * np.pi / wavelength
    y, z = positions[:, 1], positions[:, 2]
    w3 = np.concatenate([profiles * (1j * k * y), profiles * (1j * k * z), profiles], axis=0)
    axes = grid_axes(positions)
    if key is not None and w3.nbytes <= PLANAR_MEMO_BYTES // 4:
        w3.flags.writeable = False
        with _PLANAR_LOCK:
            _PLANAR_MEMO[key] = (profiles, w3, axes)  # holds profiles: its id stays unique
            while sum(v[1].nbytes for v in _PLANAR_MEMO.values()) > PLANAR_MEMO_BYTES:
                _PLANAR_MEMO.popitem(last=False)
    return w3, axes


class _PlanarProducts:
    """The blocks of t_g = ω_g^T [∂a_R/∂ξ, ∂a_R/∂ζ, a_R] (eq. FIM_measurement's transmission
    part), with ω^T(jk·y ⊙ a) = (jk·y ⊙ ω)^T a: one (3G̃ × N) @ (N × P') product per block.

    On a grid (:func:`grid_axes`) the steering vector of eq. RIS_equivalent_gain_xi_zeta
    separates, a_R,n = e^{jk z_r ζ} · e^{jk y_c ξ}: rows + cols exponentials per pair instead
    of N (the product differs from e^{jk(y_c ξ + z_r ζ)} by rounding only;
    tests/test_fast_paths.py bounds it)."""

    def __init__(self, profiles: ComplexArray, positions: FloatArray, wavelength: float) -> None:
        self.k = 2 * np.pi / wavelength
        self.y, self.z = positions[:, 1], positions[:, 2]
        self.g = profiles.shape[0]
        self.w3, self.axes = planar_weighted(profiles, positions, wavelength)

    def steering(self, xi: FloatArray, zeta: FloatArray) -> ComplexArray:
        """[N, P'] steering vectors a_R(ξ, ζ) of the block's pairs."""
        k = self.k
        if self.axes is None:  # element by element, exp(jk(yξ + zζ))
            phase = np.multiply.outer(self.y, xi)
            phase += np.multiply.outer(self.z, zeta)
            return _unit_phasors(k * phase)
        yc, zr = self.axes
        a_y = _unit_phasors(k * np.multiply.outer(yc, xi))  # [cols, P']
        a_z = _unit_phasors(k * np.multiply.outer(zr, zeta))  # [rows, P']
        return (a_z[:, None, :] * a_y[None, :, :]).reshape(self.y.shape[0], xi.shape[0])

    def block(
        self, xi: FloatArray, zeta: FloatArray, out: ComplexArray | None = None
    ) -> ComplexArray:
        """[3G̃, P'] products of one block (rows ∂ξ, ∂ζ, response; G̃ each), in ``out`` if
        given."""
        return np.asarray(np.matmul(self.w3, self.steering(xi, zeta), out=out))

    def as_vectors(self, block: ComplexArray) -> ComplexArray:
        """[3G̃, P'] → the [P', G̃, 3] view t."""
        return np.asarray(block.reshape(3, self.g, -1).transpose(2, 1, 0))


def _unit_phasors(phase: FloatArray) -> ComplexArray:
    """e^{j·phase}, built in place (the same roundings as ``np.exp(1j * phase)``)."""
    a = np.zeros(phase.shape, dtype=complex)
    a.imag = phase
    return np.exp(a, out=a)


def transmission_vectors(
    profiles: ComplexArray,
    positions: FloatArray,
    xi: FloatArray,
    zeta: FloatArray,
    wavelength: float,
) -> ComplexArray:
    """t_g = ω_g^T [∂a_R/∂ξ, ∂a_R/∂ζ, a_R] for all pairs, block by block of
    :data:`STEERING_CHUNK` pairs (:class:`_PlanarProducts`).

    profiles : [G̃, N]; positions : [N, 3]; xi, zeta : [P]. Returns [P, G̃, 3].
    """
    prod = _PlanarProducts(profiles, positions, wavelength)
    p = xi.shape[0]
    out = np.empty((3 * prod.g, p), dtype=complex)
    for s in range(0, p, STEERING_CHUNK):
        e = min(p, s + STEERING_CHUNK)
        prod.block(xi[s:e], zeta[s:e], out=out[:, s:e])
    return prod.as_vectors(out)


def transmission_gram(t: ComplexArray, weights: FloatArray) -> ComplexArray:
    """Q = Σ_g w_g conj(t_g) t_g^T, [P, m, m]; t : [P, G', m], weights : [G'] (= δ_g²).

    The upper triangle entry by entry, each a sum over g of [G', P] products (vectorised along
    the pairs, as :func:`transmission_vectors` lays t out), the lower one its conjugate and the
    diagonal real: Q is Hermitian exactly. Uniform unit weights skip the (exact) multiplication
    by 1."""
    r = t.transpose(2, 1, 0)  # [m, G', P]
    weighted = r if np.all(weights == 1.0) else r * weights[None, :, None]
    conj = np.conj(r)
    m = r.shape[0]
    q = np.empty((t.shape[0], m, m), dtype=complex)
    for i in range(m):
        q[:, i, i] = (conj[i] * weighted[i]).real.sum(axis=0)
        for j in range(i + 1, m):
            q[:, i, j] = (conj[i] * weighted[j]).sum(axis=0)
            q[:, j, i] = np.conj(q[:, i, j])
    return q


def planar_transmission_gram(
    profiles: ComplexArray,
    positions: FloatArray,
    xi: FloatArray,
    zeta: FloatArray,
    wavelength: float,
    weights: FloatArray,
) -> ComplexArray:
    """Q [P, 3, 3] of the planar model: :func:`transmission_gram` of
    :func:`transmission_vectors`, formed block by block of :data:`STEERING_CHUNK` pairs while
    the block is in cache (each pair's Q depends on that pair only: the same values)."""
    prod = _PlanarProducts(profiles, positions, wavelength)
    p = xi.shape[0]
    q = np.empty((p, 3, 3), dtype=complex)
    for s in range(0, p, STEERING_CHUNK):
        e = min(p, s + STEERING_CHUNK)
        q[s:e] = transmission_gram(prod.as_vectors(prod.block(xi[s:e], zeta[s:e])), weights)
    return q


def ris_path_fim(q: ComplexArray, alpha: FloatArray, radio: Radio) -> FloatArray:
    """The FIM block of one RIS path on (spatial parameters, r, α, β) (eq. FIM_measurement),
    [P, m+3, m+3]: (ξ, ζ, r, α, β) for the planar model (m = 2), (p_T, p_R, r, α, β) for the
    spherical one (m = 6, :mod:`ris_planner.physics.spherical`).

    q : [P, m+1, m+1] or [m+1, m+1] transmission Gram (spatial derivatives first, then the
    response itself); alpha : [P] |ρ_ℓ|. The phase β drops out. Formed with the pairs on the
    last axis (long contiguous loops), then laid out [P, ·, ·].
    """
    n = alpha.shape[0]
    m = q.shape[-1] - 1
    # parameters → column of t_g (r, α, β all use the response itself), and the −jκ_k flags
    t_index = np.array([*range(m), m, m, m])
    delay = np.array([False] * m + [True, False, False])
    # [m+3, P] gain factors: ρ (spatial and r), e^{−jβ}, −jρ (β = 0 without loss of generality)
    c = np.zeros((m + 3, n), dtype=complex)
    c[0 : m + 1] = alpha
    c[m + 1] = 1.0
    c[m + 2] = -1j * alpha
    # [m+3, m+3, P]
    qm = np.broadcast_to(q, (n, m + 1, m + 1)).transpose(1, 2, 0)[t_index[:, None], t_index]
    s = radio.subcarrier_matrix(delay)
    prod = s[:, :, None] * np.conj(c)[:, None, :] * c[None, :, :] * qm
    out = np.empty((n, m + 3, m + 3))
    np.multiply(radio.snr_scale, prod.real, out=out.transpose(1, 2, 0))
    return out


def los_path_fim(total_weight: float, alpha0: FloatArray, radio: Radio) -> FloatArray:
    """The 3×3 FIM block of the LOS path on (r0, α0, β0), [P, 3, 3]; t_g = 1 for all g."""
    n = alpha0.shape[0]
    c = np.zeros((n, 3), dtype=complex)
    c[:, 0] = alpha0
    c[:, 1] = 1.0
    c[:, 2] = -1j * alpha0
    s = radio.subcarrier_matrix(_LOS_DELAY)
    return (
        radio.snr_scale * total_weight * np.real(s[None] * np.conj(c)[:, :, None] * c[:, None, :])
    )


def eliminate_nuisance(fim: FloatArray, n_keep: int) -> FloatArray:
    """Equivalent FIM of the first ``n_keep`` parameters: A − C D⁺ Cᵀ, [P, n_keep, n_keep].

    fim : [P, n, n] with the nuisance (α, β) as the trailing 2×2 block D.
    """
    a = fim[:, :n_keep, :n_keep]
    cmat = fim[:, :n_keep, n_keep:]
    d = fim[:, n_keep:, n_keep:]
    det = d[:, 0, 0] * d[:, 1, 1] - d[:, 0, 1] * d[:, 1, 0]
    scale = np.abs(d[:, 0, 0] * d[:, 1, 1])
    ok = det > DEGENERATE_GAIN_RTOL * scale
    # [P, 2, 2] closed-form inverse, zero where the block is degenerate
    inv = np.zeros_like(d)
    safe = np.where(ok, det, 1.0)
    inv[:, 0, 0] = d[:, 1, 1] / safe
    inv[:, 1, 1] = d[:, 0, 0] / safe
    inv[:, 0, 1] = -d[:, 0, 1] / safe
    inv[:, 1, 0] = -d[:, 1, 0] / safe
    inv[~ok] = 0.0
    return np.asarray(a - cmat @ inv @ cmat.transpose(0, 2, 1))
