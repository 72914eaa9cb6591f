"""``POST /v1/plans``: RIS placement search and RIS-count comparison as a job.

The body is read here (not declared to FastAPI) so that a document with a geographic
``frame`` is converted to local metres before validation (:mod:`api.documents`); parsing,
conversion and validation run in a parse process (:mod:`api.offload`), never in the server's.
"""

from __future__ import annotations

import json
from typing import Annotated

import anyio
from fastapi import APIRouter, Depends, Request
from fastapi.responses import Response

from api.auth import Principal
from api.deps import get_principal, get_runner, get_settings, get_store
from api.documents import document_body, json_document, local_plan
from api.errors import GIS_EXTRA_RESPONSE, TOO_LARGE_RESPONSE
from api.models import JobView, plan_examples
from api.offload import ParsePool
from api.routes.jobs import CONFLICT_RESPONSE, JOB_LINKS, IdempotencyKey, submit_job
from api.settings import Settings
from api.store import JobStore, JsonText
from api.worker import JobRunner
from ris_planner.model.plan import PlanDocument

router = APIRouter(tags=["jobs"])

PLAN_BODY = document_body(
    "PlanDocument",
    "The plan document (UE maps inline: grid, points or csv_text), in local metres or with a"
    ' geographic "frame" (WGS84 lon/lat or a projected CRS; converted to local metres first)',
    plan_examples(),
)


@router.post(
    "/plans",
    status_code=202,
    response_model=JobView,
    responses={**TOO_LARGE_RESPONSE, **GIS_EXTRA_RESPONSE, **JOB_LINKS, **CONFLICT_RESPONSE},
    summary="Start a placement-planning job (ris-planner plan)",
    openapi_extra=PLAN_BODY,
)
async def post_plan(
    request: Request,
    store: Annotated[JobStore, Depends(get_store)],
    runner: Annotated[JobRunner, Depends(get_runner)],
    settings: Annotated[Settings, Depends(get_settings)],
    principal: Annotated[Principal, Depends(get_principal)],
    idempotency_key: IdempotencyKey = None,
) -> Response:
    """202 with the queued job. Its result is the ``plan.json`` of ``ris-planner plan`` (ranked
    layouts per RIS count, coverage and CDF figures of merit; ``frame`` for a geographic
    document) and its figures are ``topview``, ``heatmap`` and ``cdf`` (PNG) with the files
    ``geojson``, ``geotiff``, ``points_csv`` (WGS84 / the frame's CRS for a geographic
    document). The checks of ``ris-planner plan`` run here, on the document converted from its
    frame, before the job is queued
    (:func:`ris_planner.planning.resources.admission.plan_check`): 422 naming the field, 413
    naming the limit (sites, map points, pairs, sites × pairs, search layouts, the job memory
    budget), 501 for a frame on a server without the GIS extra. The job keeps the
    document as sent (a geographic one in its own coordinates). The job's ``estimate`` (its
    wall seconds and peak memory, estimated from the document before any work;
    :func:`ris_planner.planning.resources.time_estimate.plan_estimate`) is there from this answer
    on; the result's ``resources`` sets it beside what the run measured."""
    body = await request.body()
    pool: ParsePool = request.app.state.parse_pool
    stored, estimate = await pool.run(plan_submission, body, settings.job_memory_mb)

    def submit() -> Response:
        return submit_job("plan", stored, store, runner, principal, idempotency_key, estimate)

    return await anyio.to_thread.run_sync(submit)


def plan_submission(body: bytes, memory_mb: int) -> tuple[JsonText, dict[str, float | int]]:
    """A plan body → the document the job keeps, as JSON text, and its resource estimate:
    parsed, converted from its frame, validated and checked (:func:`api.documents.local_plan`);
    a geographic document is kept as sent, a local one with the RIS element fields it leaves
    unset still unset (plan.json ``physics.from``). Runs in a parse process
    (:mod:`api.offload`)."""
    document = json_document(body)
    request = local_plan(document, memory_mb)
    if request.frame is not None:
        stored = document
    else:  # the fields as sent (validated): what it leaves unset stays unset (physics.from)
        local = PlanDocument.model_validate(request.local)
        stored = local.model_dump(mode="json", exclude_unset=True)
    return JsonText(json.dumps(stored, allow_nan=False)), request.estimate.to_json()
