"""``POST /v1/cities``: a city planned as one map (``ris-planner city``) as a job.

The body is ``{"document": <plan document of the whole city>, "cell_m": <cell size [m]>}``,
read here (not declared to FastAPI) so that a document with a geographic ``frame`` is
converted to local metres first; parsing, conversion, the split into cells and every cell's
admission run in a parse process (:mod:`api.offload`), never in the server's.
"""

from __future__ import annotations

import json
from typing import Annotated, Any

import anyio
from fastapi import APIRouter, Depends, Request
from fastapi.responses import Response
from pydantic import Field

from api.auth import Principal
from api.deps import get_principal, get_runner, get_settings, get_store
from api.documents import json_document
from api.errors import GIS_EXTRA_RESPONSE, TOO_LARGE_RESPONSE
from api.models import JobView, plan_examples
from api.offload import ParsePool
from api.routes.jobs import CONFLICT_RESPONSE, JOB_LINKS, IdempotencyKey, submit_job
from api.settings import Settings
from api.store import JobStore, JsonText
from api.worker import JobRunner
from ris_planner.core.document import DocumentModel

router = APIRouter(tags=["jobs"])

MAX_CELL_M = 100_000.0
"""The largest cell side [m] a city job takes."""


class CityBody(DocumentModel):
    """The body of ``POST /v1/cities``."""

    document: dict[str, Any] = Field(
        description="The plan document of the whole city (local metres or with a geographic"
        " frame): sidelink pairs (pairs.max_separation_m) or explicit pairs"
    )
    cell_m: float = Field(gt=0, le=MAX_CELL_M, description="Cell side [m]")


def _city_examples() -> dict[str, Any]:
    """OpenAPI example of a city body: the Fig. 10 anchor sites over a 6 m × 6 m grid of UEs,
    sidelink pairs at most 3 m apart, cells of 4 m (four cells, one RIS each)."""
    anchors = plan_examples()["fig10"]["value"]["candidates"]
    grid = {"grid": {"x": [-3, 3, 1], "y": [-3, 3, 1], "z": [0, 0, 1]}}
    doc = {
        "ris": {"rows": 10, "cols": 10},
        "candidates": anchors,
        "tx_map": grid,
        "rx_map": grid,
        "pairs": {"sample": 200, "seed": 1, "max_separation_m": 3},
        "objective": {"kind": "coverage", "metric": "rx", "threshold_m": 1.0},
        "ris_count": [4],
    }
    return {
        "fig10": {"summary": "Fig. 10 sites as a city", "value": {"document": doc, "cell_m": 4}}
    }


CITY_BODY = {
    "requestBody": {
        "required": True,
        "description": "The city's plan document and the cell side; the document in local"
        ' metres or with a geographic "frame" (converted to local metres first)',
        "content": {
            "application/json": {
                "schema": {
                    "type": "object",
                    "additionalProperties": False,
                    "required": ["document", "cell_m"],
                    "properties": {
                        "document": {
                            "anyOf": [
                                {"$ref": "#/components/schemas/PlanDocument"},
                                {"$ref": "#/components/schemas/GeoDocument"},
                            ]
                        },
                        "cell_m": {
                            "type": "number",
                            "exclusiveMinimum": 0,
                            "maximum": MAX_CELL_M,
                            "description": "Cell side [m]",
                        },
                    },
                },
                "examples": _city_examples(),
            }
        },
    }
}


@router.post(
    "/cities",
    status_code=202,
    response_model=JobView,
    responses={**TOO_LARGE_RESPONSE, **GIS_EXTRA_RESPONSE, **JOB_LINKS, **CONFLICT_RESPONSE},
    summary="Start a city-planning job (ris-planner city)",
    openapi_extra=CITY_BODY,
)
async def post_city(
    request: Request,
    store: Annotated[JobStore, Depends(get_store)],
    runner: Annotated[JobRunner, Depends(get_runner)],
    settings: Annotated[Settings, Depends(get_settings)],
    principal: Annotated[Principal, Depends(get_principal)],
    idempotency_key: IdempotencyKey = None,
) -> Response:
    """202 with the queued job. Its result is the ``plan.json`` of ``ris-planner city``: the
    city's RIS counts, coverage and certified bound per count, its sites at city-level
    candidate indices, every cell's summary (``cells``), the pairs across cell borders
    (``city``); its files are ``geojson``, ``geotiff`` and ``points_csv`` over the whole city.
    The checks of ``ris-planner city`` run here before the job is queued: the document (422
    naming the field), the pairs drawn over the whole city, and every cell's document against
    the limits and the job memory budget (413 naming the cell and the limit)."""
    body = await request.body()
    pool: ParsePool = request.app.state.parse_pool
    stored = await pool.run(city_submission, body, settings.job_memory_mb)

    def submit() -> Response:
        return submit_job("city", stored, store, runner, principal, idempotency_key)

    return await anyio.to_thread.run_sync(submit)


def city_submission(body: bytes, memory_mb: int) -> JsonText:
    """A city body → the job's document as JSON text (the body as sent, validated): parsed,
    the document converted from its frame, split into cells and every cell admitted
    (:func:`ris_planner.io.cityplan.admit_city`). Runs in a parse process."""
    from ris_planner.io.cityplan import admit_city

    value = json_document(body)
    parsed = CityBody.model_validate(value)
    admit_city(parsed.document, parsed.cell_m, memory_mb)
    job = {"document": parsed.document, "cell_m": parsed.cell_m}
    return JsonText(json.dumps(job, allow_nan=False))
