"""A deliberately naive, obviously-correct evaluation of eq. FIM_measurement.

One pair, full K×G sum, every cross-path term included, no factorisation, no Schur shortcuts:
build ∂μ_{k,g}/∂η for η = [η_0, η_1, …, η_L] (η_0 = [τ0, α0, β0], η_ℓ = [ξ, ζ, τ, α, β])
straight from the signal model (eqs. signal_model, delay_matrix, RIS_equivalent_gain_xi_zeta),
form I(η) = 2/σ² Σ_k Σ_g Re{(∂μ)^H ∂μ}, map it with a complex-step Jacobian J_S and
invert the full state FIM. It is the reference the fast code and the benchmarks compare with.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.units import SPEED_OF_LIGHT
from ris_planner.model.scenario import Scenario
from ris_planner.physics import geometry


def _norm(v: NDArray) -> NDArray:
    return np.sqrt(np.sum(v * v))  # analytic, so complex-step differentiation works


def channel_parameters(scenario: Scenario, tx: NDArray, rx: NDArray, b: complex) -> NDArray:
    """η for one pair, straight from positions: [τ0, α0, β0, (ξ, ζ, τ, α, β) per RIS]."""
    lam = scenario.system.wavelength
    eta: list[complex] = []
    if scenario.system.los:
        d0 = _norm(tx - rx)
        eta += [(d0 + b) / SPEED_OF_LIGHT, lam / (4 * np.pi * d0), 0.3]
    for ris in scenario.ris:
        rot = geometry.rotation_matrix(ris.orientation)
        p = np.asarray(ris.position, float)
        dt, dr = _norm(tx - p), _norm(rx - p)
        t_t = rot.T @ (tx - p) / dt
        t_r = rot.T @ (rx - p) / dr
        eta += [
            t_t[1] + t_r[1],
            t_t[2] + t_r[2],
            (dt + dr + b) / SPEED_OF_LIGHT,
            lam**2 / (16 * np.pi**2 * dt * dr),
            -0.7,
        ]
    return np.array(eta)


def naive_fim_eta(
    scenario: Scenario, eta: NDArray, full_profiles: list[NDArray], delta2: NDArray
) -> NDArray:
    """I(η) of eq. FIM_measurement by the full K×G sum; full_profiles [G, N] per RIS."""
    s = scenario.system
    K, G = s.subcarriers, s.transmissions
    lam = s.wavelength
    P, sigma2 = s.tx_power_w, s.noise_variance_w
    k_idx = np.arange(1, K + 1)
    x = np.exp(1j * 2 * np.pi * np.random.default_rng(5).random(K))  # any unit-modulus pilot
    delta = np.sqrt(delta2)
    derivs = []  # each [K, G]
    pos = 0
    amp = np.sqrt(P) * x[:, None] * delta[None, :]
    wk = 2 * np.pi * k_idx * s.subcarrier_spacing

    def d_of(tau: float) -> NDArray:
        return np.exp(-1j * wk * tau)[:, None]

    if s.los:
        tau, alpha, beta = eta[0:3]
        rho = alpha * np.exp(-1j * beta)
        derivs += [
            amp * rho * (-1j * wk)[:, None] * d_of(tau) * np.ones((1, G)),
            amp * np.exp(-1j * beta) * d_of(tau) * np.ones((1, G)),
            amp * (-1j) * rho * d_of(tau) * np.ones((1, G)),
        ]
        pos = 3
    for ell, ris in enumerate(scenario.ris):
        xi, zeta, tau, alpha, beta = eta[pos + 5 * ell : pos + 5 * ell + 5]
        rho = alpha * np.exp(-1j * beta)
        spacing = ris.spacing_m or lam / 2
        z = geometry.element_positions(ris.rows, ris.cols, spacing)
        kk = 2 * np.pi / lam
        a_r = np.exp(1j * kk * (z[:, 1] * xi + z[:, 2] * zeta))
        w = full_profiles[ell]  # [G, N]
        a_g = w @ a_r
        a_xi = w @ (1j * kk * z[:, 1] * a_r)
        a_zeta = w @ (1j * kk * z[:, 2] * a_r)
        dd = d_of(tau)
        derivs += [
            amp * rho * dd * a_xi[None, :],
            amp * rho * dd * a_zeta[None, :],
            amp * rho * (-1j * wk)[:, None] * dd * a_g[None, :],
            amp * np.exp(-1j * beta) * dd * a_g[None, :],
            amp * (-1j) * rho * dd * a_g[None, :],
        ]
    n = len(derivs)
    fim = np.zeros((n, n))
    for i in range(n):
        for j in range(n):
            fim[i, j] = 2 / sigma2 * np.sum(np.real(np.conj(derivs[i]) * derivs[j]))
    return fim


def numeric_jacobian(scenario: Scenario, tx: NDArray, rx: NDArray, b: float) -> NDArray:
    """∂η/∂s_N by complex-step differentiation (exact to rounding), [len(η), 7]."""
    s0 = np.concatenate([tx, rx, [b]]).astype(complex)
    h = 1e-30
    cols = []
    for i in range(7):
        s = s0.copy()
        s[i] += 1j * h
        cols.append(np.imag(channel_parameters(scenario, s[0:3], s[3:6], s[6])) / h)
    return np.stack(cols, axis=1)


def naive_state_fim(
    scenario: Scenario, tx: NDArray, rx: NDArray, full_profiles: list[NDArray], delta2: NDArray
) -> NDArray:
    """The full state FIM on s = [p_T, p_R, B, α0, β0, α1, β1, …] = J_S I(η) J_S^T."""
    b = scenario.system.clock_offset_m
    eta = np.real(channel_parameters(scenario, tx, rx, b))
    i_eta = naive_fim_eta(scenario, eta, full_profiles, delta2)
    geo_rows = numeric_jacobian(scenario, tx, rx, b)
    # state = [s_N (7), then (α, β) of each path]; gains map to themselves
    n_paths = len(scenario.ris) + (1 if scenario.system.los else 0)
    jac = np.zeros((len(eta), 7 + 2 * n_paths))
    jac[:, :7] = geo_rows
    pos = 0
    for p in range(n_paths):
        size = 3 if (scenario.system.los and p == 0) else 5
        jac[pos + size - 2, 7 + 2 * p] = 1.0
        jac[pos + size - 1, 7 + 2 * p + 1] = 1.0
        jac[pos + size - 2 : pos + size, :7] = 0.0  # the gains' geometry rows are not states
        pos += size
    return jac.T @ i_eta @ jac


def naive_bounds(state_fim: NDArray, keep: list[int]) -> tuple[float, float, float]:
    """PEB_T, PEB_R, CEB from the full state FIM (nuisances kept), known rows removed."""
    n = state_fim.shape[0]
    idx = keep + list(range(7, n))
    crb = np.linalg.inv(state_fim[np.ix_(idx, idx)])
    d = np.diag(crb)
    pos = {k: i for i, k in enumerate(idx)}
    peb_t = np.sqrt(sum(d[pos[k]] for k in (0, 1, 2) if k in pos))
    peb_r = np.sqrt(sum(d[pos[k]] for k in (3, 4, 5) if k in pos))
    ceb = np.sqrt(d[pos[6]]) if 6 in pos else float("nan")
    return float(peb_t), float(peb_r), float(ceb)
