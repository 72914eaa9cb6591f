"""Property-based run of the service against its own OpenAPI document (schemathesis): no
generated request may produce a 5xx, and every response must match its documented schema.

A bounded number of examples per operation keeps the run at a few seconds; the engine limits
are set low so that random valid documents stay cheap (the limits themselves are part of what
is exercised: large documents must answer 413, not 5xx)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import schemathesis
from hypothesis import HealthCheck, settings
from schemathesis.checks import not_a_server_error
from schemathesis.python.asgi import shutdown_lifespans
from schemathesis.specs.openapi.checks import response_schema_conformance

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
)
app = create_app(LIMITS)
# from the app's OpenAPI document, calling the app in-process; schemathesis starts the app's
# lifespan at the first call (after the fixture below has pointed it at a temporary DB)
schema = schemathesis.openapi.from_dict(app.openapi())
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
def test_no_server_errors(case: Any) -> None:
    response = case.call()
    case.validate_response(response, checks=[not_a_server_error, response_schema_conformance])
