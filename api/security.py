"""Response headers and per-request policies of every answer (docs/guides/service-operations.md
"Hardening"): ``X-Content-Type-Options: nosniff`` on every response; a Content-Security-Policy,
``X-Frame-Options: DENY`` and ``Referrer-Policy`` on every HTML response (the planner page at
``/`` and at ``/static/index.html`` alike, the API documentation pages with their own policy);
and the job database's wait bound of a request (:data:`api.store.CALL_BUDGET_S`). Both are set by
:class:`api.front.FrontMiddleware`."""

from __future__ import annotations

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
