"""``POST /v1/power-allocations``: a job whose result is the ``ris-planner power`` document."""

from __future__ import annotations

import typing
from pathlib import Path
from typing import Any

from api_helpers import api_client, wait_for
from tolerance import SDP_ACCURACY, assert_close

from api.routes.power import Solver
from ris_planner import preset_document
from ris_planner.power import run_power
from ris_planner.power.sdp import SOLVERS


def small_power_doc(**prior: Any) -> dict[str, Any]:
    """Table I with a 4-sample DIR+DER codebook: an SDP with 4 LMIs (about a second)."""
    doc = preset_document("paper-table1")
    doc["codebook"] = {"kind": "directional_derivative", "prior": {"sigma_m": 0.1, "samples": 4}}
    doc["codebook"]["prior"] |= prior
    return doc


def without_timing(result: dict[str, Any]) -> dict[str, Any]:
    """The result without wall-clock entries (``*_time_s``), which differ run to run."""
    sdp = {k: v for k, v in result["sdp"].items() if not k.endswith("_time_s")}
    return result | {"sdp": sdp}


def test_power_job_equals_run_power(tmp_path: Path) -> None:
    doc = small_power_doc()
    with api_client(tmp_path, workers=1) as client:
        r = client.post("/v1/power-allocations", json=doc, params={"objective": "sum"})
        assert r.status_code == 202
        job = r.json()
        assert r.headers["location"] == job["url"] == f"/v1/jobs/{job['id']}"
        assert job["status"] == "queued" and job["kind"] == "power"
        assert job["request"]["objective"] == "sum" and job["request"]["solver"] == "CLARABEL"
        view = wait_for(client, job["id"], ("succeeded", "failed"))
    assert view["status"] == "succeeded", view["error"]
    expected = run_power(doc, objective="sum").to_json()
    # the worker is another process: the SDP re-solved to the solver's tolerance
    assert_close(without_timing(view["result"]), without_timing(expected), accuracy=SDP_ACCURACY)
    assert view["result"]["sdp"]["status"] == "optimal"


def test_power_bad_documents(tmp_path: Path) -> None:
    with api_client(tmp_path, workers=1) as client:
        r = client.post("/v1/power-allocations", json=small_power_doc(sigma_m=-1))
        assert r.status_code == 422
        assert any(f["field"].endswith("prior.sigma_m") for f in r.json()["fields"])
        r = client.post(
            "/v1/power-allocations", json=small_power_doc(), params={"objective": "cost"}
        )
        assert r.status_code == 422 and r.json()["fields"][0]["location"] == "query"
        # the engine's refusal (no concrete beams) comes at submission, naming the field
        doc = preset_document("paper-table1") | {"codebook": {"kind": "expected_random"}}
        r = client.post("/v1/power-allocations", json=doc)
        assert r.status_code == 422 and "expected_random" in r.json()["message"]
        assert r.json()["fields"][0]["field"] == "codebook.kind"
        assert client.get("/v1/jobs").json()["total"] == 0


def test_solver_type_matches_engine() -> None:
    assert typing.get_args(Solver) == SOLVERS


def test_power_size_limits_are_413(tmp_path: Path) -> None:
    doc = preset_document("paper-table1")
    doc["tx"], doc["rx"] = [[-2.0, -4.0, 0.0]] * 6, [[2.0, 3.0, 0.0]] * 6
    with api_client(tmp_path, max_pairs=5) as client:
        r = client.post("/v1/power-allocations", json=doc)
        assert r.status_code == 413 and r.json()["limit"] == 5
        assert client.get("/v1/jobs").json()["total"] == 0  # nothing was queued
