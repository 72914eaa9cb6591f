"""Geometry and channel parameters of section II, batched over UE pairs.

Conventions (conventions.md): R = Rz(yaw)·Ry(pitch)·Rx(roll); a RIS faces its local +x axis; its
elements lie on the local y–z plane. Every function takes arrays of UE positions with the pairs
on the leading axis and works for one RIS at a time (L is small; the pairs are many).

Delays are carried as path lengths r = c·τ [m] (eq. delay_matrix with τ = r/c), which keeps the
Fisher matrices well scaled; the delay error bound is then directly in metres.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


def rotation_matrix(orientation: ArrayLike) -> FloatArray:
    """R = Rz(yaw) · Ry(pitch) · Rx(roll).

    orientation : [..., 3] Euler angles [yaw, pitch, roll] in radians.
    Returns [..., 3, 3]; column 0 is the RIS normal (facing direction) in global coordinates.
    """
    o = np.asarray(orientation, dtype=float)
    if o.shape == (3,):  # one RIS's: computed once per orientation (the same bits)
        return _rotation_of(o.tobytes()).copy()
    return _rotation(o)


@lru_cache(maxsize=256)
def _rotation_of(orientation: bytes) -> FloatArray:
    return _rotation(np.frombuffer(orientation, dtype=float))


def _rotation(o: FloatArray) -> FloatArray:
    cy, sy = np.cos(o[..., 0]), np.sin(o[..., 0])
    cp, sp = np.cos(o[..., 1]), np.sin(o[..., 1])
    cr, sr = np.cos(o[..., 2]), np.sin(o[..., 2])
    # [..., 3, 3]: the product Rz @ Ry @ Rx written out
    return np.stack(
        [
            np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], axis=-1),
            np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], axis=-1),
            np.stack([-sp, cp * sr, cp * cr], axis=-1),
        ],
        axis=-2,
    )


def element_positions(rows: int, cols: int, spacing: float) -> FloatArray:
    """Local element positions Z^T of eq. av_steer, [N, 3].

    Element n = r·cols + c sits at (0, (c − (cols−1)/2)·d, (r − (rows−1)/2)·d).
    """
    r, c = np.divmod(np.arange(rows * cols), cols)
    return np.stack(
        [np.zeros(rows * cols), (c - (cols - 1) / 2) * spacing, (r - (rows - 1) / 2) * spacing],
        axis=-1,
    )


def fraunhofer_distance(rows: int, cols: int, spacing: float, wavelength: float) -> float:
    """2D²/λ with D the aperture diagonal (footnote 3: D = √2·0.05 m for 10×10 at λ/2)."""
    diag = spacing * float(np.hypot(rows, cols))
    return 2.0 * diag**2 / wavelength


@dataclass(frozen=True)
class RisPathGeometry:
    """Geometry of one RIS path for a batch of pairs (all arrays have pairs on axis 0).

    Attributes
    ----------
    t_tx, t_rx : [P, 3] unit direction vectors in the RIS frame (eqs. tv_T, tv_R).
    u_tx, u_rx : [P, 3] unit vectors from the RIS to the UEs, global frame.
    d_tx, d_rx : [P] distances RIS–TX and RIS–RX [m].
    rotation : [3, 3] R of the RIS.
    """

    t_tx: FloatArray
    t_rx: FloatArray
    u_tx: FloatArray
    u_rx: FloatArray
    d_tx: FloatArray
    d_rx: FloatArray
    rotation: FloatArray

    @property
    def xi(self) -> FloatArray:
        """ξ = t_T,2 + t_R,2 (eq. RIS_aoa_xi), [P]."""
        return self.t_tx[:, 1] + self.t_rx[:, 1]

    @property
    def zeta(self) -> FloatArray:
        """ζ = t_T,3 + t_R,3 (eq. RIS_aoa_xi), [P]."""
        return self.t_tx[:, 2] + self.t_rx[:, 2]

    def path_length(self, clock_offset: float | FloatArray) -> FloatArray:
        """c·τ_ℓ = d_T,ℓ + d_R,ℓ + B [m], [P]."""
        return self.d_tx + self.d_rx + clock_offset

    def gain(self, wavelength: float) -> FloatArray:
        """|ρ_ℓ| = λ² / (16π² d_T,ℓ d_R,ℓ) (Simulation Parameters), [P]."""
        return wavelength**2 / (16 * np.pi**2 * self.d_tx * self.d_rx)

    def jacobian(self) -> FloatArray:
        """∂(ξ, ζ, c·τ)/∂[p_T, p_R, B], [P, 3, 7] (rows of J_S^T of eq. crb_sidelink).

        With u = (p − p_ℓ)/d, ∂t/∂p = R^T (I − u u^T)/d; ∂d/∂p = u^T; ∂(cτ)/∂B = 1.
        """
        n = self.d_tx.shape[0]
        jac = np.zeros((n, 3, 7))
        rt = self.rotation.T
        for cols, t, u, d in (
            (slice(0, 3), self.t_tx, self.u_tx, self.d_tx),
            (slice(3, 6), self.t_rx, self.u_rx, self.d_rx),
        ):
            # rows 1, 2 of R^T (I − u u^T)/d = (R^T − t u^T)/d, with t = R^T u: [P, 3] each
            jac[:, 0, cols] = (rt[1][None, :] - t[:, 1, None] * u) / d[:, None]
            jac[:, 1, cols] = (rt[2][None, :] - t[:, 2, None] * u) / d[:, None]
            jac[:, 2, cols] = u
        jac[:, 2, 6] = 1.0
        return jac


def norms(v: FloatArray) -> FloatArray:
    """Euclidean lengths of 3-vectors v [..., 3]: √((x² + y²) + z²), the roundings of
    ``np.linalg.norm(v, axis=-1)`` (a reduction over a length-3 axis adds in that order) in
    three array operations instead of a reduction per vector."""
    s = v * v
    return np.asarray(np.sqrt(s[..., 0] + s[..., 1] + s[..., 2]))


def ris_path_geometry(
    tx: FloatArray, rx: FloatArray, ris_position: ArrayLike, ris_orientation: ArrayLike
) -> RisPathGeometry:
    """Direction vectors, distances and rotation for one RIS (eqs. tv_T, tv_R).

    tx, rx : [P, 3] UE positions [m]; ris_position : [3], metres; ris_orientation : [3], radians.
    """
    rot = rotation_matrix(ris_orientation)
    p = np.asarray(ris_position, dtype=float)
    # [P, 3] global offsets RIS -> UE
    v_tx, v_rx = tx - p, rx - p
    d_tx, d_rx = norms(v_tx), norms(v_rx)
    u_tx, u_rx = v_tx / d_tx[:, None], v_rx / d_rx[:, None]
    # [P, 3] local direction vectors t = R^T u
    return RisPathGeometry(
        t_tx=u_tx @ rot,
        t_rx=u_rx @ rot,
        u_tx=u_tx,
        u_rx=u_rx,
        d_tx=d_tx,
        d_rx=d_rx,
        rotation=rot,
    )


def angles(t: FloatArray) -> FloatArray:
    """Azimuth and elevation [φ, θ] of local direction vectors (eqs. aoa, aod), [P, 2]."""
    return np.stack([np.arctan2(t[:, 1], t[:, 0]), np.arcsin(np.clip(t[:, 2], -1, 1))], axis=-1)


def los_distance(tx: FloatArray, rx: FloatArray) -> FloatArray:
    """d0 = ‖p_T − p_R‖ [m], [P]."""
    return norms(tx - rx)


def los_gain(d0: FloatArray, wavelength: float) -> FloatArray:
    """|ρ0| = λ / (4π d0) (Simulation Parameters), [P]."""
    return wavelength / (4 * np.pi * d0)


def los_jacobian(tx: FloatArray, rx: FloatArray) -> FloatArray:
    """∂(c·τ0)/∂[p_T, p_R, B] with c·τ0 = ‖p_T − p_R‖ + B, [P, 1, 7]."""
    u = (tx - rx) / los_distance(tx, rx)[:, None]
    jac = np.zeros((tx.shape[0], 1, 7))
    jac[:, 0, 0:3] = u
    jac[:, 0, 3:6] = -u
    jac[:, 0, 6] = 1.0
    return jac


def steering_vector(
    positions: FloatArray, xi: ArrayLike, zeta: ArrayLike, wavelength: float
) -> NDArray[np.complex128]:
    """a_R(ξ, ζ) = exp(j 2π/λ Z^T [0, ξ, ζ]) (eq. RIS_equivalent_gain_xi_zeta).

    positions : [N, 3] local element positions; xi, zeta : [P]. Returns [P, N].
    """
    k = 2 * np.pi / wavelength
    xi_a, zeta_a = np.atleast_1d(np.asarray(xi, float)), np.atleast_1d(np.asarray(zeta, float))
    phase = k * (xi_a[:, None] * positions[None, :, 1] + zeta_a[:, None] * positions[None, :, 2])
    return np.asarray(np.exp(1j * phase))
