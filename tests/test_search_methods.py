"""Search methods as registered strategies (docs/concepts/planning.md, "Search methods"): every
(method, option) pair is either planned or refused before any work naming the method and the
option; ``auto`` is resolved in one place and its reason reaches plan.json, the preview and
the command line; a toy method registered only here runs through the one pipeline."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from district_site import street_doc
from waits import HANG_S

from ris_planner.core.errors import DocumentFieldError
from ris_planner.io.gis_outputs import PLAN_WRITERS
from ris_planner.model.search_methods import (
    PLAN_OPTIONS,
    Capabilities,
    SearchMethod,
    registered_methods,
    search_method,
)
from ris_planner.planning import methods
from ris_planner.planning.pipeline import run_plan
from ris_planner.planning.resources.admission import admit

OPTION_DOCUMENTS: dict[str, dict[str, Any]] = {
    "beams": {"beams": {}},
    "validation": {"validation": {"pairs": 4, "draws": 1}},
    "nested": {"rollout": "nested"},
    "sweep": {"sweep": {"tx_power_dbm": [20]}},
    "sizing": {"sizing": {"ris_sizes": [[16, 16]]}},
    "budget": {"constraints": {"budget": 100.0}},
    "heatmap_tx": {"heatmap_tx": [0.0, 0.0, 1.5]},
}
"""A document fragment that asks for each option of :data:`PLAN_OPTIONS`."""


def test_every_option_has_a_document_that_asks_for_it() -> None:
    assert set(OPTION_DOCUMENTS) == {o.name for o in PLAN_OPTIONS}


@pytest.mark.parametrize("option", [o.name for o in PLAN_OPTIONS])
@pytest.mark.parametrize("method", [m.name for m in registered_methods()])
def test_each_method_plans_or_refuses_each_option(method: str, option: str) -> None:
    """The capability table: a method that honours an option admits the document; one that
    does not refuses it before any work, naming itself, the option's field and its flag."""
    doc = street_doc(method=method) | OPTION_DOCUMENTS[option]
    spec = search_method(method)
    opt = next(o for o in PLAN_OPTIONS if o.name == option)
    if option in spec.capabilities.options:
        assert admit(doc).document.search.method == method
        return
    with pytest.raises(DocumentFieldError) as err:
        admit(doc)
    assert err.value.field == opt.field
    assert f"search method {method!r}" in str(err.value)
    if opt.flag is not None:
        assert opt.flag in str(err.value)


@pytest.mark.parametrize("method", [m.name for m in registered_methods()])
def test_each_method_refuses_an_explicit_search_field_it_does_not_read(method: str) -> None:
    fields = {"restarts": 2, "max_exhaustive": 10, "certificate_iterations": 3}
    for name, value in fields.items():
        doc = street_doc(method=method)
        doc["search"] = {"method": method, name: value}
        if name in search_method(method).capabilities.search_fields:
            admit(doc)
            continue
        with pytest.raises(DocumentFieldError, match=f"does not read search.{name}"):
            admit(doc)


def test_refused_on_the_command_line_with_exit_two(tmp_path: Path) -> None:
    """The refusal reaches the command line as exit status 2 and one line naming the method
    and the option, before any work (nothing written)."""
    doc = street_doc(method="district") | {"heatmap_tx": [0.0, 0.0, 1.5]}
    f = tmp_path / "doc.json"
    f.write_text(json.dumps(doc))
    out = tmp_path / "out"
    run = subprocess.run(
        [sys.executable, "-m", "ris_planner.cli", "plan", str(f), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=HANG_S,
        check=False,
    )
    assert run.returncode == 2, run.stderr
    assert "heatmap_tx: search method 'district' does not give per-point bounds" in run.stderr
    assert not out.exists()


def test_refused_over_rest_with_422(tmp_path: Path) -> None:
    from api_helpers import api_client

    doc = street_doc(method="district") | {"rollout": "nested", "heatmap_tx": [0, 0, 1.5]}
    with api_client(tmp_path, workers=1) as client:
        for path in ("/v1/plans", "/v1/plans/validate"):
            answer = client.post(path, json=doc)
            assert answer.status_code == 422, answer.text
            assert "heatmap_tx" in answer.text and "'district'" in answer.text


def test_the_methods_and_their_capabilities_are_listed(tmp_path: Path) -> None:
    """GET /v1/search-methods lists auto's rule and every registered method with its
    capabilities (the page builds its method list and option hints from it)."""
    from api_helpers import api_client

    with api_client(tmp_path, workers=1) as client:
        answer = client.get("/v1/search-methods")
        assert answer.status_code == 200, answer.text
        body = answer.json()
    listed = {m["name"]: m for m in body["methods"]}
    assert set(listed) == {m.name for m in registered_methods()}
    for m in registered_methods():
        assert listed[m.name]["capabilities"] == m.capabilities.to_json()
    assert body["auto"]["name"] == "auto" and body["auto"]["description"]
    assert [o["name"] for o in body["options"]] == [o.name for o in PLAN_OPTIONS]
    # the GIS files come from the writers' registry too (the page's download list)
    with api_client(tmp_path / "files", workers=1) as client:
        files = client.get("/v1/plan-files").json()["files"]
    assert [(f["name"], f["filename"], f["media_type"]) for f in files] == [
        (w.name, w.filename, w.media_type) for w in PLAN_WRITERS
    ]


def test_the_preview_names_the_method_that_runs() -> None:
    """The preview (POST /v1/plans/validate) and the run resolve auto by the same rule: the
    same method per count and the same reason."""
    from api.routes.web import _preview

    big = street_doc(method="auto", counts=(8,))
    big["search"] = {"method": "auto", "max_exhaustive": 1, "restarts": 1000, "max_rounds": 10000}
    preview = _preview(json.dumps(big).encode(), 6144)
    assert preview.search_method["used"] == "district"
    assert set(preview.methods.values()) == {"district"}
    plan = run_plan(big).to_json()
    assert plan["search_method"] == preview.search_method
    assert {e["method"] for e in plan["by_count"]} == {"district"}


class _FirstSites:
    """A toy strategy: the first sites of every count, scored by the enumerating searches'
    scorer (what the pipeline needs of a method, nothing more)."""

    def run(self, inputs, progress, executor, clock, background_checks=False, goal=None):  # type: ignore[no-untyped-def]
        from dataclasses import replace

        from ris_planner.planning.enumerating import run_enumerating

        base = run_enumerating(inputs, progress, executor, clock, False, goal)
        counts = []
        for cr in base.counts:
            layout = tuple(range(cr.ris_count))
            loss = float(base.scorer.exact_loss(np.array([layout]))[0])
            outcome = replace(cr.outcome, layouts=np.array([layout]), losses=np.array([loss]))
            outcome.method = "first"
            counts.append(
                replace(
                    cr,
                    outcome=outcome,
                    ranked=[(layout, loss)],
                    best_metric=base.layout_metric(layout),
                    certificate=None,
                    ties=(),
                    n_ties=1,
                )
            )
        return replace(base, counts=counts)

    def size_rows(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        raise NotImplementedError


def test_a_method_registered_here_runs_through_the_one_pipeline() -> None:
    """A toy method, registered only in this test with the options it honours: the document
    validates with it, the options it does not honour are refused, and its plan.json has the
    keys of every plan."""
    toy = SearchMethod(
        "first",
        "first sites",
        "the first candidates, unscored (a test of the registry)",
        Capabilities(
            objectives="any",
            pair_models=frozenset({"all", "sample"}),
            wavefronts=frozenset({"planar"}),
            codebooks=frozenset({"expected_random"}),
            options=frozenset(),
            search_fields=frozenset({"top_k"}),
            max_ris=4,
            scoring="site_cache",
        ),
    )
    methods.register(toy, _FirstSites())
    try:
        doc = street_doc(method="first")
        plan = run_plan(doc).to_json()
        want = run_plan(street_doc(method="exhaustive")).to_json()
        assert plan.keys() == want.keys()
        assert [e["sites"] for e in plan["by_count"]] == [[0, 1], [0, 1, 2]]
        assert {e["method"] for e in plan["by_count"]} == {"first"}
        assert plan["search_method"]["used"] == "first"
        with pytest.raises(DocumentFieldError, match="search method 'first' does not give"):
            admit(doc | {"rollout": "nested"})
    finally:
        methods.unregister("first")
    with pytest.raises(ValueError, match="unknown search method 'first'"):
        admit(street_doc(method="first"))
