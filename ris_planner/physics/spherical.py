"""Spherical-wave (exact per-element) RIS response and its transmission Gram (docs/
concepts/wavefront.md).

Element n at global r_n = p_ℓ + R z_n responds with
a_n = exp(jφ_n), φ_n = −(2π/λ)·[(‖p_T − r_n‖ − d_T) + (‖p_R − r_n‖ − d_R)],
d = distances to the RIS centre; far away φ_n → (2π/λ)(ξ y_n + ζ z_n), the planar a_R(ξ, ζ).
The information is taken directly on the positions: the path's "spatial" parameters are
p_T, p_R themselves (through a), next to cτ = d_T + d_R + B and the gain (α, β), so the
transmission vectors are t_g = ω_gᵀ [∂a/∂p_T,x, …, ∂a/∂p_R,z, a] (7 columns, ∂a_n/∂p = j a_n
∂φ_n/∂p) and the expected Gram over uniform phases is G·Vᴴ V (E[conj(ωᵀu) ωᵀv] = uᴴv).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from numpy.typing import NDArray

from ris_planner.model.scenario import RIS
from ris_planner.physics import geometry

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
IntArray = NDArray[np.int_]

CHUNK_ELEMENTS = 1 << 21
"""Pairs × elements per chunk of the per-element arrays (≈ 100 MB of [chunk, N, 6] floats)."""

GRAM_MAX_POINTS = 1000
"""Up to this many distinct UE positions the expected Gram takes every position-pair block
from one [3U, N] @ [N, 3U] product (≤ 72 MB); above it, per pair."""


def element_positions_global(ris: RIS, wavelength: float) -> FloatArray:
    """r_n = p_ℓ + R z_n, [N, 3], metres."""
    local = geometry.element_positions(ris.rows, ris.cols, ris.element_spacing(wavelength))
    rot = geometry.rotation_matrix(ris.orientation)
    return np.asarray(np.asarray(ris.position, dtype=float) + local @ rot.T)


def chunks(n_pairs: int, n_elements: int) -> Iterator[slice]:
    """Pair slices with ≤ CHUNK_ELEMENTS pair-elements each."""
    step = max(1, CHUNK_ELEMENTS // max(1, n_elements))
    for start in range(0, n_pairs, step):
        yield slice(start, min(n_pairs, start + step))


def point_terms(points: FloatArray, ris: RIS, wavelength: float) -> tuple[FloatArray, FloatArray]:
    """Per UE position p: (φ_p [U, N] = −(2π/λ)(‖p − r_n‖ − d_p), the centred directions
    V_p [U, N, 3] = (p − r_n)/‖p − r_n‖ − (p − p_ℓ)/d_p); ∂φ_p,n/∂p = −(2π/λ) V_p,n.

    A pair's phase is φ_T + φ_R, and its gradient on [p_T, p_R] is −(2π/λ)[V_T, V_R]: the
    per-element work is per position, not per pair.
    """
    k = 2 * np.pi / wavelength
    r = element_positions_global(ris, wavelength)
    centre = np.asarray(ris.position, dtype=float)
    phi = np.empty((points.shape[0], r.shape[0]))
    v = np.empty((points.shape[0], r.shape[0], 3))
    for sl in chunks(points.shape[0], r.shape[0]):
        # [u, N, 3] element → UE offsets, [u, N] distances
        e = points[sl, None, :] - r[None, :, :]
        dist = np.sqrt(np.einsum("pnc,pnc->pn", e, e))
        c = points[sl] - centre
        d = np.sqrt(np.einsum("pc,pc->p", c, c))
        phi[sl] = -k * (dist - d[:, None])
        v[sl] = e / dist[:, :, None] - (c / d[:, None])[:, None, :]
    return phi, v


def _unique_points(tx: FloatArray, rx: FloatArray) -> tuple[FloatArray, IntArray, IntArray]:
    """(unique positions [U, 3], index of each pair's TX [P], of its RX [P])."""
    pts, inv = np.unique(np.concatenate([tx, rx]), axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    return pts, inv[: tx.shape[0]], inv[tx.shape[0] :]


def phases(
    tx: FloatArray, rx: FloatArray, ris: RIS, wavelength: float
) -> tuple[FloatArray, FloatArray]:
    """(φ [P, N], ∂φ/∂(p_T, p_R) [P, N, 6]) of the exact per-element response.

    ∂φ_n/∂p_T = −(2π/λ)((p_T − r_n)/‖p_T − r_n‖ − (p_T − p_ℓ)/d_T), likewise for p_R.
    """
    k = 2 * np.pi / wavelength
    pts, it, ir = _unique_points(tx, rx)
    phi, v = point_terms(pts, ris, wavelength)
    return phi[it] + phi[ir], -k * np.concatenate([v[it], v[ir]], axis=2)


def expected_gram(tx: FloatArray, rx: FloatArray, ris: RIS, wavelength: float) -> ComplexArray:
    """Vᴴ V per pair for V = [j a ⊙ ∂φ/∂p (6 columns), a], [P, 7, 7] (times Σ_g δ_g² it is
    E[Q]): k²·(V_i · V_j) sums of the centred directions, jk·ΣV beside a, and N; independent
    of the phases. All position blocks come from one Gram of the unique positions' V when
    they are few (:data:`GRAM_MAX_POINTS`), else per pair."""
    k = 2 * np.pi / wavelength
    n_el = ris.rows * ris.cols
    pts, it, ir = _unique_points(tx, rx)
    _, v = point_terms(pts, ris, wavelength)
    sums = v.sum(axis=1)  # [U, 3]
    out = np.empty((tx.shape[0], 7, 7), dtype=complex)
    if pts.shape[0] <= GRAM_MAX_POINTS:
        flat = v.transpose(1, 0, 2).reshape(n_el, -1)  # [N, 3U]
        # [U, 3, U, 3] all position-pair blocks in one matrix product
        m = (flat.T @ flat).reshape(pts.shape[0], 3, pts.shape[0], 3)
        tt, tr, rr = m[it, :, it, :], m[it, :, ir, :], m[ir, :, ir, :]
    else:
        self_gram = v.transpose(0, 2, 1) @ v  # [U, 3, 3]
        tt, rr = self_gram[it], self_gram[ir]
        tr = np.empty((tx.shape[0], 3, 3))
        for sl in chunks(tx.shape[0], n_el):
            tr[sl] = v[it[sl]].transpose(0, 2, 1) @ v[ir[sl]]
    out[:, :3, :3] = k**2 * tt
    out[:, :3, 3:6] = k**2 * tr
    out[:, 3:6, :3] = k**2 * tr.transpose(0, 2, 1)
    out[:, 3:6, 3:6] = k**2 * rr
    s = np.concatenate([sums[it], sums[ir]], axis=1)  # [P, 6]
    out[:, :6, 6] = 1j * k * s
    out[:, 6, :6] = -1j * k * s
    out[:, 6, 6] = n_el
    return out


def transmission_vectors(
    profiles: ComplexArray, tx: FloatArray, rx: FloatArray, ris: RIS, wavelength: float
) -> ComplexArray:
    """t_g = ω_gᵀ [j a ⊙ ∂φ/∂p, a] for the first-block profiles [G̃, N], [P, G̃, 7].

    j a ∂φ/∂p = −jk a V: a chunk's columns [a V_T, a V_R, a] are laid out [p·7, N] and take one
    matrix product with the profiles, the factor −jk applied to the [p, 7, G̃] result."""
    k = 2 * np.pi / wavelength
    g, n_el = profiles.shape
    pts, it, ir = _unique_points(tx, rx)
    phi, v = point_terms(pts, ris, wavelength)
    phasor = np.exp(1j * phi)  # [U, N]
    vt = np.ascontiguousarray(v.transpose(0, 2, 1))  # [U, 3, N]
    del v
    right = np.ascontiguousarray(profiles.T)  # [N, G̃]
    out = np.empty((tx.shape[0], g, 7), dtype=complex)
    for sl in chunks(tx.shape[0], n_el):
        p = sl.stop - sl.start
        a = phasor[it[sl]] * phasor[ir[sl]]  # [p, N]
        w = np.empty((p, 7, n_el), dtype=complex)
        np.multiply(a[:, None, :], vt[it[sl]], out=w[:, 0:3])
        np.multiply(a[:, None, :], vt[ir[sl]], out=w[:, 3:6])
        w[:, 6] = a
        t = (w.reshape(p * 7, n_el) @ right).reshape(p, 7, g)
        t[:, :6] *= -1j * k
        out[sl] = t.transpose(0, 2, 1)
    return out


def jacobian(geo: geometry.RisPathGeometry) -> FloatArray:
    """∂(p_T, p_R via a; cτ)/∂[p_T, p_R, B], [P, 7, 7]: identity on the positions, and
    ∂(cτ) = [u_T, u_R, 1]."""
    n = geo.d_tx.shape[0]
    jac = np.zeros((n, 7, 7))
    jac[:, np.arange(6), np.arange(6)] = 1.0
    jac[:, 6, 0:3] = geo.u_tx
    jac[:, 6, 3:6] = geo.u_rx
    jac[:, 6, 6] = 1.0
    return jac
