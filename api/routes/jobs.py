"""Jobs: listing, status and result, cancellation, removal, figures; and the submit helper that
the job kinds' POST routes share.

Every job belongs to the API key that created it (:mod:`api.auth`): a key lists, reads, streams,
cancels and removes only its own jobs – another key's job answers 404, as an unknown id – and
the admin key all. ``POST /v1/jobs/{id}/cancel`` cancels (the job stays, ``cancelled``);
``DELETE /v1/jobs/{id}`` removes it (a running job is cancelled first; then GET → 404)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any

from fastapi import APIRouter, Depends, Header, Query
from fastapi import Path as PathParam
from fastapi.responses import FileResponse, JSONResponse, Response

from api.auth import Principal
from api.deps import get_principal, get_runner, get_settings, get_store
from api.errors import ErrorBody, JobConflictError, JobNotFoundError
from api.models import JobPage, JobSummary, JobView
from api.settings import Settings
from api.store import Job, JobHead, JobStatus, JobStore, JsonText
from api.worker import JobRunner
from ris_planner.io.gis_outputs import PLAN_WRITERS

router = APIRouter(prefix="/jobs", tags=["jobs"])

JobId = Annotated[
    str, PathParam(description="Job id as returned on submission", pattern="^[0-9a-f]{32}$")
]
MEDIA_TYPES = {
    ".png": "image/png",
    **{Path(w.filename).suffix: w.media_type for w in PLAN_WRITERS},
}
"""Media type of a job file by suffix: PNG figures and the plan's GIS files (their writers'
registry, :data:`ris_planner.io.gis_outputs.PLAN_WRITERS`)."""
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
                "operationId": "cancel_job_v1_jobs__job_id__cancel_post",
                "parameters": {"job_id": "$response.body#/id"},
                "description": "Cancel the job",
            },
        },
    }
}
"""OpenAPI links of a 202 job answer (clients and stateful testers follow them)."""


IDEMPOTENCY_KEY_HEADER = "Idempotency-Key"

IdempotencyKey = Annotated[
    str | None,
    Header(
        alias=IDEMPOTENCY_KEY_HEADER,
        min_length=1,
        max_length=200,
        pattern=r"^[\x21-\x7e]+$",
        description="A client-chosen key (1–200 visible ASCII characters) of this submission:"
        " a retry with the same key (same API key) returns the job created first (202, header"
        " Idempotent-Replayed: true) instead of a second job; a different document under a"
        " used key is 409",
    ),
]
"""The ``Idempotency-Key`` header of the job submissions."""

CONFLICT_RESPONSE: dict[int | str, dict[str, Any]] = {
    409: {"model": ErrorBody, "description": "Idempotency-Key reused with another document"}
}


def submit_job(
    kind: str,
    document: dict[str, Any] | JsonText,
    store: JobStore,
    runner: JobRunner,
    principal: Principal | None = None,
    idempotency_key: str | None = None,
    estimate: dict[str, float | int] | None = None,
) -> Response:
    """Store a queued job owned by ``principal``'s key, hand it to the runner, answer 202 with
    its view and Location; with an ``idempotency_key`` this key used before, the job created
    then (nothing new is queued; 409 if that job holds another document or kind).
    ``estimate``: the job's resource estimate (a plan's), kept with it from now on."""
    owner = None if principal is None or not principal.name else principal.name
    job, created = store.create_once(
        kind, document, owner=owner, idempotency_key=idempotency_key, estimate=estimate
    )
    headers = {"Location": f"/v1/jobs/{job.id}"}
    if created:
        runner.submit(job.id, kind)
    else:
        sent = json.loads(document) if isinstance(document, JsonText) else document
        if job.kind != kind or job.request != sent:
            raise JobConflictError(
                f"the Idempotency-Key was used for another submission (job {job.id}, kind"
                f" {job.kind}); use a new key for a new document"
            )
        headers["Idempotent-Replayed"] = "true"
    view = JobView.of(job)
    headers["Location"] = view.url
    if not (created and isinstance(document, JsonText)):
        return JSONResponse(view.model_dump(mode="json"), status_code=202, headers=headers)
    # the document as its text (never parsed in this process): the view's other fields, then
    # "request" with the text as sent to the store
    rest = JSONResponse(view.model_dump(mode="json", exclude={"request"})).body
    body = bytes(rest[:-1]) + b',"request":' + document.encode() + b"}"
    return Response(body, status_code=202, headers=headers, media_type="application/json")


def owned_job(store: JobStore, job_id: str, principal: Principal) -> Job:
    """The job, if ``principal`` may see it; 404 otherwise (as for an unknown id)."""
    job = store.get(job_id)
    if job is None or not principal.may_see(job.owner):
        raise JobNotFoundError(f"no job with id {job_id}")
    return job


def owned_head(store: JobStore, job_id: str, principal: Principal) -> JobHead:
    """The job's state, if ``principal`` may see it; 404 otherwise."""
    head = store.head(job_id)
    if head is None or not principal.may_see(head.owner):
        raise JobNotFoundError(f"no job with id {job_id}")
    return head


PrincipalDep = Annotated[Principal, Depends(get_principal)]


@router.get("", response_model=JobPage, summary="List jobs, newest first (paged)")
def list_jobs(
    store: Annotated[JobStore, Depends(get_store)],
    principal: PrincipalDep,
    limit: Annotated[int, Query(ge=1, le=200, description="Page size (1–200)")] = 50,
    offset: Annotated[int, Query(ge=0, le=10**9, description="Jobs to skip")] = 0,
    status: Annotated[JobStatus | None, Query(description="Only jobs with this status")] = None,
    kind: Annotated[str | None, Query(max_length=40, description="Only jobs of this kind")] = None,
) -> JobPage:
    """This key's jobs (the admin key's: all)."""
    jobs, total = store.list_jobs(
        limit=limit, offset=offset, status=status, kind=kind, owner=principal.owner_filter
    )
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
def get_job(
    job_id: JobId, store: Annotated[JobStore, Depends(get_store)], principal: PrincipalDep
) -> JobView:
    """Status, progress (0–1) and, when finished, the result or the error."""
    return JobView.of(owned_job(store, job_id, principal))


@router.post(
    "/{job_id}/cancel",
    response_model=JobView,
    responses={**NOT_FOUND, 409: {"model": ErrorBody, "description": "The job had already ended"}},
    summary="Cancel a queued or running job (the job stays, as cancelled)",
)
def cancel_job(
    job_id: JobId,
    store: Annotated[JobStore, Depends(get_store)],
    runner: Annotated[JobRunner, Depends(get_runner)],
    principal: PrincipalDep,
) -> JobView:
    """A running job's worker process is terminated; the job ends as ``cancelled`` and keeps
    answering GET. 409 if it had already ended."""
    owned_head(store, job_id, principal)  # 404 for an unknown id or another key's job
    applied = runner.cancel(job_id)
    job = owned_job(store, job_id, principal)
    if not applied:
        raise JobConflictError(f"job {job_id} has already ended ({job.status}); nothing to cancel")
    return JobView.of(job)


@router.delete(
    "/{job_id}",
    status_code=204,
    response_class=Response,
    responses={**NOT_FOUND, 204: {"description": "The job was removed"}},
    summary="Remove a job (a queued or running one is cancelled first); then GET answers 404",
)
def delete_job(
    job_id: JobId,
    store: Annotated[JobStore, Depends(get_store)],
    runner: Annotated[JobRunner, Depends(get_runner)],
    principal: PrincipalDep,
) -> Response:
    """The job's row, result and figures are removed; a queued or running job is cancelled
    (its worker process terminated) first. 404 for an unknown id, another key's job or a job
    removed before."""
    owned_head(store, job_id, principal)
    if not runner.delete(job_id):
        raise JobNotFoundError(f"no job with id {job_id}")
    return Response(status_code=204)


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
    principal: PrincipalDep,
) -> FileResponse:
    job = owned_job(store, job_id, principal)
    filename = job.figures.get(name)
    if filename is None:
        have = ", ".join(sorted(job.figures)) or "none"
        raise JobNotFoundError(f"job {job_id} has no figure {name!r} (figures: {have})")
    path = Path(settings.figures_dir) / job_id / filename
    if not path.is_file():
        raise JobNotFoundError(f"the file of figure {name!r} of job {job_id} is missing")
    return FileResponse(path, media_type=MEDIA_TYPES.get(path.suffix, "application/octet-stream"))
