"""``POST /v1/bounds``: PEB_T, PEB_R, CEB and channel bounds of a scenario, synchronously.

The body is read on the event loop; a large one is parsed and validated in a worker thread
with the computation (a 10 MB batch takes a while to validate; ``/healthz`` keeps answering
meanwhile).
A request without a query string is answered by :class:`api.front.FrontMiddleware`'s fast path
with this module's functions – a small one (body ≤ 64 KiB, work ≤ ``bounds_inline_work``) on the
event loop itself, where a worker thread's hand-off cost more than its millisecond of work –;
the route answers the others and lists the operation in the OpenAPI document.
"""

from __future__ import annotations

import anyio
from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse

from api.documents import document_body, json_document
from api.errors import GIS_EXTRA_RESPONSE, TOO_LARGE_RESPONSE
from api.models import BoundsResponse, scenario_examples
from api.settings import Settings
from ris_planner.bounds.compute import bounds_document
from ris_planner.bounds.resources import check_scenario_size
from ris_planner.io.frames import to_local
from ris_planner.model.scenario import Scenario

router = APIRouter(tags=["bounds"])

SCENARIO_BODY = document_body(
    "Scenario",
    'The scenario document, in local metres or with a geographic "frame" (WGS84'
    " lon/lat or a projected CRS; converted to local metres first)",
    scenario_examples(),
)
"""The body's OpenAPI entry (the route reads the body itself, off the event loop)."""


@router.post(
    "/bounds",
    response_model=BoundsResponse,
    responses={**TOO_LARGE_RESPONSE, **GIS_EXTRA_RESPONSE},
    summary="Bounds of one TX–RX pair or a batch of pairs",
    openapi_extra=SCENARIO_BODY,
)
async def post_bounds(request: Request) -> JSONResponse:
    """The same computation and document as ``ris-planner bounds``; 413 when the batch exceeds
    the configured pair or work limits. Parsing, validation, the computation and the answer's
    JSON run in a worker thread (at most ``bounds_concurrency`` at once), never in the event
    loop."""
    body = await request.body()
    settings: Settings = request.app.state.settings  # (no dependency to solve per request)
    limiter: anyio.CapacityLimiter = request.app.state.bounds_limiter
    return await anyio.to_thread.run_sync(bounds_answer, body, settings, limiter=limiter)


def bounds_answer(body: bytes, settings: Settings) -> JSONResponse:
    """The answer, rendered here (the JSON text of a batch is not the event loop's work); also
    the fast path's (:class:`api.front.FrontMiddleware`)."""
    return scenario_answer(bounds_scenario(body, settings))


def bounds_scenario(body: bytes, settings: Settings) -> Scenario:
    """Parse (400 for text that is not JSON), convert from a frame, validate (422), check the
    size (413)."""
    local, _ = to_local(json_document(body))
    scenario = Scenario.model_validate(local)
    check_scenario_size(scenario, settings.request_limits)
    return scenario


def scenario_answer(scenario: Scenario) -> JSONResponse:
    """Compute and render the answer of a checked scenario."""
    return JSONResponse(bounds_document(scenario))
