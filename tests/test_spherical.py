"""Spherical wavefront (docs/concepts/wavefront.md) against a brute-force reference: exact
per-element distances, the full K × G superposed signal of all paths, derivatives by
complex-step differentiation (and fourth-order central differences), the state FIM with every
gain as a nuisance."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from test_planning import plan_doc, reference_metric, setup

from ris_planner.bounds.compute import (
    REASON_CHANNEL_SPHERICAL,
    compute_bounds,
    first_block_profiles,
)
from ris_planner.core.units import SPEED_OF_LIGHT
from ris_planner.model.scenario import Scenario, load_scenario, preset_document
from ris_planner.physics import codebooks, spherical

BRUTE_RTOL = 1e-7
"""Brute force vs engine: the complex-step derivatives are exact to rounding (~1e-14), so the
7×7 FIMs (entries relative to sqrt(F_ii F_jj)) and the bounds (scaled cond ≤ 1e5 here) agree
far inside 1e-7; the phase-gradient check uses fourth-order central differences with
h = 1e-6 m ((k h)⁴/30 ≈ 4e-15 truncation, ε·kd/(kh) ≈ 1e-9 rounding)."""

COMPLEX_STEP = 1e-30
FD_STEP = 1e-6


def small_doc(n_ris: int, los: bool, known: list[str] | None = None) -> dict[str, Any]:
    """30 GHz, K = 8, G = 24, 4 × 4 RISs with 5 cm spacing (Fraunhofer distance ≈ 9 m) about
    2 m from the UEs: deep in the near field."""
    ris = [
        {"position": [-2.0, 0.3, 1.5], "orientation": [0.1, 0.2, 0.0]},
        {"position": [2.2, -0.4, 1.8], "orientation": [np.pi - 0.2, 0.3, 0.1]},
    ][:n_ris]
    for r in ris:
        r |= {"rows": 4, "cols": 4, "spacing_m": 0.05}
    return {
        "system": {
            "subcarriers": 8,
            "transmissions": 24,
            "los": los,
            "wavefront": "spherical",
            "noise_figure_db": 0,
        },
        "ris": ris,
        "tx": [-0.7, -1.1, 0.2],
        "rx": [0.9, 1.3, 0.4],
        "codebook": {"kind": "random", "seed": 3},
        "known": known or [],
    }


def brute_force_factor(sc: Scenario, full: list[np.ndarray]) -> np.ndarray:
    """A square root [2KG, 7] of the state information: the whitened real derivative matrix
    [Re ∂μ; Im ∂μ]·sqrt(2/σ²) with the gains' columns projected out (the Schur complement in
    square-root form, so the reference bounds do not square the condition number)."""
    system = sc.system
    lam = system.wavelength
    k = 2 * np.pi / lam
    omega = 2 * np.pi * np.arange(1, system.subcarriers + 1) * system.subcarrier_spacing
    tx0, rx0 = np.asarray(sc.tx, float), np.asarray(sc.rx, float)
    elems = [spherical.element_positions_global(r, lam) for r in sc.ris]
    centres = [np.asarray(r.position, float) for r in sc.ris]
    n_paths = len(sc.ris) + (1 if system.los else 0)
    gains0 = []
    if system.los:
        gains0.append(lam / (4 * np.pi * np.linalg.norm(tx0 - rx0)))
    for c in centres:
        gains0.append(lam**2 / (16 * np.pi**2 * np.linalg.norm(tx0 - c) * np.linalg.norm(rx0 - c)))

    def norm(v: np.ndarray) -> np.ndarray:
        return np.sqrt(np.sum(v * v, axis=-1))  # analytic: complex steps pass through

    def mu_parts(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(Re μ, Im μ) [K, G] of the noiseless received signal (unit pilot, δ_g = 1), written
        with real-analytic functions so a complex step differentiates each part exactly."""
        p_t, p_r, b = s[0:3], s[3:6], s[6]
        shape = (len(omega), system.transmissions)
        re, im = np.zeros(shape, dtype=complex), np.zeros(shape, dtype=complex)
        path = 0
        if system.los:
            theta = -s[8] - omega * (norm(p_t - p_r) + b) / SPEED_OF_LIGHT  # [K]
            re += (s[7] * np.cos(theta))[:, None]
            im += (s[7] * np.sin(theta))[:, None]
            path = 1
        for ell, (r, c) in enumerate(zip(elems, centres, strict=True)):
            alpha, beta = s[7 + 2 * (path + ell)], s[8 + 2 * (path + ell)]
            d_t, d_r = norm(p_t - c), norm(p_r - c)
            phi = -k * ((norm(p_t[None] - r) - d_t) + (norm(p_r[None] - r) - d_r))  # [N]
            tau = (d_t + d_r + b) / SPEED_OF_LIGHT
            # [K, G, N] total phase of element n in transmission g on subcarrier k
            theta = (
                np.angle(full[ell])[None] + phi[None, None] - beta - (omega * tau)[:, None, None]
            )
            amp = np.abs(full[ell])[None]
            re += alpha * np.sum(amp * np.cos(theta), axis=2)
            im += alpha * np.sum(amp * np.sin(theta), axis=2)
        return re, im

    s0 = np.concatenate([tx0, rx0, [system.clock_offset_m]])
    s0 = np.concatenate([s0, *[[g, 0.4] for g in gains0]])
    steps = np.full(s0.size, COMPLEX_STEP)
    steps[7::2] = COMPLEX_STEP * np.array(gains0)
    derivs = []
    for i in range(s0.size):
        x = s0.astype(complex)
        x[i] += 1j * steps[i]
        re, im = mu_parts(x)
        derivs.append(((re.imag + 1j * im.imag) / steps[i]).ravel() * np.sqrt(system.tx_power_w))
    dm = np.array(derivs).T  # [K·G, n]
    assert dm.shape[1] == 7 + 2 * n_paths
    a = np.sqrt(2 / system.noise_variance_w) * np.concatenate([dm.real, dm.imag])
    q, _ = np.linalg.qr(a[:, 7:])
    return np.asarray(a[:, :7] - q @ (q.T @ a[:, :7]))


def full_profiles(sc: Scenario) -> list[np.ndarray]:
    prof = first_block_profiles(sc)
    assert prof is not None
    b = codebooks.orthogonal_code_matrix(sc.system.transmissions, len(sc.ris))
    return [codebooks.expand_profiles(prof[i], b[:, i + 1]) for i in range(len(sc.ris))]


def bounds_of(a: np.ndarray, keep: list[int]) -> tuple[float, float]:
    """(PEB_T, PEB_R) from a square-root factor [r, 7] by the SVD of its scaled columns."""
    ak = a[:, keep]
    col = np.linalg.norm(ak, axis=0)
    _, sv, vt = np.linalg.svd(ak / col, full_matrices=False)
    diag = (vt**2 / sv[:, None] ** 2).sum(axis=0) / col**2
    pos = {s: i for i, s in enumerate(keep)}
    peb_r = float(np.sqrt(sum(diag[pos[s]] for s in (3, 4, 5))))
    peb_t = float(np.sqrt(sum(diag[pos[s]] for s in (0, 1, 2) if s in pos)))
    return peb_t, peb_r


@pytest.mark.parametrize(("n_ris", "los"), [(1, True), (2, True), (2, False)])
def test_spherical_equals_brute_force(n_ris: int, los: bool) -> None:
    known = [] if los else ["clock"]
    sc = load_scenario(small_doc(n_ris, los, known))
    res = compute_bounds(sc)
    root = brute_force_factor(sc, full_profiles(sc))
    ref = root.T @ root
    scale = np.sqrt(np.outer(np.diag(ref), np.diag(ref)))
    np.testing.assert_allclose(res.fim[0] / scale, ref / scale, rtol=0, atol=BRUTE_RTOL)
    keep = [0, 1, 2, 3, 4, 5] + ([6] if los else [])
    peb_t, peb_r = bounds_of(root, keep)
    assert res.reason[0] is None
    assert res.peb_rx[0] == pytest.approx(peb_r, rel=BRUTE_RTOL)
    assert res.peb_tx is not None and res.peb_tx[0] == pytest.approx(peb_t, rel=BRUTE_RTOL)
    # the test can fail: the planar model differs here by far more than the tolerance
    doc = small_doc(n_ris, los, known)
    doc["system"]["wavefront"] = "planar"
    planar = compute_bounds(load_scenario(doc))
    if n_ris == 2:
        assert abs(planar.peb_rx[0] / res.peb_rx[0] - 1) > 1e-3
    js = res.to_json(batch=False)
    assert js["channel_reason"] == REASON_CHANNEL_SPHERICAL
    assert all(v is None for ch in js["channel"] for k, v in ch.items() if k != "path")


def test_expected_gram_equals_finite_difference_steering_gram() -> None:
    """E[Q]/G = Vᴴ V with V's derivative columns from finite differences of the exact a."""
    sc = load_scenario(small_doc(1, True))
    ris, lam = sc.ris[0], sc.system.wavelength
    tx, rx = np.array([sc.tx]), np.array([sc.rx])
    got = spherical.expected_gram(tx, rx, ris, lam)[0]

    def a_of(p_t: np.ndarray, p_r: np.ndarray) -> np.ndarray:
        phi, _ = spherical.phases(p_t[None], p_r[None], ris, lam)
        return np.exp(1j * phi[0])

    cols = []
    for i in range(6):
        e = np.zeros(6)
        e[i] = FD_STEP
        p = np.concatenate([tx[0], rx[0]])

        def at(x: np.ndarray) -> np.ndarray:
            return a_of(x[:3], x[3:])

        cols.append(
            (-at(p + 2 * e) + 8 * at(p + e) - 8 * at(p - e) + at(p - 2 * e)) / (12 * FD_STEP)
        )
    v = np.stack([*cols, a_of(tx[0], rx[0])], axis=1)
    ref = np.conj(v).T @ v
    np.testing.assert_allclose(got, ref, rtol=BRUTE_RTOL, atol=BRUTE_RTOL * np.abs(ref).max())


def test_single_near_field_ris_without_los_known_clock_is_finite() -> None:
    """One RIS, no LOS, clock known: 3 planar parameters for 6 states (underdetermined), but
    the spherical wavefront resolves range: finite and equal to the brute force."""
    doc = small_doc(1, False, ["clock"])
    sc = load_scenario(doc)
    res = compute_bounds(sc)
    assert res.reason[0] is None and np.isfinite(res.peb_rx[0])
    root = brute_force_factor(sc, full_profiles(sc))
    assert res.peb_rx[0] == pytest.approx(bounds_of(root, [0, 1, 2, 3, 4, 5])[1], rel=BRUTE_RTOL)
    doc["system"]["wavefront"] = "planar"
    planar = compute_bounds(load_scenario(doc))
    assert np.isinf(planar.peb_rx[0]) and planar.reason[0].startswith("underdetermined")


@pytest.mark.parametrize(("codebook", "order"), [("expected_random", 2), ("random", 1)])
def test_far_away_spherical_tends_to_planar_at_the_stated_rate(codebook: str, order: int) -> None:
    """Scaling the Table I geometry by s, |PEB_sph/PEB_planar − 1| falls as s^−order: the
    planar model's phase error k·D²/(8d) enters random beams' responses linearly (order 1);
    the expected FIM depends only on the gradient Gram, whose error is O((D/d)²) (order 2)."""
    diffs = []
    for s in (4, 8, 16):
        doc = preset_document("paper-table1")
        doc["codebook"] = {"kind": codebook} | ({"seed": 2} if codebook == "random" else {})
        doc["ris"] = [r | {"position": [x * s for x in r["position"]]} for r in doc["ris"]]
        doc["tx"], doc["rx"] = [x * s for x in doc["tx"]], [x * s for x in doc["rx"]]
        planar = compute_bounds(load_scenario(doc))
        doc["system"] = doc["system"] | {"wavefront": "spherical"}
        sph = compute_bounds(load_scenario(doc))
        diffs.append(abs(sph.peb_rx[0] / planar.peb_rx[0] - 1))
    rates = [diffs[i] / diffs[i + 1] for i in range(2)]
    assert all(abs(r / 2**order - 1) < 0.1 for r in rates), rates
    assert diffs[-1] < 1e-4


def test_plan_scorer_equals_compute_bounds_spherical() -> None:
    doc = plan_doc(system={"wavefront": "spherical"}, pairs={"sample": 60, "seed": 2})
    d, sites, pairs, scorer = setup(doc)
    for lay in [(0, 1), (2, 4, 5)]:
        got = scorer.metric(np.array([lay]))[0]
        ref = reference_metric(d, sites, pairs, lay)
        np.testing.assert_array_equal(got, ref)  # bit for bit
        np.testing.assert_array_equal(got, scorer.metric_reference(np.array([lay]))[0])
    # one RIS with LOS: planar-underdetermined, finite with the spherical model
    assert np.all(np.isfinite(scorer.metric(np.array([(3,)]))[0]))


@pytest.mark.parametrize("kind", ["explicit", "directional_derivative"])
def test_spherical_other_codebooks_equal_brute_force(kind: str) -> None:
    """Explicit phases and DIR+DER beams (planar designs) through the exact response."""
    doc = small_doc(2, True)
    if kind == "explicit":
        phases = np.random.default_rng(8).uniform(0, 2 * np.pi, (2, 8, 16))
        doc["codebook"] = {"kind": "explicit", "phases": phases.tolist()}
    else:
        doc["codebook"] = {"kind": kind, "prior": {"sigma_m": 0.2, "samples": 2, "seed": 1}}
    sc = load_scenario(doc)
    res = compute_bounds(sc)
    root = brute_force_factor(sc, full_profiles(sc))
    peb_t, peb_r = bounds_of(root, list(range(7)))
    assert res.peb_rx[0] == pytest.approx(peb_r, rel=BRUTE_RTOL)
    assert res.peb_tx is not None and res.peb_tx[0] == pytest.approx(peb_t, rel=BRUTE_RTOL)
