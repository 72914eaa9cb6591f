"""Request dependencies: the app's settings, store and runner, and the API-key check.

All are ``async``: they only read the application's state, and FastAPI would otherwise run
each in the thread pool – a thread hand-off per dependency and request, which under load
queues behind request work (``/healthz`` among them)."""

from __future__ import annotations

from fastapi import HTTPException, Request, Security
from fastapi.dependencies.models import Dependant
from fastapi.exceptions import RequestValidationError
from fastapi.security import APIKeyHeader

from api.auth import ANONYMOUS, KeyRing, Principal
from api.settings import API_KEY_HEADER, Settings
from api.store import JobStore
from api.worker import JobRunner

api_key_header = APIKeyHeader(
    name=API_KEY_HEADER,
    auto_error=False,
    description="API key; required on every /v1 route when the server has keys"
    " (RIS_PLANNER_API_KEY, RIS_PLANNER_API_KEYS, RIS_PLANNER_API_KEYS_FILE)",
)


async def get_settings(request: Request) -> Settings:
    settings: Settings = request.app.state.settings
    return settings


async def get_store(request: Request) -> JobStore:
    store: JobStore = request.app.state.store
    return store


async def get_runner(request: Request) -> JobRunner:
    runner: JobRunner = request.app.state.runner
    return runner


async def get_principal(request: Request) -> Principal:
    """Who sent the request (set by :class:`api.errors.ApiKeyMiddleware`); without keys
    :data:`api.auth.ANONYMOUS`, which sees every job."""
    principal: Principal | None = getattr(request.state, "principal", None)
    return ANONYMOUS if principal is None else principal


async def require_api_key(request: Request, key: str | None = Security(api_key_header)) -> None:
    """401 unless no key is configured or the middleware accepted the request's key (the
    middleware answers first; this dependency declares the key in the OpenAPI document)."""
    keys: KeyRing = request.app.state.keys
    if keys.enabled and getattr(request.state, "principal", None) is None:
        raise HTTPException(
            401,
            f"missing or wrong API key: send it in the {API_KEY_HEADER} header",
            headers={"WWW-Authenticate": "ApiKey"},
        )


async def reject_unknown_query(request: Request) -> None:
    """422 for a query parameter the route does not declare (a misspelt ``limt=5`` would
    otherwise be ignored silently; the OpenAPI document lists every parameter)."""
    if not request.query_params:
        return
    route = request.scope.get("route")
    dependant = getattr(route, "dependant", None)
    if dependant is None:
        return
    known = _query_names(dependant)
    unknown = sorted(set(request.query_params) - known)
    if unknown:
        raise RequestValidationError(
            [
                {
                    "type": "extra_forbidden",
                    "loc": ("query", name),
                    "msg": "unknown query parameter"
                    + (f" (this route takes: {', '.join(sorted(known))})" if known else ""),
                }
                for name in unknown
            ]
        )


def _query_names(dependant: Dependant) -> set[str]:
    """The query parameter names of a route and of its (sub-)dependencies."""
    names: set[str] = set()
    todo = [dependant]
    while todo:
        d = todo.pop()
        names.update(p.alias for p in d.query_params)
        todo.extend(d.dependencies)
    return names
