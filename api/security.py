"""Response headers and per-request policies of every answer (docs/guides/service-operations.md
"Hardening"): ``X-Content-Type-Options: nosniff`` on every response; a Content-Security-Policy,
``X-Frame-Options: DENY`` and ``Referrer-Policy`` on every HTML response (the planner page at
``/`` and at ``/static/index.html`` alike, the API documentation pages with their own policy);
which hosts and origins may send what (:class:`OriginPolicy`, 403); and the media types a
request body may have (:class:`DeclaredBodies`, 415). The headers are set by the outermost
layer of the application (:func:`api.front.with_security_headers`, on every answer, a 500
included), the policies applied by :class:`api.front.FrontMiddleware`."""

from __future__ import annotations

import ipaddress
import re
from dataclasses import dataclass
from typing import Any
from urllib.parse import urlsplit

from starlette.routing import get_route_path
from starlette.types import Scope

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


# -- per-request policies (api.front.FrontMiddleware applies them) ---------------------------

SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})
"""Methods that change nothing: the origin rule leaves them alone (a page of another origin
may send them, but cannot read the answer: the service sends no CORS headers)."""

LOCAL_HOSTS = frozenset({"localhost"})
"""Host names of the loopback interface (``*.localhost`` too, RFC 6761)."""


def _host_name(host: str) -> str:
    """The name of a ``Host`` header value, without its port (``[::1]:80`` → ``::1``)."""
    host = host.strip().lower()
    if host.startswith("["):
        return host[1:].split("]", 1)[0]
    return host.rsplit(":", 1)[0] if host.count(":") == 1 else host


def _is_ip(name: str) -> bool:
    try:
        ipaddress.ip_address(name)
    except ValueError:
        return False
    return True


def loopback_connection(server: tuple[str, int] | None) -> bool:
    """Whether a request arrived on a loopback address (ASGI ``scope["server"]``: the address the
    server's socket listens on)."""
    if not server:
        return False
    try:
        return ipaddress.ip_address(server[0]).is_loopback
    except ValueError:
        return False


def media_type(content_type: str) -> str:
    """The media type of a ``Content-Type`` value, lower case, without its parameters."""
    return content_type.split(";", 1)[0].strip().lower()


def parse_list(text: str | None) -> frozenset[str]:
    """A comma-separated setting as a set of lower-case entries (``/`` at the end dropped)."""
    return frozenset(e.strip().lower().rstrip("/") for e in (text or "").split(",") if e.strip())


@dataclass(frozen=True)
class OriginPolicy:
    """Who may send what (docs/guides/service-operations.md, "Browsers and other origins").

    * **Host**: a request that arrives on a loopback address must name a loopback host –
      ``localhost`` (or ``*.localhost``), an IP address – or one of ``allowed_hosts``: a page
      whose own name resolves to 127.0.0.1 (DNS rebinding) shares the server's origin and would
      pass every origin check, but it names itself in ``Host``. A server listening on another
      interface is not checked (its clients name it as they reach it).
    * **Origin**: a request that may change something (any method but GET, HEAD, OPTIONS) from
      a browser page of another origin is refused – its ``Origin`` header is neither the
      server's own (the ``Host`` it was sent to) nor one of ``allowed_origins``, or, where a
      browser sends no ``Origin``, its ``Sec-Fetch-Site`` says another site sent it.
    """

    allowed_origins: frozenset[str] = frozenset()
    allowed_hosts: frozenset[str] = frozenset()

    def refusal(self, scope: Scope, headers: dict[bytes, bytes]) -> str | None:
        """Why the request is refused (403), or None."""
        host = headers.get(b"host", b"").decode("latin-1")
        if host and loopback_connection(scope.get("server")):
            name = _host_name(host)
            local = name in LOCAL_HOSTS or name.endswith(".localhost") or _is_ip(name)
            if not local and name not in self.allowed_hosts:
                return (
                    f"host {name!r} refused: this server listens on a loopback address and"
                    " answers only localhost, IP addresses and RIS_PLANNER_ALLOWED_HOSTS"
                )
        if scope.get("method", "GET") in SAFE_METHODS:
            return None
        origin = headers.get(b"origin")
        if origin is None:
            site = headers.get(b"sec-fetch-site", b"").decode("latin-1").lower()
            if site in ("cross-site", "same-site"):
                return f"a request from another site ({site}) may not change anything here"
            return None
        text = origin.decode("latin-1").strip().lower().rstrip("/")
        same = bool(host) and urlsplit(text).netloc == host.lower()
        if text != "null" and (same or text in self.allowed_origins):
            return None
        return (
            f"origin {text!r} refused: a page of another origin may not change anything here"
            " (RIS_PLANNER_ALLOWED_ORIGINS lists the origins allowed besides the server's own)"
        )


BodyMedia = frozenset[str] | None
"""The media types an operation's request body may have (None: it declares no body)."""


class DeclaredBodies:
    """The media types of each operation's request body, as the application's OpenAPI document
    declares them – the one source of the 415 rule, for every route, those added later too:
    a request to an operation that declares a body must send one of its media types, or no
    body at all (the operation then says what is missing). Requests are matched to operations
    by the document's own path templates (``/v1/jobs/{job_id}``: one segment a parameter)."""

    def __init__(self) -> None:
        self._fixed: dict[tuple[str, str], BodyMedia] | None = None
        self._templates: list[tuple[re.Pattern[str], str, BodyMedia]] = []

    def _load(self, spec: dict[str, Any]) -> dict[tuple[str, str], BodyMedia]:
        fixed: dict[tuple[str, str], BodyMedia] = {}
        for path, item in spec.get("paths", {}).items():
            for method, op in item.items():
                if not isinstance(op, dict):
                    continue
                body = op.get("requestBody")
                media = None if body is None else frozenset(body.get("content", {}))
                if "{" not in path:
                    fixed[(method.upper(), path)] = media
                    continue
                pattern = re.sub(r"\\\{[^}/]+\\\}", "[^/]+", re.escape(path))
                self._templates.append((re.compile(f"^{pattern}$"), method.upper(), media))
        return fixed

    def of(self, app: Any, scope: Scope) -> BodyMedia:
        """The declared media types of the operation a request goes to (None: none declared,
        or no such operation)."""
        if self._fixed is None:
            self._fixed = self._load(app.openapi())
        method, path = scope["method"], get_route_path(scope)
        if (method, path) in self._fixed:
            return self._fixed[(method, path)]
        for pattern, op_method, media in self._templates:
            if op_method == method and pattern.match(path):
                return media
        return None


def media_refusal(declared: BodyMedia, headers: dict[bytes, bytes]) -> str | None:
    """Why a request's body is refused (415) by the operation's declared media types, or None:
    a ``Content-Type`` it does not declare, or a body without one."""
    if declared is None:
        return None
    given = headers.get(b"content-type")
    if given is None:
        length = headers.get(b"content-length", b"0").strip()
        if b"transfer-encoding" not in headers and length in (b"0", b""):
            return None  # no body: the route says what is missing
        kind = "a body without a Content-Type"
    else:
        media = media_type(given.decode("latin-1"))
        if media in declared:
            return None
        kind = f"a body of media type {media or '(none)'!r}"
    return f"{kind} is not accepted here; send {', '.join(sorted(declared))}"
