"""``POST /v1/power-allocations``: beam power allocation (uniform, γ_P, SDP) as a job."""

from __future__ import annotations

import json
from typing import Annotated, Any

import anyio
from fastapi import APIRouter, Depends, Query, Request
from fastapi.responses import Response
from pydantic import Discriminator, Tag, TypeAdapter

from api.auth import Principal
from api.deps import get_principal, get_runner, get_settings, get_store
from api.documents import document_body, json_document
from api.errors import GIS_EXTRA_RESPONSE, TOO_LARGE_RESPONSE
from api.models import JobView, power_examples
from api.offload import ParsePool
from api.routes.jobs import CONFLICT_RESPONSE, JOB_LINKS, IdempotencyKey, submit_job
from api.settings import Settings
from api.store import JobStore, JsonText
from api.worker import JobRunner
from ris_planner.bounds.resources import check_scenario_size
from ris_planner.io.frames import to_local
from ris_planner.model.plan import LayoutBeamsDocument
from ris_planner.model.power import Objective, Solver
from ris_planner.model.scenario import Scenario
from ris_planner.planning.resources.admission import check_layout_beams_size
from ris_planner.power.resources import power_check

router = APIRouter(tags=["jobs"])


def _document_kind(value: Any) -> str:
    """``layout`` for a layout + UE-map document (it has ``tx_map``), else ``scenario``."""
    if isinstance(value, dict):
        return "layout" if "tx_map" in value or "rx_map" in value else "scenario"
    return "layout" if isinstance(value, LayoutBeamsDocument) else "scenario"


PowerDocument = Annotated[
    Annotated[Scenario, Tag("scenario")] | Annotated[LayoutBeamsDocument, Tag("layout")],
    Discriminator(_document_kind),
]


POWER_ADAPTER: TypeAdapter[Scenario | LayoutBeamsDocument] = TypeAdapter(PowerDocument)

POWER_BODY = document_body(
    ("Scenario", "LayoutBeamsDocument"),
    "A scenario document (its codebook gives the beams, not expected_random), or a layout + UE"
    " maps document (`ris`, `tx_map`, `rx_map`, `objective`, `beams`): beams designed from the"
    " maps, each design re-evaluated on the maps' pairs; in local metres or with a geographic"
    ' "frame" (converted to local metres first)',
    power_examples(),
)


@router.post(
    "/power-allocations",
    status_code=202,
    response_model=JobView,
    responses={**TOO_LARGE_RESPONSE, **GIS_EXTRA_RESPONSE, **JOB_LINKS, **CONFLICT_RESPONSE},
    summary="Start a power-allocation job (ris-planner power)",
    openapi_extra=POWER_BODY,
)
async def post_power(
    request: Request,
    store: Annotated[JobStore, Depends(get_store)],
    runner: Annotated[JobRunner, Depends(get_runner)],
    settings: Annotated[Settings, Depends(get_settings)],
    principal: Annotated[Principal, Depends(get_principal)],
    objective: Annotated[
        Objective,
        Query(description="Minimise the mean PEB_R² (rx), PEB_T² (tx) or their sum [m²]"),
    ] = "rx",
    solver: Annotated[Solver, Query(description="SDP solver (cvxpy)")] = "CLARABEL",
    idempotency_key: IdempotencyKey = None,
) -> Response:
    """202 with the queued job; its result is the JSON of ``ris-planner power`` (uniform power,
    the best γ_P for DIR+DER codebooks, the SDP allocation, each objective re-evaluated by the
    bounds code), or for a layout + UE maps document the beam report of
    ``ris_planner.planning.beams.run_layout_beams`` (``objective`` and ``solver`` come
    from the document then). The checks of ``ris-planner power`` run here, on the document
    converted from its frame (422 naming the field, 413 naming the limit, 501 for a frame
    without the GIS extra); engine or solver failures end the job as failed with a message.
    The job keeps a geographic document as sent."""
    body = await request.body()
    pool: ParsePool = request.app.state.parse_pool
    stored = await pool.run(power_submission, body, settings, objective, solver)

    def submit() -> Response:
        return submit_job("power", stored, store, runner, principal, idempotency_key)

    return await anyio.to_thread.run_sync(submit)


def power_submission(
    body: bytes, settings: Settings, objective: Objective, solver: Solver
) -> JsonText:
    """A power body → the job's document as JSON text: parsed, converted from its frame,
    validated and checked as ``ris-planner power`` (a parse process runs it, :mod:`api.offload`;
    a geographic document is kept as sent)."""
    document = json_document(body)
    local, frame = to_local(document)
    parsed = POWER_ADAPTER.validate_python(local)
    job: dict[str, Any]
    if isinstance(parsed, LayoutBeamsDocument):
        check_layout_beams_size(parsed, settings.request_limits)
        job = {"layout": document if frame is not None else parsed.model_dump(mode="json")}
    else:
        check_scenario_size(parsed, settings.request_limits)
        power_check(parsed, objective, settings.job_memory_mb)  # ris-planner power's checks
        job = {
            "scenario": document if frame is not None else parsed.model_dump(mode="json"),
            "objective": objective,
            "solver": solver,
        }
    return JsonText(json.dumps(job, allow_nan=False))
