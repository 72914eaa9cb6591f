"""Service metadata: ``GET /healthz`` (no API key), ``GET /v1/presets``,
``GET /v1/objectives``, ``GET /v1/obstacle-kinds``, ``GET /v1/search-methods`` and
``GET /v1/plan-files``."""

from __future__ import annotations

import sqlite3
from importlib.metadata import version
from typing import Annotated, Any

import anyio
from fastapi import APIRouter, Depends, Request
from fastapi.responses import JSONResponse
from pydantic import BaseModel, Field

from api.deps import get_runner, get_settings, get_store
from api.models import Health, ObjectiveInfo, ObjectiveList, Preset, PresetList
from api.settings import Settings
from api.store import FaultKind, JobStore, StoreUnavailableError, fault_kind
from api.worker import JobRunner, describe_error
from ris_planner.environment.kinds import describe_kinds
from ris_planner.io.gis_outputs import PLAN_WRITERS
from ris_planner.model.objectives import objective_kind, objective_names
from ris_planner.model.plan import SearchSpec
from ris_planner.model.scenario import PRESET_NAMES, preset_document
from ris_planner.model.search_methods import AUTO, PLAN_OPTIONS, registered_methods
from ris_planner.planning import PLAN_PRESET_NAMES, plan_preset

health_router = APIRouter(tags=["service"])
router = APIRouter(tags=["service"])


@health_router.get(
    "/healthz",
    response_model=Health,
    responses={503: {"model": Health, "description": "The job database does not answer"}},
    summary="Liveness and queue state (no API key needed)",
)
async def healthz(
    request: Request,
    store: Annotated[JobStore, Depends(get_store)],
    runner: Annotated[JobRunner, Depends(get_runner)],
    settings: Annotated[Settings, Depends(get_settings)],
) -> JSONResponse:
    """``ok``; ``degraded`` (200) with the ``reason`` while a fault lasts and the service still
    answers (a locked database the store retries, a dispatcher error); 503 ``unavailable``
    while the job database does not answer or takes no writes (read-only, full, corrupt: one
    attempt each, no retries: the answer comes at once); ``fault`` names the storage fault's
    class while it lasts; ``ok`` again when the fault is over, ``last_fault`` keeping the last
    one for 5 minutes. Its work runs on its own threads (never queued behind request work), so
    it answers under load."""
    limiter: anyio.CapacityLimiter = request.app.state.health_limiter
    return await anyio.to_thread.run_sync(_health, store, runner, settings, limiter=limiter)


def _health(store: JobStore, runner: JobRunner, settings: Settings) -> JSONResponse:
    """The store asked for a read (the counts, one attempt) and for what its last write probe
    met (:meth:`api.store.JobStore.write_fault`). A read that fails is ``unavailable`` (503),
    a write that failed too; a fault of a call failing now (a lock the store retries) and the
    dispatcher's are ``degraded``. ``fault`` names the storage fault's class."""
    reasons: list[str] = []
    fault: FaultKind | None = None
    status, code = "ok", 200
    try:
        counts = store.counts(retry=False)
    except (sqlite3.Error, StoreUnavailableError) as exc:
        counts, status, code = {}, "unavailable", 503
        fault = fault_kind(exc, store.path)
        reasons.append(f"the job database does not answer: {fault} ({describe_error(exc)})")
    else:
        failed = store.write_fault()
        if failed is not None:
            fault = fault_kind(failed, store.path)
            status, code = "unavailable", 503
            reasons.append(f"the job database takes no writes: {fault} ({describe_error(failed)})")
    if fault is None and store.faults.current is not None:
        fault = store.faults.kind  # a call failing now (a retried lock, a write)
        if fault not in ("locked", "gone"):  # a write that no wait can help
            status, code = "unavailable", 503
    other = runner.health()
    if other is not None and other not in " ".join(reasons):
        reasons.append(other)
    if status == "ok" and reasons:
        status = "degraded"
    body = Health(
        status=status,
        reason="; ".join(reasons) or None,
        fault=fault,
        last_fault=runner.last_fault(),
        version=version("ris_planner"),
        workers=settings.workers,
        running=runner.running(),
        jobs=counts,
    )
    return JSONResponse(body.model_dump(mode="json"), status_code=code)


@router.get("/presets", response_model=PresetList, summary="Shipped preset documents")
def presets() -> PresetList:
    return PresetList(
        scenarios=[Preset(name=n, document=preset_document(n)) for n in PRESET_NAMES],
        plans=[Preset(name=n, document=plan_preset(n)) for n in PLAN_PRESET_NAMES],
    )


@router.get("/objectives", response_model=ObjectiveList, summary="Objective kinds a plan may use")
def objectives() -> ObjectiveList:
    """The registered objective kinds (the web page's list; docs/concepts/scoring.md)."""
    return ObjectiveList(
        objectives=[ObjectiveInfo(**objective_kind(n).describe()) for n in objective_names()]
    )


class ObstacleKindInfo(BaseModel):
    """A registered obstacle kind (``environment.obstacles[].kind``) as the web page draws it."""

    kind: str = Field(description="The kind's JSON name")
    solid: bool = Field(description="Points can lie inside it (candidates inside are refused)")
    draw: dict[str, Any] = Field(
        description="How to draw one: shape polygon / polyline (points: a field of [x, y]"
        " points, or a list of fields each one point) or circle (center: a field of one point,"
        " radius: a field in metres)"
    )


class ObstacleKindList(BaseModel):
    """The obstacle kinds this service reads."""

    kinds: list[ObstacleKindInfo] = Field(description="Registered kinds, in order")


@router.get(
    "/obstacle-kinds", response_model=ObstacleKindList, summary="Obstacle kinds and their drawing"
)
def obstacle_kinds() -> ObstacleKindList:
    """The registered obstacle kinds with the drawing the web page makes of each
    (:func:`ris_planner.environment.kinds.describe_kinds`;
    docs/guides/adding-an-obstacle-kind.md)."""
    return ObstacleKindList(kinds=[ObstacleKindInfo(**k) for k in describe_kinds()])


class SearchMethodInfo(BaseModel):
    """A search method (``search.method``): what it does and its capabilities."""

    name: str = Field(description="The method's JSON name")
    label: str = Field(description="Short human name")
    description: str = Field(description="What it does and when to use it")
    capabilities: dict[str, Any] = Field(
        description="objectives (any | coverage), pair_models, wavefronts, options it honours"
        " (names of 'options'), search_fields it reads, max_ris, scoring (site_cache | sparse)"
    )
    docs: str = Field(description="The documentation page that explains it")


class PlanOptionInfo(BaseModel):
    """A document option a method may honour (a document asking a method for one it does not
    honour is refused with 422, naming the method and the option)."""

    name: str = Field(description="The capability table's name")
    field: str = Field(description="The document field that sets it")
    flag: str | None = Field(description="The ris-planner plan flag that sets it, if any")
    what: str = Field(description="What it asks for")


class SearchMethodList(BaseModel):
    """The search methods this service runs."""

    auto: SearchMethodInfo = Field(description="auto: the rule that picks a method")
    methods: list[SearchMethodInfo] = Field(description="Registered methods, in order")
    options: list[PlanOptionInfo] = Field(description="The options of the capability table")


@router.get(
    "/search-methods",
    response_model=SearchMethodList,
    summary="Search methods and what each honours",
)
def search_methods() -> SearchMethodList:
    """The registered search methods with their capabilities
    (:mod:`ris_planner.model.search_methods`; docs/concepts/planning.md, "Search methods"): the
    web page lists the methods and the options each honours from it."""
    auto = SearchMethodInfo(
        name=AUTO,
        label="auto",
        description=SearchSpec.model_fields["method"].description or "",
        capabilities={},
        docs="docs/concepts/planning.md",
    )
    return SearchMethodList(
        auto=auto,
        methods=[SearchMethodInfo(**m.to_json()) for m in registered_methods()],
        options=[
            PlanOptionInfo(name=o.name, field=o.field, flag=o.flag, what=o.what)
            for o in PLAN_OPTIONS
        ],
    )


class PlanFileInfo(BaseModel):
    """A GIS file a plan job writes (a job file: ``GET /v1/jobs/{id}/files/{name}``)."""

    name: str = Field(description="The job file's name")
    filename: str = Field(description="The file ris-planner plan writes into its folder")
    media_type: str = Field(description="Its media type")
    description: str = Field(description="What it holds")
    per_point: bool = Field(description="Written only when the plan has per-point results")


class PlanFileList(BaseModel):
    """The GIS files of a plan, in the order they are written."""

    files: list[PlanFileInfo] = Field(description="The writers' registry")


@router.get("/plan-files", response_model=PlanFileList, summary="The GIS files a plan writes")
def plan_files() -> PlanFileList:
    """The plan writers' registry (:data:`ris_planner.io.gis_outputs.PLAN_WRITERS`): what the
    command line writes, the job's files and their media types – the web page's download list
    reads it."""
    return PlanFileList(
        files=[
            PlanFileInfo(
                name=w.name,
                filename=w.filename,
                media_type=w.media_type,
                description=w.description,
                per_point=w.per_point,
            )
            for w in PLAN_WRITERS
        ]
    )
