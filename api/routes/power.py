"""``POST /v1/power-allocations``: beam power allocation (uniform, γ_P, SDP) as a job."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body, Depends, Query
from fastapi.responses import JSONResponse

from api.deps import get_runner, get_settings, get_store
from api.errors import TOO_LARGE_RESPONSE
from api.limits import check_scenario_size
from api.models import JobView, power_examples
from api.routes.jobs import JOB_LINKS, submit_job
from api.settings import Settings
from api.store import JobStore
from api.worker import JobRunner
from ris_planner.power.options import Objective, Solver
from ris_planner.scenario import Scenario
from ris_planner.validation import power_check

router = APIRouter(tags=["jobs"])


@router.post(
    "/power-allocations",
    status_code=202,
    response_model=JobView,
    responses={**TOO_LARGE_RESPONSE, **JOB_LINKS},
    summary="Start a power-allocation job (ris-planner power)",
)
def post_power(
    scenario: Annotated[
        Scenario,
        Body(
            description="The scenario document; its codebook gives the beams (not expected_random)",
            openapi_examples=power_examples(),
        ),
    ],
    store: Annotated[JobStore, Depends(get_store)],
    runner: Annotated[JobRunner, Depends(get_runner)],
    settings: Annotated[Settings, Depends(get_settings)],
    objective: Annotated[
        Objective,
        Query(description="Minimise the mean PEB_R² (rx), PEB_T² (tx) or their sum [m²]"),
    ] = "rx",
    solver: Annotated[Solver, Query(description="SDP solver (cvxpy)")] = "CLARABEL",
) -> JSONResponse:
    """202 with the queued job; its result is the JSON of ``ris-planner power`` (uniform power,
    the best γ_P for DIR+DER codebooks, the SDP allocation, each objective re-evaluated by the
    bounds code). The checks of ``ris-planner power`` run here (422 naming the field, 413 naming
    the limit); engine or solver failures end the job as failed with a message."""
    check_scenario_size(scenario, settings)
    power_check(scenario, objective, settings.job_memory_mb)  # ris-planner power's checks
    document = {
        "scenario": scenario.model_dump(mode="json"),
        "objective": objective,
        "solver": solver,
    }
    return submit_job("power", document, store, runner)
