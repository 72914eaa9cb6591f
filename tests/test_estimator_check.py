"""Plan validation (ris_planner.planning.outputs.estimator_check): the two-stage estimator on
a plan's recommended layout. Table I as a plan (its two RISs the only candidates, its TX and RX
the only map points): reproducible from its seeds, the exactly-determined geometry's second
solution and the TX↔RX swap reported as ghosts, too few paths reported as such, the site's
reflections in the signal, and the coarse (ξ, ζ) grid that grows with the aperture."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from tolerance import BOUND_ACCURACY, assert_close
from waits import HANG_S

from ris_planner import load_scenario, preset_document
from ris_planner.core.errors import RisPlannerError
from ris_planner.estimation import channel_estimation
from ris_planner.estimation.channel_estimation import ChannelEstimator, angle_grid_size
from ris_planner.estimation.signal import noise_free_signal, realisation_paths, signal_setup
from ris_planner.model.simulation import Multipath
from ris_planner.planning import PlanResult, SerialExecutor, run_plan
from ris_planner.planning.outputs.estimator_check import (
    OUTLIER_FACTOR,
    SNR_THRESHOLD_DB,
    classify_draw,
    run_estimator_check,
    search_candidates,
)
from ris_planner.planning.prepare import validate_document

ROOT = Path(__file__).resolve().parent.parent
CLI = [sys.executable, "-m", "ris_planner.cli"]
REGION = {"min_m": [-3.5, -5.0, -0.4], "max_m": [-1.2, -2.8, 0.6]}
"""A prior box of TX candidates that holds Table I's TX [−2, −4, 0] off-centre."""
EXACT_GHOST_REGION = {"min_m": [-2.9, -1.8, 0.3], "max_m": [-1.9, -0.8, 1.1]}
"""Holds the second exact solution of Table I's 7 equations (docs/guides/estimation.md:
TX ≈ [−2.32, −1.25, 0.76], RX ≈ [2.42, 0.83, 0.78]), not the truth."""
AROUND_RX = {"min_m": [1.5, 2.5, -0.2], "max_m": [2.5, 3.5, 0.2]}
"""Holds Table I's RX [2, 3, 0]: a TX found there is the TX↔RX swap."""


def table1_plan(validation: dict[str, Any] | None = None, **system: Any) -> dict[str, Any]:
    """Table I (noise figure 0 dB, the paper's isotropic element) as a plan document."""
    t1 = preset_document("paper-table1")
    return {
        "system": {**t1["system"], "noise_figure_db": 0.0, **system},
        "ris": {"rows": 10, "cols": 10, "pattern_exponent": 0, "max_angle_deg": 90},
        "candidates": [
            {"position": r["position"], "orientation": r["orientation"]} for r in t1["ris"]
        ],
        "tx_map": {"points": [t1["tx"]]},
        "rx_map": {"points": [t1["rx"]]},
        "objective": {"kind": "coverage", "metric": "rx", "threshold_m": 0.1},
        "ris_count": [2],
        "validation": {"pairs": 1, "draws": 2, "search_region": REGION, **(validation or {})},
    }


@pytest.fixture(scope="module")
def table1() -> PlanResult:
    return run_plan(table1_plan(), executor=SerialExecutor())


def recheck(result: PlanResult, **validation: Any) -> dict[str, Any]:
    """The validation stage again on the same plan with other settings."""
    spec = result.document.validation
    assert spec is not None
    doc = result.document.model_copy(
        update={"validation": spec.model_copy(update=_spec_update(validation))}
    )
    return run_estimator_check(dataclasses.replace(result, document=doc))


def _spec_update(validation: dict[str, Any]) -> dict[str, Any]:
    from ris_planner.model.plan import SearchRegion

    out = dict(validation)
    if isinstance(out.get("search_region"), dict):
        out["search_region"] = SearchRegion.model_validate(out["search_region"])
    return out


def _strip(v: dict[str, Any]) -> dict[str, Any]:
    """The validation without its wall-time fields."""
    out = json.loads(json.dumps(v))
    for lay in out["layouts"]:
        lay.pop("seconds_per_estimate")
    return out


def test_validation_is_in_plan_json_and_reproducible_from_its_seeds(table1: PlanResult) -> None:
    plan = table1.to_json()
    v = plan["validation"]
    assert "validation" in plan["timing_s"]
    assert v["search_region"]["source"] == "search_region"
    lay = v["layouts"][0]
    assert lay["sites"] == [0, 1] and lay["bound_coverage"] == 1.0
    pair = lay["pairs"][0]
    # 30 dBm, high SNR: the refined estimate is near the bound, no outlier, covered
    assert pair["outliers"] == [] and pair["estimator_covered"]
    assert pair["ratio"] < OUTLIER_FACTOR
    again = recheck(table1)
    assert _strip(again) == _strip(v)  # the same seeds: the same numbers, bit for bit
    other = recheck(table1, seed=1)
    assert other["layouts"][0]["pairs"][0]["rmse_rx_m"] != pair["rmse_rx_m"]


def test_exactly_determined_second_solution_is_reported_as_a_ghost(table1: PlanResult) -> None:
    """L = 2 with LOS: 7 observations for 7 unknowns; the prior box holds the other exact
    solution of the position equations, which the estimator converges to and reports."""
    v = recheck(table1, search_region=EXACT_GHOST_REGION)
    lay = v["layouts"][0]
    pair = lay["pairs"][0]
    assert [o["cause"] for o in pair["outliers"]] == ["ghost", "ghost"]
    assert {o["ghost"] for o in pair["outliers"]} == {"other_solution"}
    # the ghost's location to the 2 decimals the docs give it, plus the noise (PEB ≈ 0.05 m)
    assert_close(pair["outliers"][0]["tx_m"], [-2.32, -1.25, 0.76], ulps=0, atol=0.1)
    assert pair["shortfall"] == "ghost" and lay["shortfall"]["by_cause"]["ghost"] == 1
    assert lay["outliers"]["ghost"] == 2 and lay["estimator_coverage"] == 0.0
    assert any("ghost 1" in line for line in v["summary"])


def test_tx_rx_swap_is_reported_as_a_ghost(table1: PlanResult) -> None:
    v = recheck(table1, search_region=AROUND_RX, draws=1)
    (out,) = v["layouts"][0]["pairs"][0]["outliers"]
    assert out["cause"] == "ghost" and out["ghost"] == "tx_rx_swap"
    lay = v["layouts"][0]
    # up to the swap the estimate is right: covered once the roles are known
    assert lay["estimator_coverage"] == 0.0 and lay["estimator_coverage_swap_resolved"] == 1.0
    assert_close(out["tx_m"], [2.0, 3.0, 0.0], ulps=0, atol=0.1)  # the RX, up to the noise


def test_too_few_paths_are_reported_not_estimated() -> None:
    """Without LOS two RISs give 6 observations for 7 unknowns: no estimate, the cause named."""
    res = run_plan(table1_plan({"draws": 1}, los=False), executor=SerialExecutor())
    assert res.validation is not None
    pair = res.validation["layouts"][0]["pairs"][0]
    assert [o["cause"] for o in pair["outliers"]] == ["not_enough_paths"]
    assert pair["error_m"] is None and not pair["estimator_covered"]


def test_outlier_classification_rules() -> None:
    """classify_draw: within the factor no outlier; the swap first; channel misfit → the SNR
    threshold below it, else multipath (or the coarse stage); an equally good fit elsewhere →
    ghost; else the coarse stage's basin."""
    weak, strong = SNR_THRESHOLD_DB - 1, SNR_THRESHOLD_DB + 1
    assert classify_draw(3.9, 1.0, False, 0.0, 0.0, 7, False, strong) is None
    assert classify_draw(5.0, 1.0, True, 0.0, 100.0, 7, True, strong) == "ghost"
    assert classify_draw(5.0, 1.0, False, 0.0, 100.0, 7, True, weak) == "threshold_snr"
    assert classify_draw(5.0, 1.0, False, 0.0, 100.0, 7, False, weak) == "threshold_snr"
    assert classify_draw(5.0, 1.0, False, 0.0, 100.0, 7, True, strong) == "multipath_bias"
    assert classify_draw(5.0, 1.0, False, 0.0, 100.0, 7, False, strong) == "coarse_failed"
    assert classify_draw(5.0, 1.0, False, 1.0, 5.0, 10, False, strong) == "ghost"
    assert classify_draw(5.0, 1.0, False, 50.0, 5.0, 10, False, strong) == "coarse_failed"


def test_site_reflections_enter_the_simulated_signal() -> None:
    """A concrete wall behind Table I's TX: with ``reflections`` its specular copies of the
    LOS and of the TX–RIS legs join the signal (multipath: biased channel estimates), so the
    same seeds give other errors than without; the bounds are the same."""
    wall = {"kind": "wall", "name": "w", "start": [-6, -6], "end": [6, -6], "height_m": 4.0}
    doc = table1_plan({"draws": 1}) | {"environment": {"obstacles": [wall]}}
    res = run_plan(doc, executor=SerialExecutor())
    assert res.validation is not None and not res.validation["reflections"]
    with_refl = recheck(res, reflections=True)
    assert with_refl["reflections"] and with_refl["multipath"]
    a, b = res.validation["layouts"][0]["pairs"][0], with_refl["layouts"][0]["pairs"][0]
    assert a["peb_rx_m"] == b["peb_rx_m"] and a["rmse_rx_m"] != b["rmse_rx_m"]


def test_search_region_defaults_to_the_tx_map_extent_and_respects_the_cap() -> None:
    doc = validate_document(table1_plan({"search_region": None, "max_candidates": 1000}))
    assert doc.validation is not None
    pts = np.array([[0.0, 0.0, 0.0], [40.0, 20.0, 0.0], [10.0, 5.0, 0.0]])
    grid, info = search_candidates(doc.validation, pts)
    assert info["source"] == "tx_map_extent" and info["candidates"] == grid.shape[0] <= 1000
    assert info["step_m"] > 0.2
    np.testing.assert_allclose(grid.min(axis=0), [0, 0, 0])
    assert np.all(grid.max(axis=0) <= [40, 20, 0])


@pytest.mark.parametrize("size", [16, 64])
def test_coarse_angles_find_the_main_lobe_of_large_apertures(
    size: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Noise-free, one RIS path: the coarse (ξ, ζ) lies within one grid step of the truth for
    a 64 × 64 aperture too (the grid has ≥ 2 points per 2/N-wide lobe), and the normaliser
    computed in batches of one beam equals the one-batch result."""
    doc = preset_document("paper-table1")
    for r in doc["ris"]:
        r["rows"] = r["cols"] = size
    sc = load_scenario(doc)
    setup = signal_setup(sc)
    paths = realisation_paths(setup, Multipath(), np.random.default_rng(0))
    y = noise_free_signal(setup, paths)
    from ris_planner.estimation.signal import separate_paths

    est = ChannelEstimator(setup)
    m = angle_grid_size(100, size, size)
    assert est.angle_sizes == (m, m) and m >= 2 * size
    ch = est.coarse(separate_paths(setup, y))
    period = setup.ris[0].period(setup.wavelength)
    for i in range(2):
        k = int(np.flatnonzero(paths.ris == i + 1)[0])
        for got, want in ((ch.xi[i], paths.xi[k]), (ch.zeta[i], paths.zeta[k])):
            assert abs(channel_estimation.wrap(got - want, period)) <= period / m
    whole = est.angle_normalisers
    monkeypatch.setattr(channel_estimation, "NORMALISER_BATCH_ELEMENTS", 1)
    batched = ChannelEstimator(setup).angle_normalisers
    for a, b in zip(whole, batched, strict=True):
        # sums of ≤ G̃ = 96 positive terms in another order: ≤ 96 rounding steps apart
        assert_close(b, a, ulps=256)


def test_cli_validate_prints_the_summary(tmp_path: Path) -> None:
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(table1_plan({"draws": 1})))
    out = subprocess.run(
        [*CLI, "plan", str(path), "--validate", "1", "--out", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        timeout=HANG_S,
        cwd=ROOT,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert "validation 2 RIS [0, 1]: estimator coverage" in out.stdout
    plan = json.loads((tmp_path / "out" / "plan.json").read_text())
    assert plan["validation"]["pairs"] == 1
    assert (tmp_path / "out" / "validation.png").stat().st_size > 0


def test_path_snr_of_the_los_is_its_closed_form() -> None:
    """The LOS path's integrated SNR ‖μ_0‖²/σ² = P α_0² K Σ_g δ_g² / σ² (|x_k| = |c_g| = 1)."""
    from ris_planner.physics import geometry
    from ris_planner.planning.outputs.estimator_check import path_snr_db

    sc = load_scenario(preset_document("paper-table1"))
    setup = signal_setup(sc)
    d0 = geometry.los_distance(sc.tx_array[:1], sc.rx_array[:1])
    alpha = float(geometry.los_gain(d0, setup.wavelength)[0])
    want = setup.tx_power_w * alpha**2 * setup.subcarriers * float(np.sum(setup.delta**2))
    got = path_snr_db(setup)
    assert set(got) == {"los", "ris1", "ris2"}
    assert_close(10 ** (got["los"] / 10), want / setup.noise_variance_w, ulps=1024)


def test_bad_validation_settings_are_refused_with_the_field() -> None:
    with pytest.raises((ValueError, RisPlannerError), match=r"validation\.multipath\.clusters"):
        validate_document(table1_plan({"multipath": {"clusters": [{"center": [0, 0]}]}}))
    with pytest.raises((ValueError, RisPlannerError), match="exceed the limit"):
        validate_document(table1_plan({"pairs": 1000, "draws": 1000}))


@pytest.fixture(scope="module")
def table1_beams() -> PlanResult:
    """Table I as a plan that designs its beams (``beams``): validated with the design."""
    doc = table1_plan({"draws": 1}) | {"beams": {"design_positions": 4, "random_seeds": 1}}
    return run_plan(doc, executor=SerialExecutor())


def _designed_bounds(result: PlanResult, name: str, pair: dict[str, Any]) -> tuple[float, float]:
    """(PEB_T, PEB_R) of one validated pair by compute_bounds with the layout's designed
    profiles and beam powers kept in memory (nothing known, as the estimator)."""
    from ris_planner.bounds.compute import compute_bounds
    from ris_planner.planning.beams import layout_scenario

    doc = result.document
    design = result.beams[(0, 1)].codebooks[name]
    sc = layout_scenario(doc.system, [result.sites[s].ris for s in (0, 1)], [], doc.environment)
    res = compute_bounds(
        sc, [pair["tx"]], [pair["rx"]], profiles=design.profiles, beam_powers=design.powers
    )
    assert res.peb_tx is not None
    return float(res.peb_tx[0]), float(res.peb_rx[0])


def test_designed_beams_are_validated_with_their_profiles_and_powers(
    table1_beams: PlanResult,
) -> None:
    """A plan with ``beams``: the signal and the bounds use the design with the best plan
    objective (its profiles and beam powers), plan.json says which; seeds reproduce."""
    v = table1_beams.validation
    assert v is not None
    report = table1_beams.beams[(0, 1)]
    name = report.best_design("higher")  # coverage: higher is better
    assert name is not None
    lay = v["layouts"][0]
    cb = lay["codebook"]
    assert cb["kind"] == "designed" and cb["name"] == name
    assert cb["sha256_16"] == report.codebooks[name].digest()
    assert v["codebook"]["kind"] == "designed" and v["codebook"]["names"] == [name]
    pair = lay["pairs"][0]
    peb_tx, peb_rx = _designed_bounds(table1_beams, name, pair)
    assert_close(pair["peb_tx_m"], peb_tx, accuracy=BOUND_ACCURACY)
    assert_close(pair["peb_rx_m"], peb_rx, accuracy=BOUND_ACCURACY)
    rand = recheck(table1_beams, codebook="random")
    assert rand["codebook"] == {"kind": "random", "seed": 0}
    assert rand["layouts"][0]["codebook"] == {"kind": "random", "seed": 0}
    # the random codebook's bound is another number: the design is what was compared to
    assert abs(rand["layouts"][0]["pairs"][0]["peb_rx_m"] / peb_rx - 1) > 0.01
    assert _strip(recheck(table1_beams)) == _strip(v)


def test_a_named_design_is_validated_and_a_missing_one_falls_back() -> None:
    """``validation.design`` picks one design (here DIR+DER with uniform power); its bound is
    compute_bounds with those profiles and powers. A design the layout lacks (the SDP did not
    solve) falls back to the best one and says so."""
    doc = table1_plan({"draws": 1, "design": "dir_der_uniform"}) | {
        "beams": {"design_positions": 4, "random_seeds": 1}
    }
    res = run_plan(doc, executor=SerialExecutor())
    assert res.validation is not None
    lay = res.validation["layouts"][0]
    assert lay["codebook"]["name"] == "dir_der_uniform" and lay["codebook"]["design"] == "dir+der"
    assert lay["codebook"]["powers"] == "uniform" and lay["codebook"]["beam_power_max"] == 1.0
    pair = lay["pairs"][0]
    peb_tx, peb_rx = _designed_bounds(res, "dir_der_uniform", pair)
    assert_close(pair["peb_rx_m"], peb_rx, accuracy=BOUND_ACCURACY)
    assert_close(pair["peb_tx_m"], peb_tx, accuracy=BOUND_ACCURACY)
    codebooks = dict(res.beams[(0, 1)].codebooks)
    codebooks.pop("dir_der_sdp", None)
    beams = {(0, 1): dataclasses.replace(res.beams[(0, 1)], codebooks=codebooks)}
    missing = dataclasses.replace(res, beams=beams)
    again = recheck(missing, design="dir_der_sdp")
    cb = again["layouts"][0]["codebook"]
    assert "'dir_der_sdp' is not available" in cb["note"]
    assert cb["kind"] == "designed" and cb["name"] != "dir_der_sdp"


def test_a_plan_without_beams_is_validated_with_the_seeded_random_codebook(
    table1: PlanResult,
) -> None:
    v = table1.validation
    assert v is not None
    assert v["codebook"] == {"kind": "random", "seed": 0}
    assert v["layouts"][0]["codebook"] == {"kind": "random", "seed": 0}


def test_designed_beams_on_a_spread_map_reach_their_bound() -> None:
    """3 × 3 map points 0.6 m apart around each of Table I's UEs: the best design (diverse
    beams) is validated, its bound below the random codebook's, and the estimator reaches it
    (no outlier, no shortfall); with the one-point map the same design fails the coarse stage
    (docs/validation/estimator.md, "Designed beams")."""
    doc = table1_plan({"draws": 2, "pairs": 3}) | {
        "beams": {"design_positions": 16, "random_seeds": 1}
    }
    for m in ("tx_map", "rx_map"):
        x, y, z = doc[m]["points"][0]
        steps = (-0.6, 0.0, 0.6)
        doc[m] = {"points": [[x + dx, y + dy, z] for dx in steps for dy in steps]}
    doc["validation"]["search_region"] = {"min_m": [-3.5, -5.5, -0.4], "max_m": [-0.5, -2.5, 0.6]}
    res = run_plan(doc, executor=SerialExecutor())
    assert res.validation is not None
    lay = res.validation["layouts"][0]
    assert lay["codebook"]["kind"] == "designed"
    assert sum(lay["outliers"].values()) == 0 and lay["shortfall"]["count"] == 0
    rand = recheck(res, codebook="random")["layouts"][0]
    for p, q in zip(lay["pairs"], rand["pairs"], strict=True):
        assert p["peb_rx_m"] < q["peb_rx_m"] / 2
