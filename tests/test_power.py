"""Power control: the per-beam information stack, the SDP of the appendix, the γ_P search,
the must-show behaviour of Figs. 5 and 6 at small size, and the ``power`` CLI."""

from __future__ import annotations

import itertools
import json
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pytest
from conftest import small_scenario_doc
from test_crb import street_document, street_pairs
from tolerance import BOUND_ACCURACY, SDP_ACCURACY, assert_close

from ris_planner.bounds.compute import compute_bounds, first_block_profiles
from ris_planner.cli import main
from ris_planner.core.errors import RisPlannerError
from ris_planner.inversion import ldl
from ris_planner.model.power import Objective
from ris_planner.model.scenario import Scenario, load_scenario, preset_document
from ris_planner.physics.beams import codebook_block, gamma_p_powers
from ris_planner.power import run_power
from ris_planner.power.gamma import search_gamma_p
from ris_planner.power.information import BeamInformation, PathBlocks, _path_map, beam_information
from ris_planner.power.report import design_objective
from ris_planner.power.sdp import (
    mean_trace_bound,
    objective_index,
    position_traces,
    solve_power_sdp,
    whitening,
)

SOLVER_RTOL = 1e-6
"""Ordering checks SDP ≤ γ_P ≤ uniform allow the interior-point solver's relative gap
(Clarabel's default tolerances are 1e-8; the whitened problem is O(1))."""

RECOMPUTE_RTOL = 1e-4
"""The required agreement between the SDP objective and PEB² recomputed at its powers (the
SDP's optimum is PEB² at the powers it returns; docs/concepts/numerics.md, SDP_ACCURACY)."""


def paper_doc(kind: str = "directional_derivative", size: int = 10, **prior: Any) -> dict:
    doc = preset_document("paper-table1")
    doc["ris"] = [dict(r, rows=size, cols=size) for r in doc["ris"]]
    doc["codebook"] = {"kind": kind, "prior": {"sigma_m": 0.1} | prior}
    return doc


def schur(f: np.ndarray) -> np.ndarray:
    """Information on the first 7 states after eliminating the trailing gains."""
    a, c, d = f[:, :7, :7], f[:, :7, 7:], f[:, 7:, 7:]
    return np.asarray(a - c @ np.linalg.solve(d, c.transpose(0, 2, 1)))


@pytest.mark.parametrize(
    ("los", "wavefront"), [(True, "planar"), (False, "planar"), (True, "spherical")]
)
def test_stacked_beam_information_reproduces_the_core_fim(
    rng: np.random.Generator, los: bool, wavefront: str
) -> None:
    """Σ_g γ_g S_g, gains eliminated, equals compute_bounds' 7×7 FIM at γ = 1 and at random
    powers. Both sum the same per-path terms in different orders (per beam then per path vs
    Gram then Schur per path); over 400 random cases the worst difference was 4e-15 of
    max|F|, so 1e-12 leaves a margin for other BLAS builds only."""
    doc = small_scenario_doc(rng, n_ris=3, los=los)
    doc["system"] = doc["system"] | {"wavefront": wavefront}
    sc = load_scenario(doc)
    tx = rng.uniform(-3, 3, (5, 3))
    rx = rng.uniform(-3, 3, (5, 3))
    prof = first_block_profiles(sc)
    assert prof is not None
    info = beam_information(sc, tx, rx, prof)
    g = prof[0].shape[0]
    for powers in (np.ones(g), rng.uniform(0.1, 2.0, g)):
        ref = compute_bounds(sc, tx, rx, profiles=prof, beam_powers=powers).fim
        got = schur(info.fim(powers))
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def check_orderings(doc: dict[str, Any], objective: str = "rx") -> dict[str, Any]:
    out = run_power(doc, objective=objective).to_json()  # type: ignore[arg-type]
    sdp, uni = out["sdp"], out["uniform"]["objective"]
    assert sdp["status"] == "optimal"
    # the solver's value equals PEB² recomputed by compute_bounds at its powers
    assert sdp["objective"] == pytest.approx(sdp["solver_objective"], rel=RECOMPUTE_RTOL)
    best = out["gamma_p"]["objective"] if out["gamma_p"]["objective"] is not None else uni
    assert sdp["objective"] <= best * (1 + SOLVER_RTOL)
    assert best <= uni * (1 + 1e-12)
    powers = np.array(sdp["powers"])
    assert np.all(powers >= 0) and powers.sum() == pytest.approx(powers.size, rel=1e-12)
    return out


def test_sdp_gamma_uniform_ordering_dir_der() -> None:
    out = check_orderings(paper_doc(samples=8, seed=1))
    assert out["gamma_p"]["value"] > 0 and out["positions"] == 8
    # γ_P = 1 is uniform power: the search's answer is strictly better here
    assert out["gamma_p"]["objective"] < out["uniform"]["objective"]


def test_sdp_ordering_random_codebook_sum_objective() -> None:
    """Random codebook, G = 48 (G̃ = 16), the document's three pairs as design positions."""
    doc = preset_document("paper-table1") | {
        "tx": [[-2, -4, 0], [0, -3, 0.5], [-1, 2, 0]],
        "rx": [[2, 3, 0], [1, 2, 0], [2, -3, 0.3]],
    }
    doc["system"] = {"transmissions": 48}
    out = check_orderings(doc, objective="sum")
    assert out["gamma_p"]["value"] is None
    out = check_orderings(doc, objective="tx")


def test_sdp_recomputed_objective_from_powers_directly() -> None:
    """Independent of run_power: the SDP optimum equals the mean PEB_R² that compute_bounds
    gives at the returned powers (1e-4), and SCS finds the same optimum within 1e-3 (a
    first-order method with cvxpy's default eps ≈ 1e-4–1e-5; measured 3e-6 here)."""
    sc = load_scenario(paper_doc(kind="directional", samples=16, seed=2, sigma_m=0.3))
    block = codebook_block(sc)
    info = beam_information(sc, block.tx, block.rx, block.profiles)
    res = solve_power_sdp(info)
    assert res.status == "optimal" and res.objective is not None and res.powers is not None
    peb = compute_bounds(sc, block.tx, block.rx, profiles=block.profiles, beam_powers=res.powers)
    assert np.mean(peb.peb_rx**2) == pytest.approx(res.objective, rel=RECOMPUTE_RTOL)
    scs = solve_power_sdp(info, solver="SCS")
    assert scs.status in ("optimal", "inaccurate") and scs.objective is not None
    assert scs.objective == pytest.approx(res.objective, rel=1e-3)


@pytest.mark.parametrize(
    ("kind", "objective", "seed"),
    [
        ("directional", "rx", 2),
        ("directional_derivative", "sum", 3),
        ("directional_derivative", "tx", 4),
    ],
)
def test_direct_cone_program_is_the_cvxpy_programs_optimum(
    kind: str, objective: Objective, seed: int
) -> None:
    """Clarabel's cone program written directly (the default) against the same SDP stated in
    cvxpy (an independent construction of the program): the same status, optimum and – at
    the powers each returns – the same mean PEB² by the bounds' route, within the solver's
    tolerance; the solver's own time is reported by both."""
    sc = load_scenario(paper_doc(kind=kind, samples=12, seed=seed, sigma_m=0.3))
    block = codebook_block(sc)
    info = beam_information(sc, block.tx, block.rx, block.profiles)
    direct = solve_power_sdp(info, objective)
    stated = solve_power_sdp(info, objective, modeller="cvxpy")
    assert direct.status == stated.status == "optimal", (direct, stated)
    assert direct.objective is not None and stated.objective is not None
    assert direct.powers is not None and stated.powers is not None
    assert direct.objective == pytest.approx(stated.objective, rel=SOLVER_RTOL)
    index = objective_index(info, objective)
    assert mean_trace_bound(info, direct.powers, index) == pytest.approx(
        mean_trace_bound(info, stated.powers, index), rel=SOLVER_RTOL
    )
    assert direct.powers.sum() == pytest.approx(block.beam_types.size, rel=1e-12)
    assert direct.solver_time_s is not None and stated.solver_time_s is not None


def test_solver_trouble_is_data_not_an_exception() -> None:
    """One RIS, no LOS: 3 channel parameters for 7 states, singular at every power: the LMI
    is infeasible, reported as a status with no powers; the JSON says null with a reason."""
    doc = paper_doc(samples=4)
    doc["ris"] = doc["ris"][:1]
    doc["system"] = {"los": False}
    out = run_power(doc).to_json()
    assert out["sdp"]["status"] in ("infeasible", "failed")
    assert out["sdp"]["powers"] is None and out["sdp"]["objective"] is None
    assert out["uniform"]["objective"] is None and "blind spot" in out["uniform"]["reason"]
    json.dumps(out, allow_nan=False)


def test_bad_power_inputs() -> None:
    sc = load_scenario(paper_doc(samples=4))
    block = codebook_block(sc)
    info = beam_information(sc, block.tx, block.rx, block.profiles)
    for total in (0.0, -3.0, float("nan")):
        with pytest.raises(RisPlannerError, match="total power"):
            solve_power_sdp(info, total_power=total)
    with pytest.raises(RisPlannerError, match="objective 'tx'"):
        run_power(paper_doc(samples=4) | {"known": ["tx"]}, objective="tx")
    with pytest.raises(RisPlannerError, match="expected_random"):
        run_power(preset_document("paper-table1") | {"codebook": {"kind": "expected_random"}})
    with pytest.raises(RisPlannerError, match="gamma_p"):
        gamma_p_powers(block.beam_types, -1.0)


def mean_peb_rx(doc: dict[str, Any], seeds: range, gamma: str | float | None) -> float:
    """Mean PEB_R at the true (Table I) positions over prior draws; ``"opt"`` uses the γ_P
    optimised over each draw's samples (eq. opt_formulation_3)."""
    vals = []
    for seed in seeds:
        d = json.loads(json.dumps(doc))
        d["codebook"]["prior"]["seed"] = seed
        sc = load_scenario(d)
        powers = None
        if gamma == "opt":
            result = run_power(sc)
            assert result.gamma_p is not None
            powers = gamma_p_powers(codebook_block(sc).beam_types, result.gamma_p.value)
        elif gamma is not None:
            powers = gamma_p_powers(codebook_block(sc).beam_types, float(gamma))
        vals.append(compute_bounds(sc, beam_powers=powers).peb_rx[0])
    return float(np.mean(vals))


def test_fig5_small_prior_error() -> None:
    """Fig. 5 at σ = 0.01 m (paper: random 0.155, DIR 0.918, DIR+DER optimal 0.0257 m):
    DIR+DER with optimal γ_P beats random by ≥ 4×; DIR alone degrades as σ shrinks (paper:
    0.039 m at σ = 0.32 m vs 0.918 m at 0.01 m) and is worse than random at σ = 0.01."""
    seeds = range(3)
    random = compute_bounds(load_scenario("paper-table1")).peb_rx[0]
    der_opt = mean_peb_rx(paper_doc(sigma_m=0.01, samples=8), seeds, "opt")
    assert random / der_opt >= 4.0
    dir_small = mean_peb_rx(paper_doc("directional", sigma_m=0.01, samples=24), seeds, None)
    dir_mid = mean_peb_rx(paper_doc("directional", sigma_m=0.3, samples=24), seeds, None)
    assert dir_small > 5 * dir_mid and dir_small > random


def test_fig6_optimal_gamma_moves_with_ris_size() -> None:
    """Fig. 6 at σ = 0.1 m: the optimal γ_P (eq. opt_formulation_3 over the prior samples)
    shrinks from 5×5 to 20×20 RISs (paper: 1.78 → 1.0 on its grid; here ≈1.7 → ≈1.1), and
    the PEB_R curve over γ_P is U-shaped (both ends worse than the optimum)."""
    best = {}
    for size in (5, 20):
        doc = paper_doc(size=size, samples=21)
        values = []
        for seed in range(3):
            doc["codebook"]["prior"]["seed"] = seed
            sc = load_scenario(doc)
            block = codebook_block(sc)
            evaluate = design_objective(sc, block.tx, block.rx, block.profiles, "rx")
            values.append(search_gamma_p(evaluate, block.beam_types).value)
        best[size] = float(np.median(values))
        grid = 10.0 ** np.array([-2.0, np.log10(best[size]), 2.0])
        curve = [mean_peb_rx(doc, range(2), g) for g in grid]
        assert curve[0] > 1.2 * curve[1] and curve[2] > 1.1 * curve[1]
    assert best[20] < 0.8 * best[5]


def test_power_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "doc.json"
    f.write_text(json.dumps(paper_doc(samples=4)))
    assert main(["power", str(f)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out["uniform"]) >= {"objective"}
    assert set(out["gamma_p"]) >= {"value", "objective"}
    assert set(out["sdp"]) >= {"objective", "status", "solve_time_s", "powers", "solver"}
    f.write_text(json.dumps(paper_doc(sigma_m=-1)))
    assert main(["power", str(f)]) == 2
    assert "sigma_m" in capsys.readouterr().err


def test_known_height_restricts_the_objective_to_xy() -> None:
    """With heights known the SDP minimises PEB_R² over x, y only, and its value equals
    compute_bounds' (which drops z of both UEs) at the returned powers."""
    doc = paper_doc(samples=6, seed=4) | {"known": ["height"]}
    sc = load_scenario(doc)
    block = codebook_block(sc)
    info = beam_information(sc, block.tx, block.rx, block.profiles)
    assert info.stack.shape[-1] == 5 + 6 and info.rx_index.size == 2
    out = check_orderings(doc)
    powers = np.array(out["sdp"]["powers"])
    ref = compute_bounds(sc, block.tx, block.rx, profiles=block.profiles, beam_powers=powers)
    assert np.mean(ref.peb_rx**2) == pytest.approx(out["sdp"]["objective"], rel=1e-12)


@pytest.mark.parametrize("modeller", ["direct", "cvxpy"])
def test_solver_exception_becomes_a_failed_status(
    monkeypatch: pytest.MonkeyPatch, modeller: Literal["direct", "cvxpy"]
) -> None:
    import clarabel
    import cvxpy as cp

    def broken(*args: Any, **kwargs: Any) -> None:
        raise (cp.SolverError if modeller == "cvxpy" else RuntimeError)("solver crashed")

    if modeller == "cvxpy":
        monkeypatch.setattr(cp.Problem, "solve", broken)
    else:
        monkeypatch.setattr(clarabel, "DefaultSolver", broken)
    sc = load_scenario(paper_doc(samples=2))
    block = codebook_block(sc)
    info = beam_information(sc, block.tx, block.rx, block.profiles)
    res = solve_power_sdp(info, modeller=modeller)
    assert res.status == "failed" and res.powers is None and "crashed" in (res.message or "")


def test_progress_is_reported_in_order() -> None:
    seen: list[float] = []
    run_power(paper_doc(samples=2), progress=lambda f, m: seen.append(f))
    assert seen[0] == 0.0 and seen[-1] == 1.0
    assert all(0 <= a <= b <= 1 for a, b in itertools.pairwise(seen))


def test_gamma_search_matches_a_dense_grid() -> None:
    """Brute force: 601 γ_P values (1/100 decade) over [1e-3, 1e3]; the bounded search's
    objective is no worse than the grid's best (up to the grid's own resolution it can only
    be better) and its γ_P lies within one grid step of the grid's argmin."""
    sc = load_scenario(paper_doc(samples=10, seed=5, sigma_m=0.05))
    block = codebook_block(sc)
    info = beam_information(sc, block.tx, block.rx, block.profiles)

    def objective(powers: np.ndarray) -> float:
        return mean_trace_bound(info, powers, info.rx_index)

    found = search_gamma_p(objective, block.beam_types)
    grid = 10 ** np.linspace(-3, 3, 601)
    values = np.array([objective(gamma_p_powers(block.beam_types, g)) for g in grid])
    assert found.objective <= values.min() * (1 + 1e-9)
    assert abs(np.log10(found.value) - np.log10(grid[np.argmin(values)])) <= 0.01 + 1e-9


def test_bounds_cli_with_a_directional_codebook(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    f = tmp_path / "doc.json"
    doc = paper_doc()
    doc["codebook"]["gamma_p"] = 2.0
    f.write_text(json.dumps(doc))
    assert main(["bounds", str(f)]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["peb_rx_m"] == compute_bounds(load_scenario(doc)).peb_rx[0]


def test_degenerate_design_position_is_a_failed_status() -> None:
    """A design pair with TX = RX (LOS gain λ/(4π·0)) gives non-finite information: the SDP
    reports ``failed`` with the reason instead of raising; the bounds say the pair is blind."""
    doc = preset_document("paper-table1") | {
        "tx": [[-2, -4, 0], [1, 1, 0]],
        "rx": [[2, 3, 0], [1, 1, 0.5]],
    }
    doc["system"] = {"transmissions": 24}
    sc = load_scenario(doc)
    prof = first_block_profiles(sc)
    assert prof is not None
    with np.errstate(divide="ignore", invalid="ignore"):
        info = beam_information(
            sc, np.array([[-2, -4, 0], [1, 1, 0.0]]), np.array([[2, 3, 0], [1, 1, 0.0]]), prof
        )
    res = solve_power_sdp(info)
    assert res.status == "failed" and "non-finite" in (res.message or "")


# ---- one inversion route: the power module's CRBs are compute_bounds' (numerics.md) ----


def street_power(known: list[str]) -> Scenario:
    """tests/test_crb.py's street (two 20 × 20 RISs on one facade, TX 30–100 m down the
    street, RX at the origin: scaled cond(F) 1e11–1e15) with a random codebook, G = 48."""
    doc = street_document(known)
    doc["system"] = {"tx_power_dbm": 30, "noise_figure_db": 10, "transmissions": 48}
    doc["codebook"] = {"kind": "random", "seed": 3}
    return load_scenario(doc)


@pytest.mark.parametrize("known", [[], ["clock"]])
def test_ill_conditioned_design_positions_equal_compute_bounds(known: list[str]) -> None:
    """The street pairs as design positions. Inverting the full squared FIM (the former route)
    declares 6 of 7 positions singular without a known clock although compute_bounds gives a
    finite PEB_R for each; the power module's CRB traces (uniform and random powers), the γ_P
    search's objective and the SDP's value re-evaluated at its powers now equal
    compute_bounds' to the bounds' accuracy (observed ≤ 3e-11), and the SDP is optimal with
    its own objective within the solver's accuracy of the re-evaluated one."""

    sc = street_power(known)
    tx, rx = street_pairs()
    prof = first_block_profiles(sc)
    assert prof is not None
    info = beam_information(sc, tx, rx, prof)
    g = prof[0].shape[0]
    if not known:  # the hard regime: the squared full-state FIM is singular
        _, singular = ldl.inverse_diagonal_from(
            ldl.pack(info.fim(np.ones(g))), info.stack.shape[-1]
        )
        assert singular.sum() >= 5
    rng = np.random.default_rng(7)
    for powers in (np.ones(g), rng.uniform(0.2, 2.0, g)):
        ref = compute_bounds(sc, tx, rx, profiles=prof, beam_powers=powers).peb_rx
        assert np.all(np.isfinite(ref))
        assert_close(position_traces(info, powers, info.rx_index), ref**2, accuracy=BOUND_ACCURACY)
    evaluate = design_objective(sc, tx, rx, prof, "rx")
    types = np.arange(g) % 2  # any two beam families: the search's objective is what matters
    found = search_gamma_p(lambda p: mean_trace_bound(info, p, info.rx_index), types)
    assert np.isfinite(found.objective)
    assert_close(found.objective, evaluate(found.powers), accuracy=BOUND_ACCURACY)
    res = solve_power_sdp(info)
    assert res.status == "optimal" and res.powers is not None and res.objective is not None
    own = mean_trace_bound(info, res.powers, info.rx_index)
    assert res.bound == own  # the result's re-evaluation: the same function, the same process
    assert_close(own, evaluate(res.powers), accuracy=BOUND_ACCURACY)
    assert_close(res.objective, own, accuracy=SDP_ACCURACY)
    assert own <= mean_trace_bound(info, np.ones(g), info.rx_index) * (1 + SOLVER_RTOL)


@pytest.mark.parametrize(
    ("los", "wavefront", "known", "objective"),
    [
        (True, "planar", [], "rx"),
        (False, "planar", [], "sum"),
        (True, "planar", ["clock", "height"], "tx"),
        (True, "spherical", [], "rx"),
        (False, "planar", ["tx"], "rx"),
    ],
)
def test_position_traces_equal_compute_bounds_on_random_scenarios(
    rng: np.random.Generator, los: bool, wavefront: str, known: list[str], objective: str
) -> None:
    """Random small scenarios (3 RISs, 6 positions, random powers): the power module's
    per-position CRB traces equal compute_bounds' PEB² (same profiles, powers, known parts) to
    the bounds' accuracy, ``inf`` at the same places."""

    doc = small_scenario_doc(rng, n_ris=3, los=los)
    doc["system"] = doc["system"] | {"wavefront": wavefront}
    doc["known"] = known
    sc = load_scenario(doc)
    tx, rx = rng.uniform(-3, 3, (6, 3)), rng.uniform(-3, 3, (6, 3))
    prof = first_block_profiles(sc)
    assert prof is not None
    info = beam_information(sc, tx, rx, prof)
    powers = rng.uniform(0.1, 2.0, prof[0].shape[0])
    res = compute_bounds(sc, tx, rx, profiles=prof, beam_powers=powers)
    parts = {"rx": [res.peb_rx], "tx": [res.peb_tx], "sum": [res.peb_tx, res.peb_rx]}[objective]
    want = sum(np.square(p) for p in parts if p is not None)
    got = position_traces(info, powers, objective_index(info, objective))  # type: ignore[arg-type]
    assert_close(got, want, accuracy=BOUND_ACCURACY)
    # the SDP's whitening factor is a square root of the stacked FIM (entries on the scale
    # √(F_ii F_jj); worst 3.0e-15 over 120 random cases, eigh of the scaled path blocks)
    a = info.factor(powers)
    f = info.fim(powers)
    d = np.sqrt(np.diagonal(f, axis1=1, axis2=2))
    err = np.abs(a.transpose(0, 2, 1) @ a - f) / (d[:, :, None] * d[:, None, :])
    assert np.max(err) <= 1e-12


def synthetic_clockless_information(rng: np.random.Generator, n_pos: int = 4) -> BeamInformation:
    """A BeamInformation whose clock receives no information at all (one path with 7 channel
    parameters = the states, Jacobian I with a zero clock column; two beams with random PSD
    blocks): F(γ) is singular at every power (null direction e_B) while p_T and p_R are
    determined."""
    jac = np.broadcast_to(np.eye(7), (n_pos, 7, 7)).copy()
    jac[:, 6, 6] = 0.0
    t = _path_map(jac, 7, 9)
    roots = rng.normal(size=(n_pos, 2, 9, 9))
    blocks = roots @ roots.transpose(0, 1, 3, 2) / 9
    stack = np.einsum("pai,pgab,pbj->pgij", t, blocks, t)
    stack = 0.5 * (stack + stack.transpose(0, 1, 3, 2))
    path = PathBlocks(blocks, t, "ris1", jac, np.ones(n_pos, dtype=bool))
    return BeamInformation(stack, np.arange(2), np.arange(3), np.arange(3, 6), (path,), (), None)


def test_sdp_with_singular_information_whitens_the_range(rng: np.random.Generator) -> None:
    """F(uniform) singular (the clock has no information) but the objective's p_R is
    identifiable: the SDP whitens the range of F(uniform) (8 kept rows of 9), is optimal,
    and its value equals the independent route (the 6 × 6 information on [p_T, p_R] after
    eliminating the gains, inverted by numpy) at its powers; a brute-force scan of the one
    free power ratio finds no better allocation."""

    info = synthetic_clockless_information(rng)
    _, kept = whitening(info, np.ones(2))
    assert np.all(kept.sum(axis=1) == 8)

    def exact(powers: np.ndarray) -> float:
        f = info.fim(powers)
        s = np.r_[0:6, 7:9]  # drop the uninformed clock, then eliminate the gains
        f = f[:, s][:, :, s]
        return float(np.mean(np.trace(np.linalg.inv(schur6(f))[:, 3:6, 3:6], axis1=1, axis2=2)))

    res = solve_power_sdp(info)
    assert res.status == "optimal" and res.powers is not None and res.objective is not None
    assert_close(
        mean_trace_bound(info, res.powers, info.rx_index),
        exact(res.powers),
        accuracy=BOUND_ACCURACY,
    )
    assert_close(res.objective, exact(res.powers), accuracy=SDP_ACCURACY)
    scan = min(exact(np.array([a, 2.0 - a])) for a in np.linspace(0.0, 2.0, 401)[1:-1])
    assert res.objective <= scan * (1 + SDP_ACCURACY)


def schur6(f: np.ndarray) -> np.ndarray:
    a, c, d = f[:, :6, :6], f[:, :6, 6:], f[:, 6:, 6:]
    return np.asarray(a - c @ np.linalg.solve(d, c.transpose(0, 2, 1)))


def test_sdp_reports_an_unidentifiable_objective_as_infeasible(rng: np.random.Generator) -> None:
    """The objective's state without information at one position (the clock column of the
    synthetic path moved to p_R's x): infeasible at every power, said at once with a reason."""
    info = synthetic_clockless_information(rng)
    info.paths[0].jacobian[:, 3, 3] = 0.0
    info.paths[0].maps[:, 3, 3] = 0.0
    res = solve_power_sdp(info)
    assert res.status == "infeasible" and res.powers is None
    assert "not identifiable" in (res.message or "")
