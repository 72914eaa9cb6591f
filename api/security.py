"""Response headers and per-request policies of every answer (docs/guides/service-operations.md
"Hardening"): ``X-Content-Type-Options: nosniff`` on every response; a Content-Security-Policy,
``X-Frame-Options: DENY`` and ``Referrer-Policy`` on every HTML response (the planner page at
``/`` and at ``/static/index.html`` alike, the API documentation pages with their own policy);
and the job database's wait bound of a request (:data:`api.store.CALL_BUDGET_S`)."""

from __future__ import annotations

from starlette.datastructures import MutableHeaders
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from api.store import CALL_BUDGET_S

PAGE_CSP = (
    "default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data: blob:;"
    " connect-src 'self'; object-src 'none'; base-uri 'none'; frame-ancestors 'none'"
)
"""Content-Security-Policy of every HTML response without its own: only its own origin."""


def docs_csp(script_hashes: list[str]) -> str:
    """The policy of ``/docs`` and ``/redoc``: scripts from this origin plus the page's one
    inline start-up script (by its SHA-256), inline styles (both UIs set them), workers from
    blob: (ReDoc), nothing from elsewhere – they run offline from ``static/vendor``."""
    scripts = " ".join(["'self'", *(f"'sha256-{h}'" for h in script_hashes)])
    return (
        f"default-src 'self'; script-src {scripts}; style-src 'self' 'unsafe-inline';"
        " img-src 'self' data: blob:; font-src 'self' data:; worker-src 'self' blob:;"
        " connect-src 'self'; object-src 'none'; base-uri 'none'; frame-ancestors 'none'"
    )


class SecurityHeadersMiddleware:
    """Pure ASGI middleware: the headers above on every response, and the store wait bound
    (``store_wait_s``) set for everything the request runs (thread pools copy the context)."""

    def __init__(self, app: ASGIApp, store_wait_s: float) -> None:
        self.app = app
        self.store_wait_s = store_wait_s

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = MutableHeaders(scope=message)
                headers.setdefault("X-Content-Type-Options", "nosniff")
                if headers.get("content-type", "").startswith("text/html"):
                    headers.setdefault("Content-Security-Policy", PAGE_CSP)
                    headers.setdefault("X-Frame-Options", "DENY")
                    headers.setdefault("Referrer-Policy", "no-referrer")
            await send(message)

        token = CALL_BUDGET_S.set(self.store_wait_s)
        try:
            await self.app(scope, receive, send_with_headers)
        finally:
            CALL_BUDGET_S.reset(token)
