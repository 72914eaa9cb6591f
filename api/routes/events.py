"""``GET /v1/jobs/{id}/events``: a job's progress as server-sent events (``text/event-stream``).

The client opens one stream instead of polling. The server reads the job's state from the store
every :data:`EVENT_CHECK_S` – the worker writes progress at most every
:data:`api.worker.PROGRESS_INTERVAL_S`, so checking faster would find nothing new – and sends an
event only when the state changed:

* ``event: progress`` with the job summary (status, progress 0–1, message) as JSON;
* ``event: end`` with the summary once the job has ended (succeeded, failed, cancelled); the
  stream then closes;
* a ``: keep-alive`` comment every :data:`KEEPALIVE_S` while nothing changes;
* after :data:`MAX_STREAM_S`, or as soon as the server is shutting down (uvicorn waits for
  open responses before it stops), the stream closes without ``end``; ``retry:`` tells an
  ``EventSource`` to reconnect after :data:`RETRY_MS` (the page's own reader does the same).
"""

from __future__ import annotations

import json
import signal
import time
from collections.abc import AsyncIterator
from typing import Annotated

import anyio
from fastapi import APIRouter, Depends
from fastapi.responses import StreamingResponse

from api.deps import get_store
from api.models import JobSummary
from api.routes.jobs import NOT_FOUND, JobId, PrincipalDep, owned_head
from api.store import JobHead, JobStore

EVENT_CHECK_S = 0.25
"""How often the stream reads the job's state (the worker writes it at most every 0.2 s)."""

KEEPALIVE_S = 15.0
"""A comment line after this long without an event keeps proxies from closing the stream."""

MAX_STREAM_S = 600.0
"""One stream lasts at most this long; the client reconnects (bounded server resources)."""

RETRY_MS = 1000
"""Reconnection delay advertised to the client (the SSE ``retry:`` field)."""

ENDED = ("succeeded", "failed", "cancelled")

router = APIRouter(prefix="/jobs", tags=["jobs"])


def server_exiting() -> bool:
    """Whether the uvicorn server of this process has been asked to stop: its signal handler
    is the bound method ``Server.handle_exit``, which sets ``should_exit`` (False when not
    served by uvicorn, e.g. under a test client)."""
    server = getattr(signal.getsignal(signal.SIGINT), "__self__", None)
    return bool(getattr(server, "should_exit", False))


_HEADS: dict[tuple[int, str], tuple[float, JobHead | None]] = {}
"""The last state read per (store, job) and when: the streams of one job share one read per
:data:`EVENT_CHECK_S` (100 streams on a job: one store query a tick, not 100)."""


async def shared_head(store: JobStore, job_id: str, max_age_s: float) -> JobHead | None:
    """The job's state, read from the store unless another stream of the job read it less
    than ``max_age_s`` ago."""
    key = (id(store), job_id)
    hit = _HEADS.get(key)
    if hit is not None and time.monotonic() - hit[0] < max_age_s:
        return hit[1]
    job = await anyio.to_thread.run_sync(store.head, job_id)
    now = time.monotonic()
    _HEADS[key] = (now, job)
    if len(_HEADS) > 1024:  # forget states nobody asked for lately
        for k in [k for k, (t, _) in _HEADS.items() if now - t > 10 * max_age_s]:
            del _HEADS[k]
    return job


def _event(name: str, job: JobHead, seq: int) -> str:
    data = json.dumps(JobSummary.of_head(job).model_dump(mode="json"))
    return f"id: {seq}\nevent: {name}\ndata: {data}\n\n"


async def job_events(
    store: JobStore, job_id: str, check_s: float = EVENT_CHECK_S
) -> AsyncIterator[str]:
    """The event stream of one job (see the module docstring)."""
    yield f"retry: {RETRY_MS}\n\n"
    last: tuple[str, float, str] | None = None
    seq = 0
    started = sent = time.monotonic()
    while True:
        job = await shared_head(store, job_id, check_s / 2)
        if job is None:  # deleted meanwhile: nothing more will come
            return
        state = (job.status, job.progress, job.message)
        now = time.monotonic()
        if state != last:
            seq += 1
            ended = job.status in ENDED
            yield _event("end" if ended else "progress", job, seq)
            if ended:
                return
            last, sent = state, now
        elif now - sent >= KEEPALIVE_S:
            yield ": keep-alive\n\n"
            sent = now
        if now - started >= MAX_STREAM_S or server_exiting():  # (a disconnect cancels us)
            return
        await anyio.sleep(check_s)


@router.get(
    "/{job_id}/events",
    response_class=StreamingResponse,
    responses={
        200: {
            "content": {"text/event-stream": {}},
            "description": "Server-sent events: 'progress' (job summary JSON) on every change,"
            " 'end' when the job has ended",
        },
        **NOT_FOUND,
    },
    summary="Job progress as server-sent events",
)
def get_job_events(
    job_id: JobId, store: Annotated[JobStore, Depends(get_store)], principal: PrincipalDep
) -> StreamingResponse:
    """A stream of the job's state changes; ends with an ``end`` event when the job ends."""
    owned_head(store, job_id, principal)  # 404: unknown, or another key's job
    return StreamingResponse(
        job_events(store, job_id),
        media_type="text/event-stream",
        headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"},
    )
