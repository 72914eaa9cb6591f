"""Explicit pairs (the pair model ``explicit``, docs/concepts/planning.md, "Pairs"): a plan over
the listed pairs – by map index or by position – is the plan over the same pairs drawn by a
sample; the list is refused before any work when it is malformed, too long or names no map
point; the served-share estimate samples the listed pairs themselves; every search method
declares the model."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from district_site import street_doc
from pydantic import ValidationError

from ris_planner.core.errors import LimitExceededError, RisPlannerError
from ris_planner.environment import Scene
from ris_planner.model.plan import PairList, PlanDocument
from ris_planner.model.search_methods import pair_model, registered_methods
from ris_planner.planning.pipeline import run_plan
from ris_planner.planning.prepare import prepare_plan
from ris_planner.planning.resources.admission import admit
from ris_planner.planning.resources.served import document_shares, pair_served_share
from ris_planner.runtime.executor import SerialExecutor


def _listed(doc: dict[str, Any], by: str) -> dict[str, Any]:
    """``doc`` with its sampled pairs listed explicitly (by ``index`` or ``position``)."""
    pairs = prepare_plan(doc).pairs
    if by == "index":
        listed = {"tx_index": pairs.tx_index.tolist(), "rx_index": pairs.rx_index.tolist()}
    else:
        listed = {"tx": pairs.tx.tolist(), "rx": pairs.rx.tolist()}
    return doc | {"pairs": listed}


def _by_count(doc: dict[str, Any]) -> list[tuple[int, list[int], float, float]]:
    plan = run_plan(doc, executor=SerialExecutor()).to_json()
    return [
        (e["ris_count"], e["sites"], e["objective"], e["certificate"]["objective_bound"])
        for e in plan["by_count"]
    ]


@pytest.mark.parametrize("by", ["index", "position"])
def test_listed_pairs_plan_as_the_sample_they_list(by: str) -> None:
    """The same pairs, the same weights: the district plan is the same, bit for bit (one
    process, the same operations in the same order)."""
    doc = street_doc(counts=(2, 3), sample=200)
    listed = _listed(doc, by)
    assert pair_model(PlanDocument.model_validate(listed)) == "explicit"
    assert _by_count(listed) == _by_count(doc)


def test_listed_pairs_keep_their_weights_and_order() -> None:
    doc = street_doc(sample=50)
    pairs = prepare_plan(doc).pairs
    weights = np.arange(1, 51, dtype=float)
    listed = doc | {
        "pairs": {
            "tx_index": pairs.tx_index[::-1].tolist(),
            "rx_index": pairs.rx_index[::-1].tolist(),
            "weights": weights.tolist(),
        }
    }
    got = prepare_plan(listed).pairs
    assert np.array_equal(got.tx_index, pairs.tx_index[::-1])
    assert np.array_equal(got.rx, pairs.rx[::-1])
    np.testing.assert_allclose(got.weights, weights / weights.sum(), rtol=1e-15)


def test_the_enumerating_searches_take_listed_pairs() -> None:
    doc = _listed(street_doc(counts=(2,), sample=80), "index") | {"search": {"method": "auto"}}
    plan = run_plan(doc, executor=SerialExecutor()).to_json()
    assert plan["pairs"] == 80 and plan["by_count"][0]["ris_count"] == 2
    assert plan["points"]  # per-point fields from the listed pairs themselves


@pytest.mark.parametrize(
    ("pairs", "words"),
    [
        ({"tx_index": [0, 1], "rx_index": [2]}, "same number of pairs"),
        ({"tx_index": [0], "rx_index": [1], "tx": [[0, 0, 1.5]], "rx": [[3, 0, 1.5]]}, "one of"),
        ({"tx_index": [0]}, "both tx_index and rx_index"),
        ({"tx_index": [], "rx_index": []}, "at least one"),
        ({"tx_index": [0, 1], "rx_index": [2, 3], "weights": [1.0]}, "one weight per pair"),
        ({"tx_index": [0, 1], "rx_index": [2, 3], "weights": [0.0, 0.0]}, "one must be positive"),
        ({"tx_index": [0], "rx_index": [10**6]}, "beyond the map"),
        ({"tx": [[0, 0, float("nan")]], "rx": [[3, 0, 1.5]]}, "finite"),
    ],
)
def test_malformed_lists_are_refused_by_the_model(pairs: dict[str, Any], words: str) -> None:
    with pytest.raises(ValidationError, match=words):
        PlanDocument.model_validate(street_doc() | {"pairs": pairs})


def test_a_list_above_max_pairs_is_refused_before_work() -> None:
    doc = _listed(street_doc(sample=60), "index") | {"max_pairs": 50}
    with pytest.raises(LimitExceededError, match="max_pairs = 50"):
        admit(doc)


def test_a_position_that_is_no_map_point_is_refused_naming_the_pair() -> None:
    doc = _listed(street_doc(sample=20), "position")
    doc["pairs"]["rx"][7] = [0.5, 0.5, 1.5]
    with pytest.raises(RisPlannerError, match=r"pairs\.rx\[7\].*no point of the rx_map"):
        prepare_plan(doc)


def test_a_pair_with_one_position_is_refused() -> None:
    doc = _listed(street_doc(sample=20), "index")
    doc["pairs"]["rx_index"][3] = doc["pairs"]["tx_index"][3]
    with pytest.raises(RisPlannerError, match="pair 3 has the same TX and RX"):
        prepare_plan(doc)


def test_the_served_share_samples_the_listed_pairs() -> None:
    """No second sampler: both shares of an explicit document are the pair share over its own
    pairs (the positions it lists)."""
    doc = _listed(street_doc(sample=300), "index")
    parsed = PlanDocument.model_validate(doc)
    inputs = prepare_plan(doc)
    scene = Scene.from_environment(parsed.environment)
    p = inputs.pairs
    want = pair_served_share(inputs.sites, p.tx, p.rx, np.ones(p.size), scene)
    assert document_shares(parsed) == (want, want)
    assert isinstance(parsed.pairs, PairList) and parsed.pairs.size == 300


def test_every_search_method_declares_the_explicit_model() -> None:
    for method in registered_methods():
        assert "explicit" in method.capabilities.pair_models, method.name
