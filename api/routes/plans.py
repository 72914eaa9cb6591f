"""``POST /v1/plans``: RIS placement search and RIS-count comparison as a job."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body, Depends
from fastapi.responses import JSONResponse

from api.deps import get_runner, get_settings, get_store
from api.errors import TOO_LARGE_RESPONSE
from api.models import JobView, plan_examples
from api.routes.jobs import JOB_LINKS, submit_job
from api.settings import Settings
from api.store import JobStore
from api.worker import JobRunner
from ris_planner.planning import PlanDocument
from ris_planner.validation import plan_check

router = APIRouter(tags=["jobs"])


@router.post(
    "/plans",
    status_code=202,
    response_model=JobView,
    responses={**TOO_LARGE_RESPONSE, **JOB_LINKS},
    summary="Start a placement-planning job (ris-planner plan)",
)
def post_plan(
    document: Annotated[
        PlanDocument,
        Body(
            description="The plan document (UE maps inline: grid, points or csv_text)",
            openapi_examples=plan_examples(),
        ),
    ],
    store: Annotated[JobStore, Depends(get_store)],
    runner: Annotated[JobRunner, Depends(get_runner)],
    settings: Annotated[Settings, Depends(get_settings)],
) -> JSONResponse:
    """202 with the queued job. Its result is the ``plan.json`` of ``ris-planner plan`` (ranked
    layouts per RIS count, coverage and CDF figures of merit) and its figures are ``topview``,
    ``heatmap`` and ``cdf`` (PNG). The checks of ``ris-planner plan`` run here, before the job
    is queued (:func:`ris_planner.validation.plan_check`): 422 naming the field, 413 naming the
    limit (sites, map points, pairs, sites × pairs, search layouts, the job memory budget)."""
    plan_check(document, settings.job_memory_mb)
    return submit_job("plan", document.model_dump(mode="json"), store, runner)
