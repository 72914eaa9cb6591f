"""The REST service's routes through FastAPI's TestClient: bounds (same numbers as the CLI),
presets, health, API key, and every error path (422 field paths, 413 limits, 404, 405, 500)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from api_helpers import api_client
from fastapi.testclient import TestClient
from tolerance import BOUND_ACCURACY, assert_close

from api.main import create_app
from api.settings import Settings
from ris_planner import preset_document
from ris_planner.cli import main as cli_main
from ris_planner.model.paper import fig10_pairs


def cli_bounds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], document: dict[str, object]
) -> object:
    f = tmp_path / "doc.json"
    f.write_text(json.dumps(document))
    assert cli_main(["bounds", str(f)]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize("preset", ["paper-table1", "3-ris"])
def test_bounds_equals_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str], preset: str) -> None:
    """The same document gives the same JSON, number for number, as `ris-planner bounds`."""
    doc = preset_document(preset)
    with api_client(tmp_path) as client:
        r = client.post("/v1/bounds", json=doc)
    assert r.status_code == 200
    # another process: the bounds to their accuracy contract, everything else exactly
    assert_close(r.json(), cli_bounds(tmp_path, capsys, doc), accuracy=BOUND_ACCURACY)


def test_bounds_batch_equals_cli_and_ue_on_ris_is_422(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    doc = preset_document("2-ris-L")
    tx, rx = fig10_pairs()
    doc["tx"] = [*tx[:40].tolist(), doc["ris"][0]["position"]]  # last pair: TX on RIS 1
    doc["rx"] = rx[:41].tolist()
    doc["known"] = ["clock"]
    with api_client(tmp_path) as client:
        r = client.post("/v1/bounds", json=doc)
    assert r.status_code == 422  # a UE on a RIS is rejected by the document's validation
    assert r.json()["fields"][0]["field"] == "(document)"
    doc["tx"] = tx[:41].tolist()
    with api_client(tmp_path) as client:
        got = client.post("/v1/bounds", json=doc).json()
    assert_close(got, cli_bounds(tmp_path, capsys, doc), accuracy=BOUND_ACCURACY)
    assert len(got["peb_rx_m"]) == 41 and got["ceb_m"] is None and got["ceb_reason"]


def test_bounds_validation_error_names_field_path(tmp_path: Path) -> None:
    doc = preset_document("paper-table1")
    doc["ris"][1]["position"] = [4, 0, "up"]
    doc["system"]["subcarriers"] = 0
    with api_client(tmp_path) as client:
        r = client.post("/v1/bounds", json=doc)
    assert r.status_code == 422
    body = r.json()
    assert body["error"] == "validation_error" and body["status"] == 422
    fields = {f["field"] for f in body["fields"]}
    assert fields == {"ris.1.position.2", "system.subcarriers"}
    assert all(f["location"] == "body" for f in body["fields"])
    assert "Traceback" not in r.text


@pytest.mark.parametrize("path", ["/v1/bounds", "/v1/plans", "/v1/power-allocations"])
def test_malformed_bodies_are_400(tmp_path: Path, path: str) -> None:
    """Text that is not JSON, or JSON nested deeper than any document, is a malformed request
    (400, listed in the OpenAPI document); valid JSON of the wrong shape is a 422."""
    headers = {"content-type": "application/json"}
    with api_client(tmp_path) as client:
        for content in (b"{not json", b"[" * 5000 + b"]" * 5000):
            r = client.post(path, content=content, headers=headers)
            assert r.status_code == 400 and r.json()["error"] == "bad_request", r.text
        ops = client.get("/openapi.json").json()["paths"][path]
        assert "400" in ops["post"]["responses"]


@pytest.mark.parametrize(
    ("content", "headers"),
    [
        (b"[1, 2]", {"content-type": "application/json"}),
        (b"", {"content-type": "application/json"}),
    ],
)
def test_bounds_unreadable_bodies_are_422(
    tmp_path: Path, content: bytes, headers: dict[str, str]
) -> None:
    with api_client(tmp_path) as client:
        r = client.post("/v1/bounds", content=content, headers=headers)
    assert r.status_code == 422 and r.json()["fields"]


def test_bounds_pair_limit_is_413_with_limit(tmp_path: Path) -> None:
    doc = preset_document("paper-table1")
    doc["tx"] = [[-2.0, -4.0, 0.0]] * 6
    doc["rx"] = [[2.0, 3.0, 0.0]] * 6
    with api_client(tmp_path, max_pairs=5) as client:
        r = client.post("/v1/bounds", json=doc)
        assert r.status_code == 413
        assert r.json()["limit"] == 5 and "6 TX–RX pairs" in r.json()["message"]
        doc["tx"], doc["rx"] = doc["tx"][:5], doc["rx"][:5]
        assert client.post("/v1/bounds", json=doc).status_code == 200


def test_bounds_work_limits_are_413(tmp_path: Path) -> None:
    """A document within the pair limit but with huge RISs/transmissions is refused before any
    engine work (G = 100000, 512×512 elements would need terabytes)."""
    doc = preset_document("paper-table1")
    doc["system"]["transmissions"] = 100000
    doc["ris"][0] |= {"rows": 512, "cols": 512}
    with api_client(tmp_path) as client:
        r = client.post("/v1/bounds", json=doc)
    assert r.status_code == 413 and r.json()["limit"] == Settings().max_array_elements
    doc = preset_document("paper-table1")
    doc["tx"], doc["rx"] = [[-2.0, -4.0, 0.0]] * 3, [[2.0, 3.0, 0.0]] * 3
    with api_client(tmp_path, max_work=3 * 64 * 100 * 3 * 2 - 1) as client:  # Σ 3·G̃·N·P - 1
        r = client.post("/v1/bounds", json=doc)
    assert r.status_code == 413 and "complex products" in r.json()["message"]


def test_body_size_limit_declared_and_streamed(tmp_path: Path) -> None:
    doc = preset_document("paper-table1")
    doc["description"] = "x" * 1500
    with api_client(tmp_path, max_body_bytes=1024) as client:
        r = client.post("/v1/bounds", json=doc)  # Content-Length over the limit
        assert r.status_code == 413 and r.json()["limit"] == 1024

        def chunks():  # type: ignore[no-untyped-def]
            body = json.dumps(doc).encode()
            for i in range(0, len(body), 256):
                yield body[i : i + 256]

        r = client.post(  # no Content-Length: counted as it streams in
            "/v1/bounds", content=chunks(), headers={"content-type": "application/json"}
        )
        assert r.status_code == 413 and r.json()["limit"] == 1024
        assert "1024 bytes" in r.json()["message"]
        r = client.post("/v1/bounds", content=b"{}", headers={"content-length": "ten"})
        assert r.status_code == 400


def test_presets_and_health(tmp_path: Path) -> None:
    with api_client(tmp_path, workers=3) as client:
        presets = client.get("/v1/presets").json()
        names = [p["name"] for p in presets["scenarios"]]
        assert names == ["paper-table1", "2-ris-L", "2-ris-P", "3-ris", "4-ris"]
        assert presets["scenarios"][0]["document"] == preset_document("paper-table1")
        health = client.get("/healthz")
        assert health.status_code == 200
        body = health.json()
        assert body["status"] == "ok" and body["workers"] == 3 and body["running"] == 0
        assert body["jobs"] == dict.fromkeys(
            ["queued", "running", "succeeded", "failed", "cancelled"], 0
        )


def test_api_key_guards_v1_but_not_healthz(tmp_path: Path) -> None:
    doc = preset_document("paper-table1")
    with api_client(tmp_path, api_key="s3cret-key") as client:
        assert client.get("/healthz").status_code == 200
        for method, path in [("GET", "/v1/presets"), ("GET", "/v1/jobs"), ("POST", "/v1/bounds")]:
            r = client.request(method, path, json=doc if method == "POST" else None)
            assert r.status_code == 401, path
            assert r.json()["error"] == "unauthorized" and "X-API-Key" in r.json()["message"]
        wrong = client.get("/v1/presets", headers={"X-API-Key": "s3cret-kez"})
        assert wrong.status_code == 401
        assert client.get("/v1/presets", headers={"X-API-Key": "s3cret-key"}).status_code == 200
        ok = client.post("/v1/bounds", json=doc, headers={"X-API-Key": "s3cret-key"})
        assert ok.status_code == 200
        assert "X-API-Key" in json.dumps(client.get("/openapi.json").json()["components"])


def test_unknown_job_routes_and_methods(tmp_path: Path) -> None:
    with api_client(tmp_path) as client:
        missing = "0" * 32
        for method, path in [
            ("GET", f"/v1/jobs/{missing}"),
            ("DELETE", f"/v1/jobs/{missing}"),
            ("POST", f"/v1/jobs/{missing}/cancel"),
            ("GET", f"/v1/jobs/{missing}/figures/topview"),
        ]:
            r = client.request(method, path)
            assert r.status_code == 404 and r.json()["error"] == "not_found", path
        r = client.get("/v1/jobs/not-a-job-id")
        assert r.status_code == 422 and r.json()["fields"][0]["location"] == "path"
        assert client.get("/v1/nothing").status_code == 404
        r = client.put("/v1/bounds", json={})
        assert r.status_code == 405 and r.json()["error"] == "method_not_allowed"


def test_unexpected_error_is_json_500_without_traceback(tmp_path: Path) -> None:
    app = create_app(Settings(db=tmp_path / "j.db"))

    def broken() -> None:
        raise KeyError("internal detail")

    app.add_api_route("/v1/broken", broken)
    with TestClient(app, raise_server_exceptions=False) as client:
        r = client.get("/v1/broken")
    assert r.status_code == 500
    body = r.json()
    assert body["error"] == "internal_error" and "id " in body["message"]
    assert "Traceback" not in r.text and "internal detail" not in r.text


def test_openapi_documents_every_field(tmp_path: Path) -> None:
    """Every property of every schema in the OpenAPI document has a description."""
    with api_client(tmp_path) as client:
        spec = client.get("/openapi.json").json()
        assert client.get("/docs").status_code == 200
    missing = []
    for name, schema in spec["components"]["schemas"].items():
        for prop, sub in schema.get("properties", {}).items():
            if "description" not in sub:
                missing.append(f"{name}.{prop}")
    assert missing == []
    assert "HTTPValidationError" not in spec["components"]["schemas"]  # 422s are ErrorBody
    for path, ops in spec["paths"].items():
        for op in ops.values():
            for param in op.get("parameters", []):
                assert param.get("description"), (path, param["name"])


def test_engine_value_error_is_422(tmp_path: Path) -> None:
    """G = 1 transmission cannot hold L + 1 = 2 orthogonal blocks: the engine's ValueError is a
    422 naming the rule (found by the schemathesis run, formerly a 500)."""
    doc = {
        "ris": [{"position": [0.0, 0.0, 1.0]}],
        "tx": [0.0, 0.0, 0.0],
        "rx": [1.0, 0.0, 0.0],
        "system": {"transmissions": 1, "los": False},
    }
    with api_client(tmp_path) as client:
        r = client.post("/v1/bounds", json=doc)
    assert r.status_code == 422 and "G ≥ L+1" in r.json()["message"]


def test_health_reports_database_failure_as_503(tmp_path: Path) -> None:
    with api_client(tmp_path) as client:
        client.app.state.store.path = tmp_path  # a folder: SQLite cannot open it
        r = client.get("/healthz")
    body = r.json()
    assert r.status_code == 503 and body["status"] == "unavailable"
    assert body["reason"].startswith("the job database does not answer")


def test_settings_from_environment_and_bad_values(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setenv("RIS_PLANNER_DB", "/tmp/x/jobs.db")
    monkeypatch.setenv("RIS_PLANNER_MAX_PAIRS", "7")
    monkeypatch.setenv("RIS_PLANNER_API_KEY", "zebra-secret")
    s = Settings()
    assert (str(s.db), s.max_pairs, s.workers) == ("/tmp/x/jobs.db", 7, 2)
    assert s.figures_dir == Path("/tmp/x/jobs.db.data") and s.api_key is not None
    assert "zebra" not in repr(s)  # the key is a secret
    monkeypatch.setenv("RIS_PLANNER_WORKERS", "0")
    assert cli_main(["serve"]) == 2  # refused before any server starts
    assert "workers" in capsys.readouterr().err
