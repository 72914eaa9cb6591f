"""The application factory: ``create_app(settings)``; ``app`` for ``uvicorn api.main:app``.

Nothing touches the disk at import: the job store (schema created if missing) and the job
runner (start-up recovery, worker processes) are created in the application's lifespan.
"""

from __future__ import annotations

import logging
import sys
from collections.abc import AsyncIterator, Mapping
from contextlib import asynccontextmanager
from importlib.metadata import version

import anyio
from fastapi import Depends, FastAPI
from starlette.types import ASGIApp
from threadpoolctl import threadpool_limits

from api.auth import KeyRing
from api.deps import reject_unknown_query, require_api_key
from api.documents import install_document_schemas
from api.errors import V1_ERROR_RESPONSES, install_error_handlers, install_policy_responses
from api.front import FrontMiddleware, with_security_headers
from api.kinds import JOB_KINDS
from api.offload import ParsePool, install_answered_handler
from api.routes import (
    bounds,
    candidates,
    cities,
    events,
    imports,
    jobs,
    meta,
    plans,
    power,
    sites,
    web,
)
from api.settings import API_KEY_HEADER, Settings
from api.store import JobStore, server_lock
from api.worker import JobFunction, JobRunner
from ris_planner.runtime import allocator

DESCRIPTION = """\
RIS deployment planning for base-station-free 3D sidelink positioning: CRB-based position error
bounds (PEB_T, PEB_R, CEB) for a layout, and long-running work as persistent jobs.

Documents are those of the `ris-planner` command line. Units are SI unless a field name says
otherwise (`_m` metres, `_hz` hertz, `_dbm` dBm, angles in radians). Errors are JSON with the
field path of each problem. When the server has API keys, every `/v1` route needs one in the
`X-API-Key` header; a key sees only the jobs it created (the admin key sees all). Submissions
take an `Idempotency-Key` header: a retried POST with the same key returns the first job. When
the job database does not answer within a bound, every route answers 503 with `Retry-After`.
"""


GIL_SWITCH_S = 0.001
"""The interpreter's thread switch interval while the service runs (default 5 ms)."""


def service_logging() -> None:
    """Show the service's own log lines (the ``api`` logger and its children: a client gone
    before its body, a job's start and end, a storage fault) beside uvicorn's, at uvicorn's
    ``--log-level`` and in its format – when the server runs under uvicorn and nothing else
    configured logging (uvicorn configures only its own loggers: without this, lines below
    WARNING went nowhere)."""
    service = logging.getLogger("api")
    level = logging.getLogger("uvicorn.error").level
    if service.handlers or logging.getLogger().handlers or level == logging.NOTSET:
        return
    handler = logging.StreamHandler()
    try:
        from uvicorn.logging import DefaultFormatter

        handler.setFormatter(DefaultFormatter("%(levelprefix)s %(message)s", use_colors=False))
    except ImportError:  # uvicorn's level was set, so it is there; a plain format otherwise
        handler.setFormatter(logging.Formatter("%(levelname)s: %(message)s"))
    service.addHandler(handler)
    service.setLevel(level)


class ServiceApp(FastAPI):
    """The service's application: FastAPI with the security headers as its outermost layer
    (:func:`api.front.with_security_headers`), around Starlette's own error middleware, so that
    every answer has them – the 500 of an unexpected error too."""

    def build_middleware_stack(self) -> ASGIApp:
        return with_security_headers(super().build_middleware_stack())


def create_app(
    settings: Settings | None = None,
    kinds: Mapping[str, JobFunction] | None = None,
    *,
    fast_paths: bool = True,
) -> FastAPI:
    """A configured application; ``settings`` default to the environment's, ``kinds`` (job
    kind → function run by the workers) to :data:`api.kinds.JOB_KINDS`; ``fast_paths=False``
    sends ``POST /v1/bounds`` through its route too (:mod:`api.front`; the tests compare)."""
    settings = settings if settings is not None else Settings()
    job_kinds = dict(JOB_KINDS if kinds is None else kinds)

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        current: Settings = app.state.settings  # read at start-up (tests may swap the DB)
        service_logging()
        allocator.tune_malloc()  # the service's entry point (ris_planner.runtime.allocator)
        # a thread validating a large document hands the GIL over every 1 ms instead of 5 ms:
        # the event loop and /healthz wait less behind it (docs/guides/service-operations.md)
        switch = sys.getswitchinterval()
        sys.setswitchinterval(GIL_SWITCH_S)
        with server_lock(current.db):  # refuses a second server on this database file
            store = JobStore(
                current.db,
                recreate=True,
                busy_timeout_s=current.db_busy_timeout_s,
                retry_s=current.db_retry_s,
            )
            runner = JobRunner(
                store,
                current.figures_dir,
                job_kinds,
                current.workers,
                current.blas_threads,
                memory_mb=current.job_memory_mb,
            )
            app.state.store = store
            app.state.runner = runner
            app.state.bounds_limiter = anyio.CapacityLimiter(current.bounds_concurrency)
            app.state.parse_limiter = anyio.CapacityLimiter(current.parse_concurrency)
            # the document routes' parsing and validation, in processes (api.offload)
            parse_pool = ParsePool(current.parse_concurrency)
            app.state.parse_pool = parse_pool
            app.state.health_limiter = anyio.CapacityLimiter(2)  # never behind request work
            blas = threadpool_limits(limits=current.blas_threads)  # this process's threads
            runner.start()
            parse_pool.start()
            # the OpenAPI document now, off the event loop: the front middleware reads each
            # operation's body media types from it (api.security.DeclaredBodies)
            await anyio.to_thread.run_sync(app.openapi)
            try:
                yield
            finally:
                parse_pool.close()
                runner.stop()
                blas.restore_original_limits()
                sys.setswitchinterval(switch)

    app = ServiceApp(
        title="ris_planner",
        version=version("ris_planner"),
        description=DESCRIPTION,
        lifespan=lifespan,
        docs_url=None,  # local Swagger UI and ReDoc assets instead: api.routes.web
        redoc_url=None,
        redirect_slashes=False,  # a redirect would echo the request's (untrusted) Host
    )
    app.state.settings = settings
    install_error_handlers(app)
    install_answered_handler(app)
    keys = KeyRing(settings)
    app.state.keys = keys
    # one layer: the store wait bound, hosts and origins, the API key, the body limit, the
    # body's media type, and the fast path of POST /v1/bounds (api.front)
    app.add_middleware(
        FrontMiddleware,
        keys=keys,
        header=API_KEY_HEADER,
        max_bytes=settings.max_body_bytes,
        store_wait_s=settings.request_store_wait_s,
        policy=settings.origin_policy,
        fast_bounds=fast_paths,
    )
    app.include_router(meta.health_router)
    web.install_web(app)
    v1 = [Depends(require_api_key), Depends(reject_unknown_query)]
    routers = (
        web.router,
        bounds.router,
        plans.router,
        cities.router,
        power.router,
        imports.router,
        sites.router,
        candidates.router,
        events.router,
        jobs.router,
    )
    for router in (*routers, meta.router):
        app.include_router(router, prefix="/v1", dependencies=v1, responses=V1_ERROR_RESPONSES)
    install_document_schemas(app)
    install_policy_responses(app)
    return app


app = create_app()
