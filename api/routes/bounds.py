"""``POST /v1/bounds``: PEB_T, PEB_R, CEB and channel bounds of a scenario, synchronously."""

from __future__ import annotations

from typing import Annotated, Any

import anyio
from fastapi import APIRouter, Body, Depends, Request
from fastapi.responses import JSONResponse

from api.deps import get_settings
from api.errors import TOO_LARGE_RESPONSE
from api.limits import check_scenario_size
from api.models import BoundsResponse, scenario_examples
from api.settings import Settings
from ris_planner.bounds import compute_bounds
from ris_planner.scenario import Scenario

router = APIRouter(tags=["bounds"])


@router.post(
    "/bounds",
    response_model=BoundsResponse,
    responses=TOO_LARGE_RESPONSE,
    summary="Bounds of one TX–RX pair or a batch of pairs",
)
async def post_bounds(
    request: Request,
    scenario: Annotated[
        Scenario,
        Body(
            description="The scenario document (DESIGN.md)",
            openapi_examples=scenario_examples(),
        ),
    ],
    settings: Annotated[Settings, Depends(get_settings)],
) -> JSONResponse:
    """The same computation and document as ``ris-planner bounds``; 413 when the batch exceeds
    the configured pair or work limits. Runs in a worker thread (at most
    ``bounds_concurrency`` at once), never in the event loop."""
    check_scenario_size(scenario, settings)
    limiter: anyio.CapacityLimiter = request.app.state.bounds_limiter
    answer = await anyio.to_thread.run_sync(_bounds_json, scenario, limiter=limiter)
    return JSONResponse(answer)


def _bounds_json(scenario: Scenario) -> dict[str, Any]:
    return compute_bounds(scenario).to_json(batch=scenario.is_batch)
