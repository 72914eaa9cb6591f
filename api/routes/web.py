"""The planner's web page and the API documentation pages, all from files shipped in the
package (``api/static``; nothing is loaded from a CDN), and ``POST /v1/plans/validate``: the
job submission's validation and pre-work checks as a dry run, with a preview of what the page
draws (expanded candidate sites, UE map points).

* ``GET /`` – the single-page planner (``static/index.html`` + ``app.js`` + ``app.css``);
* ``GET /docs`` – Swagger UI, ``GET /redoc`` – ReDoc, from the vendored ``swagger-ui-dist``
  and ``redoc`` bundles under ``static/vendor`` (versions in ``static/vendor/VENDORED.md``);
* ``GET /static/...`` – the files themselves.
"""

from __future__ import annotations

import base64
import hashlib
import math
import re
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from fastapi import APIRouter, Depends, FastAPI, Request
from fastapi.openapi.docs import (
    get_redoc_html,
    get_swagger_ui_html,
    get_swagger_ui_oauth2_redirect_html,
)
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse, Response
from fastapi.staticfiles import StaticFiles
from pydantic import BaseModel, Field

from api.deps import get_settings
from api.documents import document_body, json_document, local_plan
from api.errors import GIS_EXTRA_RESPONSE, TOO_LARGE_RESPONSE
from api.models import plan_examples
from api.offload import Answer, ParsePool
from api.security import PAGE_CSP, docs_csp
from api.settings import Settings
from ris_planner.io.candidates import in_document_coordinates
from ris_planner.model.search_methods import count_method
from ris_planner.planning.inputs.sites import candidate_json
from ris_planner.planning.inputs.ue_maps import PointMap
from ris_planner.planning.prepare import prepare_plan

STATIC_DIR = Path(__file__).resolve().parent.parent / "static"
"""The shipped page and vendored assets (package data of ``api``)."""

PREVIEW_MAX_POINTS = 5000
"""UE map points returned per map by the validation preview (every k-th point beyond it)."""


def inline_script_hashes(html: str) -> list[str]:
    """SHA-256 (base64) of each inline ``<script>`` of a page, for its CSP."""
    bodies = re.findall(r"<script(?![^>]*\bsrc=)[^>]*>(.*?)</script>", html, flags=re.S)
    return [base64.b64encode(hashlib.sha256(b.encode()).digest()).decode() for b in bodies]


def _with_csp(page: HTMLResponse) -> HTMLResponse:
    """The page with a CSP admitting its own inline start-up script (and nothing else inline)."""
    html = bytes(page.body).decode("utf-8")
    return HTMLResponse(
        html, headers={"Content-Security-Policy": docs_csp(inline_script_hashes(html))}
    )


router = APIRouter(tags=["jobs"])


class MapPreview(BaseModel):
    """A UE map as the engine expanded it (grids, roads and CSV rows to points)."""

    total: int = Field(ge=1, description="Points in the map (after dropping zero weights)")
    stride: int = Field(ge=1, description="Every stride-th point is listed")
    points: list[list[float]] = Field(description="Listed positions [x, y, z] in metres")
    weights: list[float] = Field(description="Relative weights of the listed points")


class PlanPreview(BaseModel):
    """The answer of ``POST /v1/plans/validate``: the document passed every check that job
    submission and the start of the job run, and this is what the job would work on."""

    valid: bool = Field(description="Always true (an invalid document is a 422 / 413)")
    sites: int = Field(ge=1, description="Candidate sites after expanding walls")
    pairs: int = Field(ge=1, description="TX–RX pairs the search scores")
    tx_points: int = Field(ge=1, description="Points of the TX map")
    rx_points: int = Field(ge=1, description="Points of the RX map")
    layouts: dict[str, int] = Field(description="Per RIS count: C(sites, count) layouts")
    methods: dict[str, str] = Field(
        description="Per RIS count: the search that runs it (exhaustive, greedy, district …)"
    )
    search_method: dict[str, str] = Field(
        description="The plan's search: requested, used (auto resolved, as the job resolves"
        " it) and why"
    )
    sizing_search_method: dict[str, str] | None = Field(
        None, description="The sizing question's search (requested, used, why), with sizing"
    )
    candidates: list[dict[str, Any]] = Field(
        description="Every candidate site: index, position [m], orientation [rad], name"
    )
    tx_map: MapPreview = Field(description="The TX map's points (every stride-th)")
    rx_map: MapPreview = Field(description="The RX map's points (every stride-th)")
    dropped: dict[str, int] = Field(
        default_factory=dict,
        description="UE map points inside buildings per map (tx, rx): the plan drops them, and"
        " tx_map and rx_map list only the points it keeps",
    )
    obstacles: list[dict[str, Any]] = Field(
        default_factory=list,
        description="environment.obstacles in the local metres the job works in (a geographic"
        " document's converted from its frame)",
    )
    frame: dict[str, Any] | None = Field(
        None,
        description="A geographic document's frame: origin [lon, lat, h] and local_crs (the"
        " local transverse Mercator frame of every position above); null for local documents",
    )


def _map_preview(pm: PointMap) -> MapPreview:
    n = len(pm.points)
    stride = max(1, math.ceil(n / PREVIEW_MAX_POINTS))
    return MapPreview(
        total=n,
        stride=stride,
        points=np.round(pm.points[::stride], 6).tolist(),
        weights=pm.weights[::stride].tolist(),
    )


@router.post(
    "/plans/validate",
    response_model=PlanPreview,
    responses={**TOO_LARGE_RESPONSE, **GIS_EXTRA_RESPONSE},
    summary="Check a plan document without starting a job (dry run of POST /v1/plans)",
    openapi_extra=document_body(
        "PlanDocument",
        "The plan document, as for POST /v1/plans (local metres or a geographic frame)",
        plan_examples(),
    ),
)
async def validate_plan(
    request: Request, settings: Annotated[Settings, Depends(get_settings)]
) -> Response:
    """The validation of ``POST /v1/plans`` (a geographic document converted from its frame
    first; 422 with the field paths, 413 naming the limit, 501 without the GIS extra) plus the
    checks the job makes before it computes anything (RIS counts against the sites, pair and
    site-cache limits: 422 / 413); nothing is queued. The answer previews the expanded sites,
    maps and obstacles in local metres, with the document's frame."""
    body = await request.body()
    pool: ParsePool = request.app.state.parse_pool
    answer: Answer = await pool.run(preview_answer, body, settings.job_memory_mb)
    return answer.response()


def preview_answer(body: bytes, memory_mb: int) -> Answer:
    """:func:`_preview` rendered (in a parse process, :mod:`api.offload`)."""
    return Answer.of(JSONResponse(_preview(body, memory_mb).model_dump(mode="json")))


def _preview(body: bytes, memory_mb: int) -> PlanPreview:
    request = local_plan(json_document(body), memory_mb)
    frame = request.frame
    with in_document_coordinates(frame):  # sites inside buildings named as the document has them
        inputs = prepare_plan(request.admitted)
    n_sites = len(inputs.sites)
    search = inputs.document.search
    layouts = {str(c): math.comb(n_sites, c) for c in inputs.counts}
    methods = {c: count_method(search.method, n, search.max_exhaustive) for c, n in layouts.items()}
    env = inputs.document.environment
    return PlanPreview(
        valid=True,
        sites=n_sites,
        pairs=inputs.pairs.size,
        tx_points=len(inputs.tx_map.points),
        rx_points=len(inputs.rx_map.points),
        layouts=layouts,
        methods=methods,
        search_method=inputs.choice.to_json(),
        sizing_search_method=None
        if inputs.sizing_choice is None
        else inputs.sizing_choice.to_json(),
        candidates=[{"index": i, **candidate_json(s)} for i, s in enumerate(inputs.sites)],
        tx_map=_map_preview(inputs.tx_map),
        rx_map=_map_preview(inputs.rx_map),
        dropped=dict(inputs.dropped),
        obstacles=[] if env is None else env.model_dump(mode="json")["obstacles"],
        frame=None if frame is None else frame.describe(),
    )


def install_web(app: FastAPI) -> None:
    """Serve the page, the static files and local ``/docs`` + ``/redoc`` on ``app`` (created
    with ``docs_url=None, redoc_url=None`` so FastAPI's CDN-based pages are not registered)."""
    app.mount("/static", StaticFiles(directory=STATIC_DIR), name="static")
    pages = APIRouter(include_in_schema=False)
    title = app.title
    openapi_url = app.openapi_url or "/openapi.json"
    oauth_redirect = "/docs/oauth2-redirect"

    @pages.get("/", response_class=HTMLResponse)
    def index() -> FileResponse:
        return FileResponse(
            STATIC_DIR / "index.html",
            media_type="text/html",
            headers={"Content-Security-Policy": PAGE_CSP, "Cache-Control": "no-cache"},
        )

    @pages.get("/docs", response_class=HTMLResponse)
    def swagger_ui() -> HTMLResponse:
        return _with_csp(docs_page())

    def docs_page() -> HTMLResponse:
        return get_swagger_ui_html(
            openapi_url=openapi_url,
            title=f"{title} – Swagger UI",
            swagger_js_url="/static/vendor/swagger-ui/swagger-ui-bundle.js",
            swagger_css_url="/static/vendor/swagger-ui/swagger-ui.css",
            swagger_favicon_url="/static/favicon.svg",
            oauth2_redirect_url=oauth_redirect,
            swagger_ui_parameters={"validatorUrl": None},
        )

    @pages.get(oauth_redirect, response_class=HTMLResponse)
    def swagger_redirect() -> HTMLResponse:
        return _with_csp(get_swagger_ui_oauth2_redirect_html())

    @pages.get("/redoc", response_class=HTMLResponse)
    def redoc() -> HTMLResponse:
        return _with_csp(redoc_page())

    def redoc_page() -> HTMLResponse:
        return get_redoc_html(
            openapi_url=openapi_url,
            title=f"{title} – ReDoc",
            redoc_js_url="/static/vendor/redoc/redoc.standalone.js",
            redoc_favicon_url="/static/favicon.svg",
            with_google_fonts=False,
        )

    app.include_router(pages)
