"""Jobs: listing, status and result, cancellation, figures; and the submit helper that the job
kinds' POST routes share."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

from fastapi import APIRouter, Depends, Query
from fastapi import Path as PathParam
from fastapi.responses import FileResponse, JSONResponse

from api.deps import get_runner, get_settings, get_store
from api.errors import ErrorBody, JobConflictError, JobNotFoundError
from api.models import JobPage, JobSummary, JobView
from api.settings import Settings
from api.store import Job, JobStatus, JobStore
from api.worker import JobRunner

router = APIRouter(prefix="/jobs", tags=["jobs"])

JobId = Annotated[
    str, PathParam(description="Job id as returned on submission", pattern="^[0-9a-f]{32}$")
]
MEDIA_TYPES = {
    ".png": "image/png",
    ".geojson": "application/geo+json",
    ".tif": "image/tiff",
    ".csv": "text/csv",
}
"""Media type of a job file by suffix (PNG figures; the plan's GIS files)."""
NOT_FOUND: dict[int | str, dict[str, Any]] = {
    404: {"model": ErrorBody, "description": "No such job"}
}


JOB_LINKS: dict[int | str, dict[str, Any]] = {
    202: {
        "description": "The queued job; its URL is in the Location header",
        "links": {
            "GetJob": {
                "operationId": "get_job_v1_jobs__job_id__get",
                "parameters": {"job_id": "$response.body#/id"},
                "description": "Status and result of the job",
            },
            "CancelJob": {
                "operationId": "cancel_job_v1_jobs__job_id__delete",
                "parameters": {"job_id": "$response.body#/id"},
                "description": "Cancel the job",
            },
        },
    }
}
"""OpenAPI links of a 202 job answer (clients and stateful testers follow them)."""


def submit_job(
    kind: str, document: dict[str, Any], store: JobStore, runner: JobRunner
) -> JSONResponse:
    """Store a queued job, hand it to the runner, answer 202 with its view and Location."""
    job = store.create(kind, document)
    runner.submit(job.id, kind)
    view = JobView.of(job)
    return JSONResponse(
        view.model_dump(mode="json"), status_code=202, headers={"Location": view.url}
    )


def _job(store: JobStore, job_id: str) -> Job:
    job = store.get(job_id)
    if job is None:
        raise JobNotFoundError(f"no job with id {job_id}")
    return job


@router.get("", response_model=JobPage, summary="List jobs, newest first (paged)")
def list_jobs(
    store: Annotated[JobStore, Depends(get_store)],
    limit: Annotated[int, Query(ge=1, le=200, description="Page size (1–200)")] = 50,
    offset: Annotated[int, Query(ge=0, le=10**9, description="Jobs to skip")] = 0,
    status: Annotated[JobStatus | None, Query(description="Only jobs with this status")] = None,
    kind: Annotated[str | None, Query(max_length=40, description="Only jobs of this kind")] = None,
) -> JobPage:
    jobs, total = store.list_jobs(limit=limit, offset=offset, status=status, kind=kind)
    nxt = offset + len(jobs)
    return JobPage(
        items=[JobSummary.of_head(j) for j in jobs],
        total=total,
        limit=limit,
        offset=offset,
        next_offset=nxt if nxt < total else None,
    )


@router.get(
    "/{job_id}", response_model=JobView, responses=NOT_FOUND, summary="Job status and result"
)
def get_job(job_id: JobId, store: Annotated[JobStore, Depends(get_store)]) -> JobView:
    """Status, progress (0–1) and, when finished, the result or the error."""
    return JobView.of(_job(store, job_id))


@router.delete(
    "/{job_id}",
    response_model=JobView,
    responses={**NOT_FOUND, 409: {"model": ErrorBody, "description": "The job had already ended"}},
    summary="Cancel a queued or running job",
)
def cancel_job(
    job_id: JobId,
    store: Annotated[JobStore, Depends(get_store)],
    runner: Annotated[JobRunner, Depends(get_runner)],
) -> JobView:
    """A running job's worker process is terminated; the job ends as ``cancelled``."""
    applied = runner.cancel(job_id)
    job = _job(store, job_id)  # 404 for an unknown id (nothing was cancelled then)
    if not applied:
        raise JobConflictError(f"job {job_id} has already ended ({job.status}); nothing to cancel")
    return JobView.of(job)


@router.get(
    "/{job_id}/figures/{name}",
    response_class=FileResponse,
    responses={
        200: {
            "content": {t: {} for t in MEDIA_TYPES.values()},
            "description": "The figure or file (PNG, GeoJSON, GeoTIFF, CSV)",
        },
        **NOT_FOUND,
    },
    summary="A figure or result file of a finished job (PNG, GeoJSON, GeoTIFF, CSV)",
)
def get_figure(
    job_id: JobId,
    name: Annotated[
        str, PathParam(max_length=64, description="Figure name, as listed in the job's figures")
    ],
    store: Annotated[JobStore, Depends(get_store)],
    settings: Annotated[Settings, Depends(get_settings)],
) -> FileResponse:
    job = _job(store, job_id)
    filename = job.figures.get(name)
    if filename is None:
        have = ", ".join(sorted(job.figures)) or "none"
        raise JobNotFoundError(f"job {job_id} has no figure {name!r} (figures: {have})")
    path = Path(settings.figures_dir) / job_id / filename
    if not path.is_file():
        raise JobNotFoundError(f"the file of figure {name!r} of job {job_id} is missing")
    return FileResponse(path, media_type=MEDIA_TYPES.get(path.suffix, "application/octet-stream"))
