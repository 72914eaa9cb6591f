"""``POST /v1/plans``: a job whose result is ``ris-planner plan``'s plan.json, with figures."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from api_helpers import api_client, wait_for
from tolerance import BOUND_ACCURACY, assert_close

from ris_planner.planning import SerialExecutor, run_plan

GRID = {"grid": {"x": [-3, 3, 1], "y": [-3, 3, 1], "z": [0, 0.5, 0.5]}}


def small_plan_doc(**over: Any) -> dict[str, Any]:
    """Five candidates on a ring facing the centre, 7×7×2 grids, 200 sampled pairs, 2–3 RISs:
    a plan of a fraction of a second."""
    candidates = []
    for k in range(5):
        phi = 2 * math.pi * k / 5 + 0.1
        candidates.append(
            {
                "position": [4.5 * math.cos(phi), 4.5 * math.sin(phi), 2.0 + (k % 2)],
                "orientation": [phi + math.pi, math.pi / 6, 0.0],
            }
        )
    doc: dict[str, Any] = {
        "candidates": candidates,
        "tx_map": GRID,
        "rx_map": GRID,
        "pairs": {"sample": 200, "seed": 1},
        "objective": {"kind": "mean_capped", "metric": "rx", "cap_m": 1.0},
        "ris_count": [2, 3],
    }
    return doc | over


def without_timing(plan: dict[str, Any]) -> dict[str, Any]:
    """plan.json without what each run measures: its stage times and its resources."""
    return {k: v for k, v in plan.items() if k not in ("timing_s", "resources")}


def test_plan_job_equals_run_plan_with_figures(tmp_path: Path) -> None:
    doc = small_plan_doc()
    with api_client(tmp_path, workers=1) as client:
        r = client.post("/v1/plans", json=doc)
        assert r.status_code == 202 and r.json()["kind"] == "plan"
        view = wait_for(client, r.json()["id"], ("succeeded", "failed"))
        assert view["status"] == "succeeded", view["error"]
        gis = {"geojson", "geotiff", "points_csv"}  # ris_planner.io.gis_outputs.GIS_FILES
        assert set(view["figures"]) == {"topview", "heatmap", "cdf"} | gis
        for name, url in view["figures"].items():
            if name not in gis:
                png = client.get(url)
                assert png.status_code == 200 and png.content[:4] == b"\x89PNG"
        geo = client.get(view["figures"]["geojson"])
        assert geo.headers["content-type"] == "application/geo+json"
        assert geo.json()["type"] == "FeatureCollection"
        tif = client.get(view["figures"]["geotiff"])
        assert tif.headers["content-type"] == "image/tiff" and tif.content[:4] == b"II*\x00"
        rows = client.get(view["figures"]["points_csv"]).text.splitlines()
        assert rows[0].startswith("index,x_m,y_m,z_m,weight") and len(rows) == 1 + 7 * 7 * 2
    with SerialExecutor() as executor:
        expected = run_plan(doc, executor=executor).to_json()
    # the worker is another process: plan figures to the bounds' accuracy, decisions exactly
    assert_close(without_timing(view["result"]), without_timing(expected), accuracy=BOUND_ACCURACY)
    assert [b["ris_count"] for b in view["result"]["by_count"]] == [2, 3]


def test_plan_errors(tmp_path: Path) -> None:
    with api_client(tmp_path, workers=1) as client:
        r = client.post("/v1/plans", json=small_plan_doc(ris_count=[0]))
        assert r.status_code == 422 and r.json()["fields"][0]["field"].startswith("ris_count")
        # more RISs than candidate sites: refused at submission (the job's own check, shared)
        r = client.post("/v1/plans", json=small_plan_doc(ris_count=[9]))
        assert r.status_code == 422 and "exceeds the 5 candidate sites" in r.json()["message"]
        assert r.json()["fields"][0]["field"] == "ris_count"
        assert client.get("/v1/jobs").json()["total"] == 0
        presets = client.get("/v1/presets").json()
        assert [p["name"] for p in presets["plans"]] == ["fig10-anchors", "junction", "hall"]


def test_plan_body_limit_is_413(tmp_path: Path) -> None:
    doc = small_plan_doc(description="x" * 5000)
    with api_client(tmp_path, max_body_bytes=4096) as client:
        r = client.post("/v1/plans", json=doc)
        assert r.status_code == 413 and r.json()["limit"] == 4096
        assert client.get("/v1/jobs").json()["total"] == 0


def test_plan_job_with_validation(tmp_path: Path) -> None:
    """The document's ``validation`` over REST: plan.json ``validation`` and its figure; bad
    settings are refused at submission with the field."""
    doc = small_plan_doc(ris_count=[3], validation={"pairs": 2, "draws": 1})
    with api_client(tmp_path, workers=1) as client:
        r = client.post("/v1/plans", json=doc)
        assert r.status_code == 202
        view = wait_for(client, r.json()["id"], ("succeeded", "failed"))
        assert view["status"] == "succeeded", view["error"]
        v = view["result"]["validation"]
        assert v["pairs"] == 2 and [lay["ris_count"] for lay in v["layouts"]] == [3]
        assert len(v["layouts"][0]["pairs"]) == 2 and v["threshold_m"] == 1.0
        assert "validation" in view["result"]["timing_s"]
        png = client.get(view["figures"]["validation"])
        assert png.status_code == 200 and png.content[:4] == b"\x89PNG"
        bad = small_plan_doc(validation={"pairs": 1000, "draws": 1000})
        r = client.post("/v1/plans", json=bad)
        assert r.status_code == 422 and "exceed the limit" in r.json()["message"]
