"""Geometry conventions (conventions.md) and the Jacobian against finite differences."""

from __future__ import annotations

import numpy as np
import pytest

from ris_planner.physics import geometry

FD_STEP_M = 1e-6
FD_RTOL = 1e-7
"""Central differences with h = 1e-6 m on functions with curvature ~1/d (d ≳ 1 m) have
truncation error ~h² ≈ 1e-12 and rounding ~ε/h ≈ 2e-10 relative to O(1) derivatives."""


def test_rotation_conventions() -> None:
    # the paper's RIS 2 at [4, 0, 2] with orientation [π, 0, 0] faces −x
    r = geometry.rotation_matrix([np.pi, 0.0, 0.0])
    np.testing.assert_allclose(r[:, 0], [-1, 0, 0], atol=1e-15)
    # a positive pitch tilts the face downwards
    r = geometry.rotation_matrix([0.0, np.pi / 6, 0.0])
    assert r[2, 0] == pytest.approx(-0.5)
    # R = Rz(yaw) Ry(pitch) Rx(roll), orthonormal with det 1
    o = np.array([0.3, -0.7, 1.1])
    cz, sz, cy, sy, cx, sx = (
        np.cos(o[0]),
        np.sin(o[0]),
        np.cos(o[1]),
        np.sin(o[1]),
        np.cos(o[2]),
        np.sin(o[2]),
    )
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    np.testing.assert_allclose(geometry.rotation_matrix(o), rz @ ry @ rx, atol=1e-15)
    # batched
    assert geometry.rotation_matrix(np.zeros((4, 2, 3))).shape == (4, 2, 3, 3)


def test_element_order() -> None:
    z = geometry.element_positions(rows=2, cols=3, spacing=0.5)
    # element n = r·cols + c at (0, (c − 1)·d, (r − 0.5)·d)
    np.testing.assert_allclose(z[0], [0, -0.5, -0.25])
    np.testing.assert_allclose(z[2], [0, 0.5, -0.25])
    np.testing.assert_allclose(z[3], [0, -0.5, 0.25])
    np.testing.assert_allclose(z.sum(axis=0), 0, atol=1e-15)


def test_direction_vectors_and_spatial_frequencies() -> None:
    tx = np.array([[-2.0, -4.0, 0.0]])
    rx = np.array([[2.0, 3.0, 0.0]])
    geo = geometry.ris_path_geometry(tx, rx, [4, 0, 2], [np.pi, 0, 0])
    # RIS 2 faces −x: local t = R^T u, so a UE at smaller x is in front (t_1 > 0)
    assert geo.t_tx[0, 0] > 0 and geo.t_rx[0, 0] > 0
    u_t = (tx[0] - [4, 0, 2]) / np.linalg.norm(tx[0] - [4, 0, 2])
    u_r = (rx[0] - [4, 0, 2]) / np.linalg.norm(rx[0] - [4, 0, 2])
    # with yaw π: local y = −global y, local z = global z
    assert geo.xi[0] == pytest.approx(-u_t[1] - u_r[1])
    assert geo.zeta[0] == pytest.approx(u_t[2] + u_r[2])
    ang = geometry.angles(geo.t_tx)
    t_back = np.array(
        [
            np.cos(ang[0, 0]) * np.cos(ang[0, 1]),
            np.sin(ang[0, 0]) * np.cos(ang[0, 1]),
            np.sin(ang[0, 1]),
        ]
    )
    np.testing.assert_allclose(t_back, geo.t_tx[0], atol=1e-14)  # eqs. aoa, tv_T


def test_jacobian_matches_finite_differences(rng: np.random.Generator) -> None:
    n = 5
    tx, rx = rng.uniform(-3, 3, (n, 3)), rng.uniform(-3, 3, (n, 3))
    p, o = rng.uniform(-5, 5, 3), rng.uniform(-np.pi, np.pi, 3)
    b = 2.5

    def eta(s: np.ndarray) -> np.ndarray:
        g = geometry.ris_path_geometry(s[:, 0:3], s[:, 3:6], p, o)
        return np.stack([g.xi, g.zeta, g.path_length(s[:, 6])], axis=-1)

    s0 = np.concatenate([tx, rx, np.full((n, 1), b)], axis=1)
    jac = geometry.ris_path_geometry(tx, rx, p, o).jacobian()
    for i in range(7):
        e = np.zeros(7)
        e[i] = FD_STEP_M
        fd = (eta(s0 + e) - eta(s0 - e)) / (2 * FD_STEP_M)
        np.testing.assert_allclose(jac[:, :, i], fd, rtol=FD_RTOL, atol=FD_RTOL)
    jl = geometry.los_jacobian(tx, rx)
    for i in range(7):
        e = np.zeros(7)
        e[i] = FD_STEP_M
        sp, sm = s0 + e, s0 - e
        fd = (
            np.linalg.norm(sp[:, :3] - sp[:, 3:6], axis=1)
            + sp[:, 6]
            - np.linalg.norm(sm[:, :3] - sm[:, 3:6], axis=1)
            - sm[:, 6]
        ) / (2 * FD_STEP_M)
        np.testing.assert_allclose(jl[:, 0, i], fd, rtol=FD_RTOL, atol=FD_RTOL)


def test_fraunhofer_distance_matches_footnote3() -> None:
    # 10×10 at λ/2 with λ = 1 cm: D = √2·0.05 m, 2D²/λ = 1 m
    assert geometry.fraunhofer_distance(10, 10, 0.005, 0.01) == pytest.approx(1.0)


def test_path_gains() -> None:
    lam = 0.01
    assert geometry.los_gain(np.array([2.0]), lam)[0] == pytest.approx(lam / (8 * np.pi))
    geo = geometry.ris_path_geometry(
        np.array([[1.0, 0, 0]]), np.array([[0, 2.0, 0]]), [0, 0, 0], [0, 0, 0]
    )
    assert geo.gain(lam)[0] == pytest.approx(lam**2 / (16 * np.pi**2 * 2.0))
