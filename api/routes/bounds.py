"""``POST /v1/bounds``: PEB_T, PEB_R, CEB and channel bounds of a scenario, synchronously.

The body is read on the event loop but parsed and validated in a worker thread with the
computation (a 10 MB batch takes a while to validate; ``/healthz`` keeps answering meanwhile).
"""

from __future__ import annotations

from typing import Annotated, Any

import anyio
from fastapi import APIRouter, Depends, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse

from api.deps import get_settings
from api.errors import TOO_LARGE_RESPONSE, MalformedBodyError
from api.limits import check_scenario_size
from api.models import BoundsResponse, scenario_examples
from api.settings import Settings
from ris_planner.bounds import compute_bounds
from ris_planner.errors import RisPlannerError
from ris_planner.io_json import parse_json
from ris_planner.scenario import Scenario

router = APIRouter(tags=["bounds"])

SCENARIO_BODY: dict[str, Any] = {
    "requestBody": {
        "required": True,
        "description": "The scenario document (DESIGN.md)",
        "content": {
            "application/json": {
                "schema": {"$ref": "#/components/schemas/Scenario"},
                "examples": scenario_examples(),
            }
        },
    }
}
"""The body's OpenAPI entry (the route reads the body itself, off the event loop)."""


@router.post(
    "/bounds",
    response_model=BoundsResponse,
    responses=TOO_LARGE_RESPONSE,
    summary="Bounds of one TX–RX pair or a batch of pairs",
    openapi_extra=SCENARIO_BODY,
)
async def post_bounds(
    request: Request, settings: Annotated[Settings, Depends(get_settings)]
) -> JSONResponse:
    """The same computation and document as ``ris-planner bounds``; 413 when the batch exceeds
    the configured pair or work limits. Parsing, validation and the computation run in a
    worker thread (at most ``bounds_concurrency`` at once), never in the event loop."""
    body = await request.body()
    limiter: anyio.CapacityLimiter = request.app.state.bounds_limiter
    answer = await anyio.to_thread.run_sync(_bounds_json, body, settings, limiter=limiter)
    return JSONResponse(answer)


def _bounds_json(body: bytes, settings: Settings) -> dict[str, Any]:
    """Parse (400 for text that is not JSON), validate (422), check the size (413), compute."""
    if not body.strip():
        raise RequestValidationError(
            [{"type": "missing", "loc": ("body",), "msg": "Field required"}]
        )
    try:
        document = parse_json(body, "request body")
    except RisPlannerError as exc:
        raise MalformedBodyError(str(exc)) from None
    scenario = Scenario.model_validate(document)
    check_scenario_size(scenario, settings)
    return compute_bounds(scenario).to_json(batch=scenario.is_batch)
