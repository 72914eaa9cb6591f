"""Property-based run of the service against its own OpenAPI document (schemathesis), with
every check schemathesis has: no 5xx, status codes, content types, headers and bodies as
documented, data the schema forbids refused (negative data, missing headers, unsupported
methods), data it admits accepted (positive data) – the last except on the routes that take a
document, whose semantic rules (a CRS that exists, geometry, sizes against limits) a JSON Schema
cannot state: there a 413/422 for admitted data is expected, and the exact string and number
constraints the server enforces before those rules (frame.crs, the DXF layer choices, ...) are
checked by ``test_schema_states_the_string_rules`` below.

A bounded number of examples per operation keeps the run at a few seconds; the engine limits
are set low so that random valid documents stay cheap (the limits themselves are part of what
is exercised: large documents must answer 413, not 5xx)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import schemathesis
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, settings
from schemathesis.config import SchemathesisConfig
from schemathesis.config._checks import NEGATIVE_DATA_REJECTION_EXPECTED_STATUSES
from schemathesis.python.asgi import shutdown_lifespans
from schemathesis.specs.openapi.checks import positive_data_acceptance

from api.main import create_app
from api.settings import Settings

EXAMPLES_PER_OPERATION = 25

LIMITS = Settings(
    db=Path("set-by-the-fixture.db"),
    workers=1,
    max_pairs=50,
    max_array_elements=200_000,
    max_work=2_000_000,
    max_body_bytes=200_000,
    api_key="schemathesis-key",  # the schema declares the key: the server must enforce it
)
AUTH = {"X-API-Key": "schemathesis-key"}
app = create_app(LIMITS)
# from the app's OpenAPI document, calling the app in-process; schemathesis starts the app's
# lifespan at the first call (after the fixture below has pointed it at a temporary DB)
CONFIG = SchemathesisConfig.from_dict(
    {  # 413 is the service's refusal of a list above its maxItems (checked before validation)
        "checks": {
            "negative_data_rejection": {
                "expected-statuses": [*NEGATIVE_DATA_REJECTION_EXPECTED_STATUSES, "413"]
            }
        }
    }
)
for dxf in ("application/dxf", "image/vnd.dxf", "image/x-dxf"):  # the import's DXF bodies: bytes
    schemathesis.serializer.alias(dxf, "application/octet-stream")
schema = schemathesis.openapi.from_dict(app.openapi(), config=CONFIG)
schema.app = app


@pytest.fixture(scope="module", autouse=True)
def temporary_database(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    db = tmp_path_factory.mktemp("schemathesis") / "jobs.db"
    app.state.settings = LIMITS.model_copy(update={"db": db})
    yield
    shutdown_lifespans()  # stops the job runner (worker processes) started by schemathesis


@schema.parametrize()
@settings(
    max_examples=EXAMPLES_PER_OPERATION,
    derandomize=True,  # the same examples in every run (CI); False explores new ones
    deadline=None,
    suppress_health_check=list(HealthCheck),
)
def test_all_checks(case: Any) -> None:
    # the key where the generated case has none, unless leaving it out is the case's point
    negative_headers = any(
        str(loc).lower().endswith("header") and not info.mode.is_positive
        for loc, info in (case.meta.components.items() if case.meta else ())
    )
    auth = {} if negative_headers or "X-API-Key" in (case.headers or {}) else AUTH
    response = case.call(headers=auth)
    semantic = case.body is not None or case.path == "/v1/import"  # see the module docstring
    excluded = [positive_data_acceptance] if semantic else []
    case.validate_response(response, excluded_checks=excluded, headers=auth)


def test_schema_states_the_string_rules(tmp_path: Path) -> None:
    """What the schema refuses, the server refuses (and the other way round) for the strings
    Schemathesis found out of step: a blank CRS, an empty DXF layer choice."""
    spec = app.openapi()
    crs = spec["components"]["schemas"]["CrsFrame"]["properties"]["crs"]
    assert crs["minLength"] == 1 and crs["pattern"] == r"\S"
    layer = next(
        p for p in spec["paths"]["/v1/import"]["post"]["parameters"] if p["name"] == "layer"
    )
    item = layer["schema"]["anyOf"][0]["items"]
    assert item["minLength"] >= 1 and item["pattern"].startswith("^[^=]+=")
    local = create_app(LIMITS.model_copy(update={"db": tmp_path / "jobs.db"}))
    with TestClient(local, raise_server_exceptions=False) as client:
        for route in ("/v1/bounds", "/v1/plans", "/v1/plans/validate", "/v1/power-allocations"):
            for frame in ({"crs": ""}, {"crs": "  "}, {"origin": [0, 89]}, {"origin": [200, 0]}):
                r = client.post(route, json={"frame": frame}, headers=AUTH)
                assert r.status_code == 422, (route, frame, r.text)
        for spec_text in ("", "=wall:3", "a=wall:0", "a=roof:3", "a=prism:3:-1", "a=wall:1e3"):
            r = client.post(
                "/v1/import?format=dxf",
                params={"layer": spec_text},
                content=b"0",
                headers=AUTH | {"Content-Type": "application/octet-stream"},
            )
            assert r.status_code == 422, (spec_text, r.text)
            assert r.json()["fields"][0]["location"] == "query", r.text
