"""An objective kind registered only here – higher is better, with a parameter of its own that
no shipped kind uses – runs end to end through every module that reads the objective: the
document, the plan (plan.json's direction words and certificate), the GIS export (GeoJSON and
GeoTIFF), the estimator check and the web page (its list, its level field, the document it
submits and the results it draws; docs/guides/adding-an-objective.md)."""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pydantic import ValidationError
from test_estimator_check import table1_plan

from ris_planner.io.gis_outputs import plan_outputs
from ris_planner.model.objectives import ObjectiveKind, objective_kind, register, unregister
from ris_planner.planning import PlanDocument, SerialExecutor, run_plan

try:  # the browser test's fixtures and helpers; the rest runs without a browser
    from test_web import (  # noqa: F401  (fixtures: browser, page, server, shots)
        WAIT_MS,
        browser,
        expect,
        js_num,
        open_page,
        page,
        server,
        shots,
        undeclared_percentages,
    )
    from test_web_map import upload

    NO_BROWSER = None
except pytest.skip.Exception as exc:
    NO_BROWSER = str(exc)

LIMIT_M = 0.1


class SquaredShare(ObjectiveKind):
    """Toy: the squared weighted fraction of pairs whose bound is ≤ ``limit_m`` (higher is
    better, monotone in every pair's bound)."""

    name = "toy_squared_share"
    label = "squared share"
    parameter = "limit_m"
    parameter_label = "Limit on the bound [m]"
    higher_is_better = True
    unit = ""
    max_value = 1.0

    def _limit(self, spec: Any) -> float:
        value = self.parameter_value(spec)
        assert value is not None
        return value

    def value(self, spec: Any, metric: Any, weights: Any) -> Any:
        return ((metric <= self._limit(spec)) * weights).sum(axis=1) ** 2

    def reference_level(self, spec: Any) -> float:
        return self._limit(spec)

    def screen_level(self, spec: Any) -> float | None:
        return self._limit(spec)


@pytest.fixture
def toy() -> Iterator[ObjectiveKind]:
    kind = register(SquaredShare())
    try:
        yield kind
    finally:
        unregister(kind.name)


def toy_document(name: str, **validation: Any) -> dict[str, Any]:
    doc = table1_plan(validation)
    doc["objective"] = {"kind": name, "metric": "rx", "limit_m": LIMIT_M}
    return doc


def test_the_document_takes_the_kinds_own_parameter(toy: ObjectiveKind) -> None:
    doc = PlanDocument.model_validate(toy_document(toy.name))
    assert toy.parameter_value(doc.objective) == LIMIT_M
    assert doc.objective.model_dump()["limit_m"] == LIMIT_M
    with pytest.raises(ValidationError, match="needs limit_m"):
        PlanDocument.model_validate({**toy_document(toy.name), "objective": {"kind": toy.name}})
    bad = {"kind": toy.name, "limit_m": -1.0}
    with pytest.raises(ValidationError, match="limit_m must be a finite number > 0"):
        PlanDocument.model_validate({**toy_document(toy.name), "objective": bad})
    # another kind does not take it, and the toy takes no other unknown field
    other = {"kind": "coverage", "threshold_m": 1.0, "limit_m": 1.0}
    with pytest.raises(ValidationError, match=r"objective\.limit_m: extra inputs"):
        PlanDocument.model_validate({**toy_document(toy.name), "objective": other})
    extra = {"kind": toy.name, "limit_m": 1.0, "limits_m": 1.0}
    with pytest.raises(ValidationError, match=r"objective\.limits_m: extra inputs"):
        PlanDocument.model_validate({**toy_document(toy.name), "objective": extra})
    props = PlanDocument.model_json_schema()["$defs"]["Objective"]
    assert "limit_m" in props["properties"] and props["additionalProperties"] is False


def test_a_higher_is_better_toy_runs_plan_export_and_estimator_check(
    toy: ObjectiveKind, tmp_path: Path
) -> None:
    result = run_plan(toy_document(toy.name, pairs=1, draws=2), executor=SerialExecutor())
    plan = result.to_json()
    assert plan["objective"] == {**plan["objective"], "kind": toy.name, "limit_m": LIMIT_M}
    assert plan["objective_better"] == "higher"
    (count,) = plan["by_count"]
    best = count["top_layouts"][0]
    assert 0.0 <= best["objective"] <= 1.0
    cert = count["certificate"]
    if cert is not None:
        assert cert["bound_side"] == "upper"
        if cert["objective_bound"] is not None:
            assert cert["objective_bound"] >= best["objective"] - 1e-12
    # the same document through a plan.json round trip validates (the parameter is kept)
    PlanDocument.model_validate({**toy_document(toy.name), "objective": plan["objective"]})
    # the GIS export of the local document
    files = plan_outputs(result, plan, toy_document(toy.name), tmp_path)
    fc = json.loads(files["geojson"].read_text())
    assert fc["type"] == "FeatureCollection" and fc["features"]
    # the GeoTIFF holds the best layout's bound at the RX point (the objective's own metric)
    rasterio = pytest.importorskip("rasterio")
    with rasterio.open(files["geotiff"]) as ds:
        band = ds.read(1)
    _, values, _ = result.heatmap()
    assert band.shape == (1, 1)
    assert abs(float(band[0, 0]) - float(values[0])) <= 1e-6 * float(values[0])  # float32
    # the estimator check counts a pair as covered at the kind's level
    v = plan["validation"]
    assert v["threshold_m"] == LIMIT_M and v["pairs"] == 1
    assert v["layouts"] and all(np.isfinite(p["bound_m"]) for p in v["layouts"][0]["pairs"])


def test_shipped_kinds_direction_and_check_level() -> None:
    cov, cap, qua = (objective_kind(n) for n in ("coverage", "mean_capped", "quantile"))
    assert (cov.better, cov.bound_side) == ("higher", "upper")
    assert (cap.better, cap.bound_side) == ("lower", "lower")
    assert (qua.better, qua.bound_side) == ("lower", "lower")
    doc = PlanDocument.model_validate(
        {**toy_document("coverage"), "objective": {"kind": "quantile", "q": 0.5}}
    )
    assert qua.check_level(doc.objective) is None


def test_the_guide_cites_existing_modules() -> None:
    root = Path(__file__).resolve().parent.parent
    page = (root / "docs/guides/adding-an-objective.md").read_text(encoding="utf-8")
    cited = set(re.findall(r"`((?:ris_planner|api|tests)/[\w/]+\.py)`", page))
    assert len(cited) >= 10
    missing = sorted(p for p in cited if not (root / p).is_file())
    assert not missing, f"docs/guides/adding-an-objective.md cites missing files: {missing}"
    protocol = (root / "ris_planner/model/objectives/protocol.py").read_text(encoding="utf-8")
    # the protocol members it names: the table's first column and every `name(...)` call
    members = set(re.findall(r"^\| `(\w+)`", page, flags=re.M))
    members |= set(re.findall(r"`(\w+)\(", page)) - {"MyKind"}
    unknown = sorted(
        m for m in members if not re.search(rf"^\s*def {m}\(|^\s+{m}: ", protocol, flags=re.M)
    )
    assert len(members) >= 15 and not unknown, unknown


@pytest.mark.skipif(NO_BROWSER is not None, reason=str(NO_BROWSER))
def test_the_page_plans_with_it(
    toy: ObjectiveKind, page: tuple[Any, Any], server: str, shots: Any, tmp_path: Path
) -> None:
    """The page lists the kind from ``GET /v1/objectives``, labels its level field with the
    kind's parameter, submits the kind's own field, and draws the plan's results the kind's
    way (higher is better, a fraction in %). The served page runs in its own process without
    the toy, so the requests that read it are answered here by the service's own functions
    (where the fixture registered it), and the plan runs here on the submitted document."""
    from api.routes.meta import objectives
    from api.routes.web import preview_answer
    from api.settings import Settings
    from ris_planner.io.geoplan import plan_document

    pg, _ = page
    memory_mb = Settings().job_memory_mb
    job_id = "7" * 32
    sent: dict[str, Any] = {}

    def view(status: str) -> dict[str, Any]:
        done = status == "succeeded"
        return {
            "id": job_id,
            "kind": "plan",
            "status": status,
            "progress": 1.0 if done else 0.0,
            "message": "done" if done else "",
            "error": None,
            "created_at": "2026-12-05T00:00:00+00:00",
            "started_at": None,
            "finished_at": None,
            "url": f"/v1/jobs/{job_id}",
            "estimate": None,
            "request": sent.get("doc", {}),
            "result": sent.get("plan") if done else None,
            "figures": {},
        }

    def answer(route: Any, body: Any, status: int = 200) -> None:
        text = body if isinstance(body, str) else json.dumps(body)
        route.fulfill(status=status, content_type="application/json", body=text)

    def validate(route: Any) -> None:
        got = preview_answer(route.request.post_data_buffer, memory_mb)
        route.fulfill(status=got.status, content_type="application/json", body=got.body)

    def submit(route: Any) -> None:
        if route.request.method != "POST":
            route.continue_()
            return
        sent["doc"] = json.loads(route.request.post_data or "{}")
        sent["plan"] = plan_document(sent["doc"], tmp_path / "plan").plan
        answer(route, view("queued"), 202)

    def events(route: Any) -> None:
        data = json.dumps({k: v for k, v in view("succeeded").items() if k != "result"})
        body = f"event: end\ndata: {data}\n\n"
        route.fulfill(status=200, content_type="text/event-stream", body=body)

    pg.route("**/v1/objectives", lambda route: answer(route, objectives().model_dump_json()))
    pg.route("**/v1/plans/validate", validate)
    pg.route("**/v1/plans", submit)
    pg.route(f"**/v1/jobs/{job_id}/events", events)
    pg.route(f"**/v1/jobs/{job_id}", lambda route: answer(route, view("succeeded")))
    open_page(pg, server)
    doc = toy_document(toy.name)
    del doc["validation"]
    upload(pg, doc, "toy-objective.json")
    expect(pg.locator("#f-objective-kind")).to_have_value(toy.name)
    expect(pg.locator("#f-objective-kind option:checked")).to_have_text(toy.label)
    expect(pg.locator("#label-objective-level")).to_have_text(toy.parameter_label)
    expect(pg.locator("#f-objective-level")).to_have_value(str(LIMIT_M))
    pg.fill("#f-objective-level", "0.2")
    pg.click("#submit")
    expect(pg.locator("#job-status")).to_contain_text("succeeded", timeout=WAIT_MS)
    assert sent["doc"]["objective"] == {"kind": toy.name, "metric": "rx", "limit_m": 0.2}
    plan = sent["plan"]
    assert plan["objective_better"] == "higher"
    expect(pg.locator("#results-note")).to_contain_text(f"{toy.name} of")
    expect(pg.locator("#results-note")).to_contain_text("higher is better")
    # a fraction that is no share of the pairs (share_of_servable null): the number itself,
    # never a percentage without its denominator
    entry = plan["by_count"][0]
    assert entry["share_of_servable"] is None and plan["objective_unit"] == ""
    best = entry["top_layouts"][0]["objective"]
    first = pg.locator("#count-table tbody tr").first
    expect(first.locator("td.objective")).to_have_text(js_num(best))
    assert undeclared_percentages(pg) == []
    shots.take(pg, "objective-extension")
