"""The objective protocol: an objective is one module behind
:class:`ris_planner.model.objectives.ObjectiveKind`; a toy kind registered here only runs a
whole plan, unknown kinds fail with the known ones listed, the service lists the kinds."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from api_helpers import api_client
from pydantic import ValidationError
from test_planning import plan_doc, reference_metric, setup
from tolerance import BOUND_ACCURACY, assert_close

from ris_planner.model.objectives import (
    ObjectiveKind,
    objective_kind,
    objective_names,
    register,
    unregister,
)
from ris_planner.planning import PlanDocument, SerialExecutor, run_plan
from ris_planner.planning.search.layouts import exhaustive


class WorstPairs(ObjectiveKind):
    """Toy: the weighted mean of min(bound, cap_m)² over the pairs (lower is better; a
    different value from every shipped kind, monotone in each pair's bound)."""

    name = "toy_mean_square"
    label = "toy mean square"
    parameter = "cap_m"
    parameter_label = "Cap [m]"
    unit = "m²"

    def value(self, spec: Any, metric: Any, weights: Any) -> Any:
        return (np.minimum(metric, spec.cap_m) ** 2 * weights).sum(axis=1)


@pytest.fixture
def toy() -> Iterator[ObjectiveKind]:
    kind = register(WorstPairs())
    try:
        yield kind
    finally:
        unregister(kind.name)


def test_shipped_kinds_and_json_names() -> None:
    assert objective_names()[:3] == ("coverage", "mean_capped", "quantile")
    assert objective_kind("coverage").higher_is_better
    assert not objective_kind("quantile").higher_is_better
    schema = PlanDocument.model_json_schema()
    kind = schema["$defs"]["Objective"]["properties"]["kind"]
    assert kind["enum"] == list(objective_names())


def test_unknown_kind_names_the_known_ones() -> None:
    with pytest.raises(ValidationError, match="known kinds: 'coverage', 'mean_capped', 'quantile'"):
        PlanDocument.model_validate(plan_doc(objective={"kind": "median", "q": 0.5}))
    with pytest.raises(ValueError, match="unknown objective kind 'median'"):
        objective_kind("median")


def test_a_toy_objective_runs_a_plan(toy: ObjectiveKind) -> None:
    doc = plan_doc(
        objective={"kind": toy.name, "metric": "rx", "cap_m": 0.4},
        pairs={"sample": 60, "seed": 3},
        ris_count=[2],
    )
    with pytest.raises(ValidationError, match="needs cap_m"):
        PlanDocument.model_validate(plan_doc(objective={"kind": toy.name}))
    plan = run_plan(doc, executor=SerialExecutor()).to_json()
    assert plan["objective"]["kind"] == toy.name and plan["objective_better"] == "lower"
    (count,) = plan["by_count"]
    best = count["top_layouts"][0]
    # the reported objective is the toy's value of the layout's compute_bounds PEB_R
    d, sites, pairs, scorer = setup(doc)
    metric = reference_metric(d, sites, pairs, tuple(best["sites"]))
    expect = float((np.minimum(metric, 0.4) ** 2 * pairs.weights).sum())
    assert_close(best["objective"], expect, accuracy=BOUND_ACCURACY)
    # and it is the exhaustive optimum of the toy objective
    ex = exhaustive(scorer, len(sites), 2, SerialExecutor())
    assert tuple(best["sites"]) == ex.ranked(1)[0][0]


def test_service_lists_the_registered_kinds(tmp_path: Path, toy: ObjectiveKind) -> None:
    with api_client(tmp_path) as client:
        body = client.get("/v1/objectives").json()
    names = [o["name"] for o in body["objectives"]]
    assert names == list(objective_names()) and toy.name in names
    cov = body["objectives"][0]
    assert cov == {
        "name": "coverage",
        "label": "coverage",
        "parameter": "threshold_m",
        "parameter_label": "Coverage threshold [m]",
        "higher_is_better": True,
        "unit": "",
    }
