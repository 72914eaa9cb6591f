"""Warnings of bounds and plans: expected-random optimism, grating lobes, near field; the
random-codebook re-evaluation of a plan's best layouts."""

from __future__ import annotations

import numpy as np
from test_planning import plan_doc

from ris_planner import compute_bounds, load_scenario, preset_document
from ris_planner.bounds import advice
from ris_planner.planning import SerialExecutor, run_plan


def table1(**over: object) -> dict[str, object]:
    return preset_document("paper-table1") | over


def test_table1_has_no_warnings_and_json_lists_them() -> None:
    js = compute_bounds(load_scenario(table1())).to_json(batch=False)
    assert js["warnings"] == []


def test_expected_random_optimism_warning_below_the_measured_block_length() -> None:
    doc = table1(codebook={"kind": "expected_random"})
    assert compute_bounds(load_scenario(doc)).warnings == ()  # G/Γ = 192/3 = 64
    doc["system"] = {"transmissions": 24}  # G/Γ = 8: 1.15× measured
    w = compute_bounds(load_scenario(doc)).warnings
    assert len(w) == 1 and w[0].startswith("expected_random optimism") and "= 8 " in w[0]
    doc["codebook"] = {"kind": "random", "seed": 1}  # the random codebook is not optimistic
    assert compute_bounds(load_scenario(doc)).warnings == ()
    assert advice.expected_random_warning(48, 2) is None  # G/Γ = 16, the threshold


def test_spacing_above_half_wavelength_warns_but_computes() -> None:
    doc = table1()
    ris = [dict(r) for r in doc["ris"]]  # type: ignore[attr-defined]
    ris[1]["spacing_m"] = 0.02  # 2λ at 30 GHz
    res = compute_bounds(load_scenario(table1(ris=ris)))
    assert np.isfinite(res.peb_rx[0])
    lobes = [w for w in res.warnings if w.startswith("grating lobes")]
    assert len(lobes) == 1 and "ris2" in lobes[0]


def test_near_field_majority_advice() -> None:
    doc = table1()
    ris = [dict(r) | {"rows": 60, "cols": 60} for r in doc["ris"]]  # type: ignore[attr-defined]
    res = compute_bounds(load_scenario(table1(ris=ris)))
    assert not res.far_field.all()
    assert any(w.startswith("near field") for w in res.warnings)


def test_plan_reports_random_codebook_objective_and_warnings() -> None:
    res = run_plan(plan_doc(system={"transmissions": 24}, ris_count=[2]), executor=SerialExecutor())
    js = res.to_json()
    entry = js["by_count"][0]
    rc = entry["random_codebook"]
    assert rc["seeds"] == 5 and rc["pairs"] == res.pairs.size
    assert rc["expected"] == entry["objective"]
    assert rc["min"] <= rc["mean"] <= rc["max"]
    # mean-capped PEB_R: random codebooks are worse than the expected FIM (Jensen), G/Γ = 8
    assert rc["mean"] > rc["expected"]
    assert any(w.startswith("expected_random optimism") for w in js["warnings"])
