"""Beams designed from the UE maps and power allocation for a recommended layout:
designed beams against random codebooks on narrow and wide maps (the paper's Fig. 5 trend),
the power-allocation order on the design positions, reproducibility, the re-evaluation by an
independent scenario route, and the layout + maps document over REST."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from api_helpers import api_client, wait_for
from tolerance import SDP_ACCURACY, assert_close

from ris_planner.bounds.compute import compute_bounds
from ris_planner.model.plan import PlanDocument
from ris_planner.model.scenario import Scenario
from ris_planner.planning import PlanResult, SerialExecutor, plan_preset, run_plan
from ris_planner.planning.beams import (
    design_beams,
    design_positions,
    run_layout_beams,
)
from ris_planner.planning.outputs.report import write_figures
from ris_planner.planning.scoring.scorer import objective_value

SOLVER_RTOL = SDP_ACCURACY
"""The SDP's own objective and its re-evaluation by compute_bounds on the design positions
agree to the interior-point solver's tolerance (tests/tolerance.py)."""

ORDER_RTOL = 1e-9
"""SDP ≤ γ_P ≤ uniform on the design positions up to the rounding of compute_bounds."""

ANCHORS = plan_preset("fig10-anchors")
NARROW_TX = {"grid": {"x": [-2.1, -1.9, 0.1], "y": [-2.1, -1.9, 0.1], "z": [0, 0, 1]}}
NARROW_RX = {"grid": {"x": [1.4, 1.6, 0.1], "y": [1.9, 2.1, 0.1], "z": [0, 0, 1]}}
WIDE = {"grid": {"x": [-3.5, 3.5, 1.0], "y": [-3.5, 3.5, 1.0], "z": [0, 0, 1]}}
OBJECTIVE = {"kind": "mean_capped", "cap_m": 1.0}
BEAMS = {"design_positions": 16, "random_seeds": 2, "seed": 0}


def anchors_doc(tx_map: dict[str, Any], rx_map: dict[str, Any]) -> dict[str, Any]:
    """The four Fig. 10 anchors as candidates, 2 RISs, all TX × RX pairs of the two maps."""
    doc = {k: ANCHORS[k] for k in ("system", "ris", "candidates")}
    return doc | {
        "tx_map": tx_map,
        "rx_map": rx_map,
        "pairs": "all",
        "objective": OBJECTIVE,
        "ris_count": [2],
        "beams": BEAMS,
    }


@pytest.fixture(scope="module")
def narrow() -> PlanResult:
    return run_plan(anchors_doc(NARROW_TX, NARROW_RX), executor=SerialExecutor())


@pytest.fixture(scope="module")
def wide() -> PlanResult:
    return run_plan(anchors_doc(WIDE, WIDE), executor=SerialExecutor())


def beams_of(result: PlanResult) -> dict[str, Any]:
    entry: dict[str, Any] = result.to_json()["by_count"][0]["beams"]
    return entry


def test_designed_beams_beat_random_on_a_narrow_map_not_on_a_wide_one(
    narrow: PlanResult, wide: PlanResult
) -> None:
    n, w = beams_of(narrow)["objective"], beams_of(wide)["objective"]
    # narrow map (0.2 m squares against an 8 m site): beams pointed at the UEs beat every
    # random codebook by far, DIR+DER (with its derivative beams) beats DIR
    assert n["dir_der_gamma_p"] < 0.5 * n["random_min"]
    assert n["directional"] < 0.5 * n["random_min"]
    assert n["dir_der_gamma_p"] < n["directional"]
    # wide map (the whole site): designed beams are no better than the best random draw
    assert w["dir_der_gamma_p"] >= w["random_min"]
    assert w["directional"] >= w["random_min"]
    for obj in (n, w):  # the search's own score is reported beside them
        assert obj["random_min"] <= obj["random_mean"] <= obj["random_max"]
        assert obj["expected_random"] is not None


def test_power_allocation_order_and_solver_agreement(narrow: PlanResult, wide: PlanResult) -> None:
    for result in (narrow, wide):
        b = beams_of(result)
        d = b["design_objective_m2"]
        assert b["sdp"]["status"] == "optimal"
        assert d["sdp"] <= d["gamma_p"] * (1 + ORDER_RTOL)
        assert d["gamma_p"] <= d["uniform"] * (1 + ORDER_RTOL)
        assert abs(d["sdp"] - d["sdp_solver"]) <= SOLVER_RTOL * d["sdp"]
        assert b["design_positions"] == min(BEAMS["design_positions"], result.pairs.size)
        assert b["samples_per_block"] == {"directional": 64, "directional_derivative": 21}


def test_design_positions_reproduce_from_the_seed(rng: np.random.Generator) -> None:
    w = rng.uniform(0, 1, 200)
    mask = rng.uniform(size=200) < 0.6
    a = design_positions(w, mask, 30, seed=3)
    np.testing.assert_array_equal(a, design_positions(w, mask, 30, seed=3))
    assert not np.array_equal(a, design_positions(w, mask, 30, seed=4))
    assert a.size == 30 == np.unique(a).size and np.all(mask[a])
    few = design_positions(w, mask & (np.arange(200) < 20), 30, seed=3)
    np.testing.assert_array_equal(few, np.nonzero(mask[:20])[0])  # all of them, sorted


def test_samples_come_from_the_pairs_each_ris_serves(narrow: PlanResult) -> None:
    doc = narrow.document
    ris = [narrow.sites[s].ris for s in (1, 3)]
    pairs = narrow.pairs
    served = np.zeros((2, pairs.size), dtype=bool)
    served[0, ::3] = True  # RIS 0 serves a third of the pairs, RIS 1 none
    beams = design_beams(doc.system, ris, pairs, served, seed=1)
    tx0, rx0 = beams.samples[0]
    allowed = {(tuple(t), tuple(r)) for t, r in zip(pairs.tx[::3], pairs.rx[::3], strict=True)}
    assert all((tuple(t), tuple(r)) in allowed for t, r in zip(tx0, rx0, strict=True))
    assert beams.unserved == [1]
    for block in (*beams.directional, *beams.derivative):
        assert block.shape == (64, 100)
        np.testing.assert_allclose(np.abs(block), 1.0, rtol=0, atol=1e-12)


def test_reported_objectives_equal_an_explicit_codebook_scenario(narrow: PlanResult) -> None:
    """Re-derive the DIR+DER profiles from the seed, put them in a validated scenario document
    (explicit phases) and recompute the plan objective of the SDP and γ_P powers."""
    doc: PlanDocument = narrow.document
    lay = narrow.counts[0].ranked[0][0]
    ris = [narrow.sites[s].ris for s in lay]
    pairs = narrow.pairs
    served = np.ones((2, pairs.size), dtype=bool)
    beams = design_beams(doc.system, ris, pairs, served, seed=BEAMS["seed"])
    report = beams_of(narrow)
    scenario = Scenario.model_validate(
        {
            "system": doc.system.model_dump(),
            "ris": [r.model_dump() for r in ris],
            "tx": pairs.tx.tolist(),
            "rx": pairs.rx.tolist(),
            "codebook": {
                "kind": "explicit",
                "phases": [np.angle(p).tolist() for p in beams.derivative],
            },
        }
    )
    for key, powers in (
        ("dir_der_sdp", report["sdp"]["powers"]),
        ("dir_der_uniform", None),
    ):
        res = compute_bounds(scenario, beam_powers=powers)
        value = objective_value(doc.objective, res.peb_rx[None, :], pairs.weights)[0]
        assert value == pytest.approx(report["objective"][key], rel=1e-12)


def test_figure_and_extra_layout(narrow: PlanResult, tmp_path: Path) -> None:
    paths = write_figures(narrow, tmp_path)
    assert paths["beams"].stat().st_size > 10_000
    doc = anchors_doc(NARROW_TX, NARROW_RX)
    doc["beams"] = BEAMS | {"layouts": [[0, 2]], "design_positions": 4, "random_seeds": 1}
    out = run_plan(doc, executor=SerialExecutor()).to_json()
    sites = [entry["sites"] for entry in out["beams"]["layouts"]]
    assert [0, 2] in sites and out["by_count"][0]["sites"] in sites
    bad = doc | {"beams": BEAMS | {"layouts": [[0, 9]]}}
    with pytest.raises(ValueError, match=r"beams.layouts entry \[0, 9\]"):
        run_plan(bad, executor=SerialExecutor())


def layout_doc() -> dict[str, Any]:
    """The best narrow-map 2-RIS layout as a layout + UE maps power document."""
    doc = anchors_doc(NARROW_TX, NARROW_RX)
    return {
        "system": doc["system"],
        "ris": [
            {
                "position": ANCHORS["candidates"][i]["position"],
                "orientation": ANCHORS["candidates"][i]["orientation"],
                **ANCHORS["ris"],
            }
            for i in (1, 3)
        ],
        "tx_map": NARROW_TX,
        "rx_map": NARROW_RX,
        "objective": OBJECTIVE,
        "beams": BEAMS | {"design_positions": 4, "random_seeds": 1},
    }


def test_layout_and_maps_power_document_over_rest(tmp_path: Path) -> None:
    doc = layout_doc()
    expected = run_layout_beams(doc)
    with api_client(tmp_path, workers=1) as client:
        r = client.post("/v1/power-allocations", json=doc)
        assert r.status_code == 202, r.text
        view = wait_for(client, r.json()["id"], ("succeeded", "failed"))
        assert view["status"] == "succeeded", view["error"]
        got = view["result"]
        # another process (its own BLAS threads): the same SDP solved to the solver's tolerance
        assert_close(got["objective"], expected["objective"], accuracy=SOLVER_RTOL)
        powers = np.asarray(expected["sdp"]["powers"], dtype=float)
        assert_close(
            got["sdp"]["powers"],
            expected["sdp"]["powers"],
            accuracy=SOLVER_RTOL,
            atol=SOLVER_RTOL * float(np.max(powers)),
        )
        bad = doc | {"beams": {"design_positions": 100000}}
        r = client.post("/v1/power-allocations", json=bad)
        assert r.status_code == 422
        fields = [f["field"] for f in r.json()["fields"]]
        assert any("design_positions" in f for f in fields), r.json()
        r = client.post("/v1/power-allocations", json=doc | {"max_pairs": 10})
        assert r.status_code == 413, r.text


def test_unordered_pairs_are_scored_in_both_directions_as_the_plan() -> None:
    """With ``unordered`` pairs the plan counts each pair both ways (the reverse PEB_R is the
    forward PEB_T); the beam report's expected_random value is the plan's own objective."""
    doc = anchors_doc(NARROW_TX, NARROW_TX)
    doc |= {
        "tx_map": {"points": [[-2, -2, 0], [1.5, 2, 0], [2, -1, 0], [-1, 2.5, 0]]},
        "pairs": "unordered",
        "objective": {"kind": "mean_capped", "cap_m": 1.0},
        "beams": BEAMS | {"design_positions": 4, "random_seeds": 1},
    }
    doc["rx_map"] = doc["tx_map"]
    out = run_plan(doc, executor=SerialExecutor()).to_json()
    entry = out["by_count"][0]
    assert entry["beams"]["objective"]["expected_random"] == pytest.approx(
        entry["objective"], rel=1e-12
    )
