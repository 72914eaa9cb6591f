"""The service's one error module: error types, the JSON error body, the exception handlers and
the request-body size limit.

Every error answer has the same shape (:class:`ErrorBody`): ``status``, a short ``error`` code,
a readable ``message``, the offending ``fields`` (validation) and the ``limit`` (413). Mapping:

* request validation (body, query, path) and pydantic errors raised by the engine → 422 with the
  field path of each problem;
* body larger than ``max_body_bytes`` → 413 with the limit; :class:`LimitExceededError` (too
  many pairs, layouts, …) → 413; other :class:`RisPlannerError` and plain ``ValueError`` from
  the engine (input it cannot work with, as the CLI treats it) → 422;
* a feature of the GIS extra on a server without it (:class:`MissingExtraError`) → 501 with
  what to install;
* unknown job or figure (or another key's job) → 404; cancelling a finished job → 409;
  missing/wrong API key → 401; unknown route 404, wrong method 405;
* the job database does not answer within the request's bound (:class:`StoreUnavailableError`,
  a SQLite error) → 503 with ``Retry-After`` (one handler, every route);
* a client that disconnects before sending its whole body → one info log line, no traceback;
* anything else → 500 with an error id and no traceback (the traceback goes to the log).

The API-key check (401) and the body limit (400 for an invalid ``Content-Length``, 413) run in
:class:`api.front.FrontMiddleware`, before anything reads a body.
"""

from __future__ import annotations

import logging
import sqlite3
import uuid
from collections.abc import Sequence
from typing import Any

import anyio
from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import BaseModel, Field, ValidationError
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.requests import ClientDisconnect
from starlette.responses import Response
from starlette.routing import Match

from api.store import StoreUnavailableError
from ris_planner.core.errors import DocumentFieldError, LimitExceededError, RisPlannerError
from ris_planner.core.io_json import MalformedJsonError
from ris_planner.io import MissingExtraError
from ris_planner.model.limits import COUNT_LIMITS, LIST_LIMITS, MAX_CANDIDATES

log = logging.getLogger("api")


class FieldError(BaseModel):
    """One validation problem."""

    location: str = Field(description="Where the field is: body, query, path or header")
    field: str = Field(description="Dotted path of the field, e.g. 'ris.1.position.2'")
    message: str = Field(description="What is wrong with the value")
    type: str = Field(description="Machine-readable error type (pydantic's)")


class ErrorBody(BaseModel):
    """The body of every error response."""

    status: int = Field(description="HTTP status code (repeated for convenience)")
    error: str = Field(description="Short error code, e.g. 'validation_error', 'not_found'")
    message: str = Field(description="Readable explanation: the rule, the value, how to fix it")
    fields: list[FieldError] = Field(
        default_factory=list, description="Validation problems, one per field (422 only)"
    )
    limit: int | None = Field(None, description="The limit that was exceeded (413 only)")


class MalformedBodyError(RisPlannerError):
    """A request body that is not a JSON object (→ 400)."""


class JobNotFoundError(Exception):
    """No job (or no figure of a job) with this id/name."""


class JobConflictError(Exception):
    """The job is in a state that forbids the operation (e.g. cancelling a finished job)."""


class BodyTooLargeError(StarletteHTTPException):
    """The request body is larger than the configured limit (an HTTP exception, so that it
    passes FastAPI's body reading unchanged)."""

    def __init__(self, limit: int) -> None:
        super().__init__(413, f"request body larger than the limit of {limit} bytes")
        self.limit = limit


V1_ERROR_RESPONSES: dict[int | str, dict[str, Any]] = {
    400: {
        "model": ErrorBody,
        "description": "Malformed request: a body that is not JSON, nested too deeply, or an"
        " invalid Content-Length",
    },
    401: {"model": ErrorBody, "description": "Missing or wrong API key (when one is configured)"},
    422: {"model": ErrorBody, "description": "Invalid request; `fields` names each problem"},
    503: {
        "model": ErrorBody,
        "description": "The job database did not answer within the request's bound; retry"
        " after the Retry-After header's seconds",
        "headers": {"Retry-After": {"schema": {"type": "integer"}, "description": "Seconds"}},
    },
}
"""``responses=`` entries of every /v1 route (OpenAPI)."""

TOO_LARGE_RESPONSE: dict[int | str, dict[str, Any]] = {
    413: {"model": ErrorBody, "description": "Request too large (body bytes, pairs or work)"},
}
"""``responses=`` entry of the routes that take a document."""

GIS_EXTRA_RESPONSE: dict[int | str, dict[str, Any]] = {
    501: {
        "model": ErrorBody,
        "description": "The request needs the GIS extra, which this server lacks (a geographic"
        " frame, an import): the message says what to install",
    },
}
"""``responses=`` entry of the routes that may need the GIS libraries."""


def _error_entry(description: str) -> dict[str, Any]:
    return {
        "description": description,
        "content": {"application/json": {"schema": {"$ref": "#/components/schemas/ErrorBody"}}},
    }


POLICY_RESPONSES: dict[str, dict[str, Any]] = {
    "403": _error_entry(
        "Refused: a write from a browser page of another origin, or a host name that is not a"
        " loopback one on a server listening on a loopback address"
    ),
    "413": _error_entry("Request too large (body bytes, or a size above its limit)"),
    "415": _error_entry(
        "A body whose media type this operation does not declare (or a body without one)"
    ),
}
"""The answers of the front middleware's rules (:mod:`api.front`), by the operations they
apply to: 403 to every operation that may change something, 413 and 415 to every operation
that takes a body."""


def install_policy_responses(app: FastAPI) -> None:
    """Declare :data:`POLICY_RESPONSES` in ``app``'s OpenAPI document, on every operation they
    apply to (one rule for every route, those added later too)."""
    generate = app.openapi

    def openapi() -> dict[str, Any]:
        schema = generate()
        for item in schema.get("paths", {}).values():
            for method, op in item.items():
                if not isinstance(op, dict) or method in ("get", "head", "options"):
                    continue
                responses = op.setdefault("responses", {})
                responses.setdefault("403", POLICY_RESPONSES["403"])
                if "requestBody" in op:
                    responses.setdefault("413", POLICY_RESPONSES["413"])
                    responses.setdefault("415", POLICY_RESPONSES["415"])
        return schema

    app.openapi = openapi  # type: ignore[method-assign]


def error_response(
    status: int,
    error: str,
    message: str,
    fields: Sequence[FieldError] = (),
    limit: int | None = None,
    headers: dict[str, str] | None = None,
) -> JSONResponse:
    body = ErrorBody(status=status, error=error, message=message, fields=list(fields), limit=limit)
    return JSONResponse(body.model_dump(mode="json"), status_code=status, headers=headers)


def _field_errors(errors: Sequence[Any], default_location: str = "body") -> list[FieldError]:
    out = []
    for err in errors:
        loc = [str(p) for p in err.get("loc", ())]
        location = default_location
        if loc and loc[0] in ("body", "query", "path", "header", "cookie"):
            location, loc = loc[0], loc[1:]
        out.append(
            FieldError(
                location=location,
                field=".".join(loc) or "(document)",
                message=str(err.get("msg", "invalid value")),
                type=str(err.get("type", "value_error")),
            )
        )
    return out


MAX_FIELD_ERRORS = 50
"""Validation problems listed in one 422 body (a NaN-filled phase table has thousands)."""


def _validation_response(fields: list[FieldError]) -> JSONResponse:
    if not fields:  # never an empty list: the document as a whole is at fault
        fields = [
            FieldError(location="body", field="(document)", message="invalid", type="value_error")
        ]
    summary = "; ".join(f"{f.field}: {f.message}" for f in fields[:5])
    more = f" (and {len(fields) - 5} more)" if len(fields) > 5 else ""
    return error_response(
        422, "validation_error", f"invalid request: {summary}{more}", fields[:MAX_FIELD_ERRORS]
    )


_HTTP_CODES = {
    400: "bad_request",
    401: "unauthorized",
    403: "forbidden",
    404: "not_found",
    405: "method_not_allowed",
    406: "not_acceptable",
    409: "conflict",
    413: "too_large",
    415: "unsupported_media_type",
    501: "not_implemented",
    503: "unavailable",
}

RETRY_AFTER_S = 5
"""``Retry-After`` of a 503 (the store retries with backoff of up to 2 s between attempts)."""


async def _on_validation(request: Request, exc: Exception) -> JSONResponse:
    """Request bodies (FastAPI) and documents validated later (pydantic) alike. The error list
    of a large invalid document (one error per bad item: tens of thousands) is built in a
    worker thread, never on the event loop."""
    assert isinstance(exc, RequestValidationError | ValidationError)
    return await anyio.to_thread.run_sync(_validation_answer, exc)


def _validation_answer(exc: RequestValidationError | ValidationError) -> JSONResponse:
    if isinstance(exc, ValidationError):
        errors: Sequence[Any] = exc.errors(include_url=False, include_input=False)
    else:
        errors = exc.errors()
    bad_json = [e for e in errors if e.get("type") == "json_invalid"]
    if bad_json:  # text that is not JSON: a malformed request, not an invalid document
        detail = bad_json[0].get("ctx", {}).get("error", "JSON decode error")
        return error_response(400, "bad_request", f"request body: not valid JSON ({detail})")
    size = size_limit(errors)
    if size is not None:  # a size above its limit: 413 with the limit, whatever else is wrong
        return _limit_answer(size)
    return _validation_response(_field_errors(errors))


API_LIST_LIMITS: dict[str, tuple[int, str]] = {
    "local": (MAX_CANDIDATES, "candidates"),
    "document": (MAX_CANDIDATES, "candidates"),
    "properties": (MAX_CANDIDATES, "candidate properties"),
}
"""The service's own bulk lists (the candidate routes' bodies), as
:data:`ris_planner.model.limits.LIST_LIMITS` for the documents."""

BULK_LISTS = {**LIST_LIMITS, **API_LIST_LIMITS}


def size_limit(errors: Sequence[Any]) -> LimitExceededError | None:
    """The first size limit among validation errors, as the engine's error (its message naming
    the field, its limit): a validator that raised :class:`LimitExceededError` (a grid above
    its points), a bulk list above its ``max_length`` (:data:`BULK_LISTS`), a count above its
    ``le`` (:data:`ris_planner.model.limits.COUNT_LIMITS`). None when there is none."""
    for err in errors:
        ctx = err.get("ctx") or {}
        field = _field_errors([err])[0].field
        cause = ctx.get("error")
        if isinstance(cause, LimitExceededError) and cause.limit is not None:
            return LimitExceededError(f"{field}: {cause}", cause.limit)
        names = [p for p in err.get("loc", ()) if isinstance(p, str)]
        name = names[-1] if names else ""
        kind, message = err.get("type"), err.get("msg", "")
        if kind == "too_long" and ctx.get("max_length") == BULK_LISTS.get(name, (None,))[0]:
            return LimitExceededError(f"{field}: {message}", BULK_LISTS[name][0])
        if kind == "less_than_equal" and ctx.get("le") == COUNT_LIMITS.get(name, (None,))[0]:
            return LimitExceededError(f"{field}: {message}", COUNT_LIMITS[name][0])
    return None


async def _on_limit(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, LimitExceededError)
    return _limit_answer(exc)


def _limit_answer(exc: LimitExceededError) -> JSONResponse:
    return error_response(413, "too_large", str(exc), limit=exc.limit)


async def _on_missing_extra(request: Request, exc: Exception) -> JSONResponse:
    """A feature of the optional GIS extra on a server without it: not the client's fault."""
    return _missing_extra_answer(exc)


def _missing_extra_answer(exc: Exception) -> JSONResponse:
    return error_response(501, "not_implemented", f"this server cannot do that: {exc}")


def exception_answer(exc: Exception) -> JSONResponse | None:
    """The handlers' answer to a document's error – validation (422, or 400 for text that is
    not JSON), a limit (413), a missing extra (501), an engine rule (422 / 400) – rendered
    synchronously (in a parse process, :mod:`api.offload`); None for any other exception."""
    if isinstance(exc, RequestValidationError | ValidationError):
        return _validation_answer(exc)
    if isinstance(exc, LimitExceededError):
        return _limit_answer(exc)
    if isinstance(exc, MissingExtraError):
        return _missing_extra_answer(exc)
    if isinstance(exc, ValueError):
        return _engine_answer(exc)
    return None


async def _on_engine_error(request: Request, exc: Exception) -> JSONResponse:
    """Every 422 names a field: the rule's own field, else the document as a whole."""
    return _engine_answer(exc)


def _engine_answer(exc: Exception) -> JSONResponse:
    if isinstance(exc, MalformedBodyError | MalformedJsonError):
        return error_response(400, "bad_request", str(exc))
    field, reason = "(document)", str(exc)
    if isinstance(exc, DocumentFieldError):
        field, reason = exc.field, exc.reason
    fields = [FieldError(location="body", field=field, message=reason, type="value_error")]
    return error_response(422, "invalid_input", str(exc), fields)


async def _on_not_found(request: Request, exc: Exception) -> JSONResponse:
    return error_response(404, "not_found", str(exc))


async def _on_conflict(request: Request, exc: Exception) -> JSONResponse:
    return error_response(409, "conflict", str(exc))


HTTP_METHODS = ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS")


def allowed_methods(request: Request) -> list[str]:
    """Every method some route serves at this request's path (the routes of one path may be
    separate, e.g. GET and DELETE of a job, and a 405 names them all)."""
    allowed = []
    for method in HTTP_METHODS:
        scope = {**request.scope, "method": method}
        if any(route.matches(scope)[0] == Match.FULL for route in request.app.router.routes):
            allowed.append(method)
    return allowed


async def _on_http(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, StarletteHTTPException)
    limit = exc.limit if isinstance(exc, BodyTooLargeError) else None
    headers = dict(exc.headers) if exc.headers else {}
    message = str(exc.detail)
    if exc.status_code == 405:
        allow = allowed_methods(request)
        headers["Allow"] = ", ".join(allow)
        message = f"method {request.method} not allowed here; allowed: {', '.join(allow)}"
    return error_response(
        exc.status_code,
        _HTTP_CODES.get(exc.status_code, "http_error"),
        message,
        limit=limit,
        headers=headers or None,
    )


async def _on_store_unavailable(request: Request, exc: Exception) -> JSONResponse:
    """The job database did not answer (locked, full, unwritable, I/O): not the client's fault
    and usually passing, so 503 with Retry-After, whatever the route."""
    reason = str(exc) if isinstance(exc, StoreUnavailableError) else f"job database error: {exc}"
    log.warning("503 on %s %s: %s", request.method, request.url.path, reason)
    return error_response(
        503,
        "unavailable",
        f"the job database is unavailable, try again in {RETRY_AFTER_S} s ({reason})",
        headers={"Retry-After": str(RETRY_AFTER_S)},
    )


async def _on_disconnect(request: Request, exc: Exception) -> Response:
    """The client went away before its body arrived: nobody reads an answer, one log line."""
    log.info("client disconnected during %s %s (request dropped)", request.method, request.url.path)
    return Response(status_code=400)


async def _on_unexpected(request: Request, exc: Exception) -> JSONResponse:
    error_id = uuid.uuid4().hex[:12]
    log.error(
        "unexpected error %s on %s %s", error_id, request.method, request.url.path, exc_info=exc
    )
    return error_response(
        500, "internal_error", f"unexpected server error (id {error_id}); the log has details"
    )


def install_error_handlers(app: FastAPI) -> None:
    """Register the handlers above on ``app`` (most specific classes first)."""
    app.add_exception_handler(RequestValidationError, _on_validation)
    app.add_exception_handler(ValidationError, _on_validation)
    app.add_exception_handler(LimitExceededError, _on_limit)
    app.add_exception_handler(MissingExtraError, _on_missing_extra)
    app.add_exception_handler(ValueError, _on_engine_error)  # RisPlannerError and the engine's
    app.add_exception_handler(JobNotFoundError, _on_not_found)
    app.add_exception_handler(JobConflictError, _on_conflict)
    app.add_exception_handler(StarletteHTTPException, _on_http)
    app.add_exception_handler(StoreUnavailableError, _on_store_unavailable)
    app.add_exception_handler(sqlite3.Error, _on_store_unavailable)
    app.add_exception_handler(ClientDisconnect, _on_disconnect)
    app.add_exception_handler(Exception, _on_unexpected)
