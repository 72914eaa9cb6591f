"""The service's one ASGI middleware: every request's per-request work in one layer, and the
fast path of ``POST /v1/bounds``; and the outermost layer that adds the security headers.

Per HTTP request, in this order (each was a middleware of its own until a profile of
``POST /v1/bounds`` showed the layers' cost; docs/validation/speed-guard.md):

1. the job database's wait bound of the request (:data:`api.store.CALL_BUDGET_S`, set for
   everything the request runs: thread pools copy the context);
2. 403 for a request the :class:`api.security.OriginPolicy` refuses: a host name that is not
   a loopback one on a loopback server, a write from a page of another origin;
3. with API keys configured (:class:`api.auth.KeyRing`), a ``/v1`` request without a known
   ``X-API-Key`` gets 401 before anything reads its body; a known key's
   :class:`api.auth.Principal` goes to ``scope["state"]["principal"]``;
4. 400 for an invalid ``Content-Length``, 413 before reading a body whose ``Content-Length``
   exceeds ``max_bytes``; a streamed (chunked) body is counted as it arrives and stopped at the
   limit (:class:`api.errors.BodyTooLargeError`, 413);
5. 415 for a body whose media type the operation does not declare in the OpenAPI document
   (:class:`api.security.DeclaredBodies`), before anything reads it.

The security headers of :mod:`api.security` (``nosniff`` on every answer, the page policy on
HTML) are added by :func:`with_security_headers`, which wraps the whole application – the
500 of an unexpected error, answered outside every middleware, included.

The fast path: ``POST /v1/bounds`` without a query string is answered here, without FastAPI's
routing, dependency solving and response machinery, by the route's own functions
(:mod:`api.routes.bounds`: parse, validate, check the size, compute, render the JSON). A body of
at most :data:`api.settings.INLINE_MAX_BODY_BYTES` is parsed on the event loop, and a request
whose work (:func:`ris_planner.bounds.resources.request_work`) is at most the setting
``bounds_inline_work`` is answered there too (≈ 1 ms: a worker thread's hand-off and GIL
switches cost more); larger ones run in a worker thread under the route's limiter. The
route's dependencies have nothing to do for such a request (the key was checked in step 3; no
query parameter to reject), and its errors go to the application's own exception handlers, so
the answers – 200, 400, 401, 413, 415, 422, 501 and their bodies – are those of the route
(``tests/test_api_front.py`` compares both). Any other request, a query string included,
takes the route.
"""

from __future__ import annotations

import logging
from typing import Any

import anyio
from starlette.datastructures import MutableHeaders
from starlette.requests import ClientDisconnect, Request
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from api.auth import KeyRing
from api.errors import BodyTooLargeError, error_response
from api.routes.bounds import bounds_answer, bounds_scenario, scenario_answer
from api.security import PAGE_CSP, SAFE_METHODS, DeclaredBodies, OriginPolicy, media_refusal
from api.settings import INLINE_MAX_BODY_BYTES
from api.store import CALL_BUDGET_S
from ris_planner.bounds.resources import request_work

log = logging.getLogger("api")

BOUNDS_PATH = "/v1/bounds"
"""The route that has a fast path."""


def _security_headers(message: Message) -> None:
    """The headers of :mod:`api.security` on a response start message (in place)."""
    headers = MutableHeaders(scope=message)
    headers.setdefault("X-Content-Type-Options", "nosniff")
    if headers.get("content-type", "").startswith("text/html"):
        headers.setdefault("Content-Security-Policy", PAGE_CSP)
        headers.setdefault("X-Frame-Options", "DENY")
        headers.setdefault("Referrer-Policy", "no-referrer")


def with_security_headers(app: ASGIApp) -> ASGIApp:
    """``app`` with the headers of :mod:`api.security` on every HTTP answer: the outermost
    layer of the service (:class:`api.main.ServiceApp`), so that the 500 of an unexpected error
    – rendered by Starlette's outermost ``ServerErrorMiddleware`` – has them too."""

    async def secured(scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await app(scope, receive, send)
            return

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                _security_headers(message)
            await send(message)

        await app(scope, receive, send_with_headers)

    return secured


class FrontMiddleware:
    """Pure ASGI middleware: the per-request work above, and the fast path of
    ``POST /v1/bounds`` (``fast_bounds=False`` sends it through the route like any other)."""

    def __init__(
        self,
        app: ASGIApp,
        *,
        keys: KeyRing,
        header: str,
        max_bytes: int,
        store_wait_s: float,
        policy: OriginPolicy | None = None,
        prefix: str = "/v1",
        fast_bounds: bool = True,
    ) -> None:
        self.app = app
        self.policy = policy if policy is not None else OriginPolicy()
        self.bodies = DeclaredBodies()
        self.keys = keys
        self.header = header.lower().encode("latin-1")
        self.header_name = header
        self.max_bytes = max_bytes
        self.store_wait_s = store_wait_s
        self.prefix = prefix
        self.fast_bounds = fast_bounds

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        token = CALL_BUDGET_S.set(self.store_wait_s)
        try:
            await self._http(scope, receive, send)
        finally:
            CALL_BUDGET_S.reset(token)

    async def _http(self, scope: Scope, receive: Receive, send: Send) -> None:
        path: str = scope.get("path", "")
        headers = dict(scope.get("headers", []))
        refused = self.policy.refusal(scope, headers)
        if refused is not None:
            await error_response(403, "forbidden", refused)(scope, receive, send)
            return
        if self.keys.enabled and (path == self.prefix or path.startswith(self.prefix + "/")):
            given = next((v for k, v in scope.get("headers", []) if k == self.header), None)
            principal = self.keys.lookup(given)
            if principal is None:
                response = error_response(
                    401,
                    "unauthorized",
                    f"missing or wrong API key: send it in the {self.header_name} header",
                    headers={"WWW-Authenticate": "ApiKey"},
                )
                await response(scope, receive, send)
                return
            scope.setdefault("state", {})["principal"] = principal
        for name, value in scope.get("headers", []):
            if name == b"content-length":
                try:
                    length = int(value)
                except ValueError:
                    length = -1
                if length < 0:
                    response = error_response(400, "bad_request", "invalid Content-Length header")
                    await response(scope, receive, send)
                    return
                if length > self.max_bytes:
                    response = error_response(
                        413,
                        "too_large",
                        f"request body of {length} bytes exceeds the limit of"
                        f" {self.max_bytes} bytes",
                        limit=self.max_bytes,
                    )
                    await response(scope, receive, send)
                    return
        if scope["method"] not in SAFE_METHODS:
            refused = media_refusal(self.bodies.of(scope["app"], scope), headers)
            if refused is not None:
                response = error_response(415, "unsupported_media_type", refused)
                await response(scope, receive, send)
                return
        if (
            self.fast_bounds
            and path == BOUNDS_PATH
            and scope["method"] == "POST"
            and not scope.get("query_string")
            and not scope.get("root_path")
        ):
            await self._bounds(scope, receive, send)
            return
        received = 0

        async def limited_receive() -> Message:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > self.max_bytes:
                    raise BodyTooLargeError(self.max_bytes)
            return message

        await self.app(scope, limited_receive, send)

    async def _bounds(self, scope: Scope, receive: Receive, send: Send) -> None:
        """``POST /v1/bounds``: the route's work and answers without the route's machinery."""
        app: Any = scope["app"]  # the application (Starlette puts itself there)
        settings = app.state.settings
        limiter = app.state.bounds_limiter
        try:
            body = await self._read_body(receive)
            if settings.bounds_inline_work > 0 and len(body) <= INLINE_MAX_BODY_BYTES:
                # a small text: parsed and validated here; a small request answered here too
                scenario = bounds_scenario(body, settings)
                if request_work(scenario) <= settings.bounds_inline_work:
                    response = scenario_answer(scenario)
                else:
                    response = await anyio.to_thread.run_sync(
                        scenario_answer, scenario, limiter=limiter
                    )
            else:
                response = await anyio.to_thread.run_sync(
                    bounds_answer, body, settings, limiter=limiter
                )
        except Exception as exc:
            handler = _handler(app.exception_handlers, exc)
            if handler is None:  # → ServerErrorMiddleware: 500 with an error id, as the route's
                raise
            response = await handler(Request(scope, receive), exc)
        await response(scope, receive, send)

    async def _read_body(self, receive: Receive) -> bytes:
        """The whole body (``Request.body``), stopped at the limit."""
        chunks: list[bytes] = []
        received = 0
        while True:
            message = await receive()
            if message["type"] == "http.request":
                chunk = message.get("body", b"")
                received += len(chunk)
                if received > self.max_bytes:
                    raise BodyTooLargeError(self.max_bytes)
                chunks.append(chunk)
                if not message.get("more_body", False):
                    return b"".join(chunks)
            elif message["type"] == "http.disconnect":
                raise ClientDisconnect()


def _handler(handlers: dict[Any, Any], exc: Exception) -> Any:
    """The application's handler of ``exc`` by its class's MRO, as Starlette's
    ``ExceptionMiddleware`` finds it (the catch-all ``Exception`` handler is the
    ``ServerErrorMiddleware``'s, outside this middleware: None)."""
    for cls in type(exc).__mro__:
        if cls is Exception:
            return None
        if cls in handlers:
            return handlers[cls]
    return None
