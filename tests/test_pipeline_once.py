"""One pipeline for every plan (docs/concepts/planning.md, "Pipeline"): a document is converted
from its frame, validated, estimated and its maps built exactly once on its way from the
command line's reading to plan.json, whatever the search method; an enumerating and a district
plan of the same document have the same plan.json keys, and a district plan writes the same
files (its heatmap, GeoTIFF and points CSV re-read here)."""

from __future__ import annotations

import csv
import json
import sys
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from district_site import street_doc
from tolerance import assert_close

from ris_planner.model.plan import PlanDocument


@pytest.fixture
def calls(monkeypatch: pytest.MonkeyPatch) -> Iterator[Counter[str]]:
    """Counts the calls of the conversions, validations, estimates and map builds, wherever
    the package imported them from."""
    import ris_planner.io.frames as frames
    import ris_planner.planning.inputs.ue_maps as ue_maps
    import ris_planner.planning.resources.admission as admission

    seen: Counter[str] = Counter()

    def counted(name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            seen[name] += 1
            return fn(*args, **kwargs)

        return wrapper

    targets = {
        "to_local": frames.to_local,
        "build_map": ue_maps.build_map,
        "estimate_plan": admission.estimate_plan,
        "admit": admission.admit,
    }
    for name, fn in targets.items():
        wrapped = counted(name, fn)
        for module in list(sys.modules.values()):
            if (module.__name__ or "").startswith("ris_planner") and getattr(
                module, name, None
            ) is fn:
                monkeypatch.setattr(module, name, wrapped)
    validate = PlanDocument.model_validate.__func__  # type: ignore[attr-defined]

    def model_validate(cls: type, *args: Any, **kwargs: Any) -> Any:
        seen["PlanDocument.model_validate"] += 1
        return validate(cls, *args, **kwargs)

    monkeypatch.setattr(PlanDocument, "model_validate", classmethod(model_validate))
    yield seen


@pytest.mark.parametrize("method", ["district", "exhaustive"])
def test_a_plan_is_converted_validated_estimated_and_mapped_once(
    method: str, calls: Counter[str], tmp_path: Path
) -> None:
    """The command line's path (admit_request, then plan_document through run_plan): each of
    the conversion, the validation, the estimate and each UE map build happens exactly once."""
    from ris_planner.io.estimates import plan_measured
    from ris_planner.io.plan_request import admit_request
    from ris_planner.runtime.executor import SerialExecutor

    doc = street_doc(method=method)
    request = admit_request(doc)
    done = plan_measured(SerialExecutor(), request, tmp_path)
    assert done.plan["search_method"]["used"] == method
    assert calls["to_local"] == 1
    assert calls["admit"] == 1
    assert calls["PlanDocument.model_validate"] == 1
    assert calls["estimate_plan"] == 1
    assert calls["build_map"] == 2  # the TX map and the RX map


def test_enumerating_and_district_plans_have_the_same_keys() -> None:
    from ris_planner.planning.pipeline import run_plan

    district = run_plan(street_doc(method="district")).to_json()
    exhaustive = run_plan(street_doc(method="exhaustive")).to_json()
    assert district.keys() == exhaustive.keys()
    for a, b in zip(district["by_count"], exhaustive["by_count"], strict=True):
        assert a.keys() == b.keys()
    assert district["points"][0].keys() == exhaustive["points"][0].keys()
    assert_close(district["pairs_summary"], exhaustive["pairs_summary"], ulps=4096)


def test_a_district_plan_writes_the_files_of_every_plan(tmp_path: Path) -> None:
    """The district plan's per-point fields reach the GeoTIFF and the points CSV; read back,
    they are plan.json's ``points`` (the largest count's bound, per RX point)."""
    rasterio = pytest.importorskip("rasterio")
    from ris_planner.io.estimates import plan_measured
    from ris_planner.io.plan_request import admit_request
    from ris_planner.runtime.executor import SerialExecutor

    done = plan_measured(SerialExecutor(), admit_request(street_doc()), tmp_path)
    plan = done.plan
    for name in ("topview", "heatmap", "cdf", "district", "geojson", "geotiff", "points_csv"):
        assert done.files[name].stat().st_size > 0, name
    largest = str(plan["by_count"][-1]["ris_count"])
    bounds = {p["index"]: p["bound_m"][largest] for p in plan["points"]}
    with open(done.files["points_csv"], newline="") as f:
        rows = list(csv.DictReader(line for line in f if not line.startswith("#")))
    assert len(rows) == len(plan["points"])
    column = f"bound_m_{largest}"
    for row in rows:
        want = bounds[int(row["index"])]
        got = row[column]
        assert (got == "") == (want is None), row
        if want is not None:
            assert abs(float(got) - want) <= 1e-6 * want
    with rasterio.open(done.files["geotiff"]) as tif:
        band = tif.read(1)
    finite = [b for b in bounds.values() if b is not None]
    shown = band[np.isfinite(band) & (band != tif.nodata)]
    assert shown.size > 0 and shown.max() <= max(finite) * (1 + 1e-6)
    assert json.loads(json.dumps(plan))  # plan.json as written
