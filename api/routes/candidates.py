"""``POST /v1/candidates/convert``: candidate sites between the local metres the planner page
edits them in and the coordinates of a document's ``frame``, or from mounting-point GeoJSON.

The page draws and edits candidates in the local frame the job works in (x east, y north, z
up, metres; docs/guides/web-page.md). A geographic plan document (an import's, with
``"frame": {"origin": [lon, lat, h]}``) keeps its candidates in the frame's coordinates, so an
edited list goes back through this route before the document is validated or submitted. The
conversions are the service's own:

* document → local: :func:`ris_planner.io.frames.to_local`, the boundary every route that
  takes a document uses;
* GeoJSON sites (Point features with ``azimuth_deg``, ``tilt_deg``, ``height``/``height_m``,
  as ``POST /v1/sites`` answers or ``examples/helsinki/sites.geojson`` holds) → candidates:
  :func:`ris_planner.io.site_points.import_sites` at the frame's origin (what
  ``POST /v1/import`` does with a site file's points), then ``to_local``;
* local → document: the inverse of the frame's projection
  (:func:`~ris_planner.io.candidates.document_positions`: WGS84 frames through
  :meth:`~ris_planner.io.frames.Frame.to_geographic`; projected-CRS frames: the local
  transverse Mercator frame → the CRS), heights back in the frame's datum (z + h_origin).

Orientations (Euler yaw, pitch, roll in radians, yaw from local east) are the same in both:
:func:`~ris_planner.io.frames.to_local` converts positions only. Every answer lists the
candidates both ways, validated as plan candidates (422 naming ``local.N.field``).

``POST /v1/candidates/geojson`` writes candidates in local metres (the page's list, a plan's
``candidates``) as the candidates file of ``ris-planner sites`` – the same function,
:func:`ris_planner.io.candidates.candidates_geojson`: top-level ``frame`` and licence, WGS84
Points with ``azimuth_deg`` / ``tilt_deg`` / ``height_m`` – so the page's download is the
document the command line writes, and its import centres on the same origin.

``POST /v1/site/preview`` draws a document that cannot be planned yet (an imported site
before any candidate is placed): its obstacles and UE maps in local metres, as the preview of
``POST /v1/plans/validate`` lists them.
"""

from __future__ import annotations

from typing import Annotated, Any

import anyio
from fastapi import APIRouter, Body, Request
from fastapi.responses import JSONResponse
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from api.documents import GeoFrame, json_document
from api.errors import GIS_EXTRA_RESPONSE, TOO_LARGE_RESPONSE, size_limit
from api.models import plan_examples
from api.routes.web import MapPreview, _map_preview
from ris_planner.core.errors import DocumentFieldError, LimitExceededError, RisPlannerError
from ris_planner.environment.model import Environment
from ris_planner.io.candidates import (
    ATTRIBUTION_KEYS,
    SITE_PROPERTIES,
    candidates_geojson,
    document_positions,
)
from ris_planner.io.frames import MAX_LICENSE_CHARS, Frame, parse_frame, to_local
from ris_planner.io.site_points import import_sites
from ris_planner.model.limits import MAX_CANDIDATES
from ris_planner.model.plan import Candidate, UEMap
from ris_planner.planning.inputs.ue_maps import build_map

router = APIRouter(tags=["import"])

MAX_CONVERT_CANDIDATES = MAX_CANDIDATES
"""Candidates per request: a plan document's limit on explicit candidates (413 above it)."""


class CandidateConversion(BaseModel):
    """Exactly one of ``local``, ``document`` and ``sites``; ``frame`` is the plan document's
    (absent or null: a local document, whose coordinates are the local metres already)."""

    frame: GeoFrame | None = Field(None, description="The plan document's frame, if any")
    local: list[dict[str, Any]] | None = Field(
        None,
        max_length=MAX_CONVERT_CANDIDATES,
        description="Candidates in local metres: position [x, y, z], orientation [yaw, pitch,"
        " roll] in radians, name, cost",
    )
    document: list[dict[str, Any]] | None = Field(
        None,
        max_length=MAX_CONVERT_CANDIDATES,
        description="Candidates as the document holds them (the frame's coordinates)",
    )
    sites: dict[str, Any] | None = Field(
        None,
        description="A GeoJSON FeatureCollection (WGS84) of mounting Points with azimuth_deg"
        " (compass), tilt_deg (down) and height/height_m (above the frame's datum)",
    )

    @model_validator(mode="after")
    def _one_source(self) -> CandidateConversion:
        given = [k for k in ("local", "document", "sites") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(f"give exactly one of local, document, sites (got {given or 'none'})")
        if self.sites is not None and self.frame is None:
            raise ValueError("sites (WGS84 GeoJSON) need the document's frame")
        return self


class ConvertedCandidates(BaseModel):
    """The same candidates in both coordinate systems, in input order."""

    local: list[dict[str, Any]] = Field(description="Local metres (what the page draws)")
    document: list[dict[str, Any]] = Field(
        description="The frame's coordinates (what the plan document holds)"
    )


def _checked(cands: list[dict[str, Any]], where: str) -> list[dict[str, Any]]:
    """Plan candidates (:class:`Candidate` rules: a finite pose in range); defaults filled."""
    out = []
    for i, c in enumerate(cands):
        try:
            model = Candidate.model_validate(c)
        except ValidationError as exc:
            first = exc.errors()[0]
            loc = ".".join(str(p) for p in first["loc"])
            raise DocumentFieldError(
                f"{where}.{i}" + (f".{loc}" if loc else ""), first["msg"]
            ) from None
        out.append(model.model_dump(mode="json", exclude_none=True))
    return out


def _to_frame(frame: Frame, local: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Local candidates → the frame's coordinates (inverse of ``to_local``)."""
    if not local:
        return []
    geo = document_positions(frame, [c["position"] for c in local])
    return [{**c, "position": p} for c, p in zip(local, geo.tolist(), strict=True)]


def _local_of(frame_json: dict[str, Any], cands: list[dict[str, Any]]) -> list[dict[str, Any]]:
    local, _ = to_local({"frame": frame_json, "candidates": cands})
    out: list[dict[str, Any]] = local["candidates"]
    return out


def convert_candidates(req: CandidateConversion) -> ConvertedCandidates:
    """The conversion of :func:`post_convert` (pure; errors name the field)."""
    if req.frame is None:
        cands = req.local if req.local is not None else req.document
        same = _checked(cands or [], "local" if req.local is not None else "document")
        return ConvertedCandidates(local=same, document=[dict(c) for c in same])
    frame_json = req.frame.model_dump(mode="json", exclude_none=True)
    frame = parse_frame(frame_json, {"candidates": req.document or []})
    if req.local is not None:
        local = _checked(req.local, "local")
        return ConvertedCandidates(local=local, document=_to_frame(frame, local))
    if req.document is not None:
        local = _checked(_local_of(frame_json, req.document), "document")
        return ConvertedCandidates(
            local=local,
            document=[
                {**c, "position": d["position"]} for c, d in zip(local, req.document, strict=True)
            ],
        )
    assert req.sites is not None
    try:
        fragment, _ = import_sites(req.sites, frame.origin)
    except DocumentFieldError as exc:
        raise DocumentFieldError(f"sites.{exc.field}", exc.reason) from None
    except RisPlannerError as exc:
        raise DocumentFieldError("sites", str(exc)) from None
    geo = fragment.get("candidates") or []
    local = _checked(_local_of({"origin": list(frame.origin)}, geo), "sites")
    return ConvertedCandidates(local=local, document=_to_frame(frame, local))


EXAMPLE_FRAMED_CANDIDATES: dict[str, Any] = {
    "frame": {"origin": [24.9382, 60.17, 0.0]},
    "local": [
        {"position": [-10.0, 5.0, 6.0], "orientation": [3.14159, 0.2, 0.0]},
        {"position": [12.0, -4.0, 4.0], "name": "pole"},
    ],
}
"""Two candidates in local metres and the frame of their document (central Helsinki): the
OpenAPI examples of the candidate routes."""

CONVERT_EXAMPLES: dict[str, Any] = {
    "to_document": {
        "summary": "Two candidates in local metres → a WGS84 document's coordinates",
        "value": EXAMPLE_FRAMED_CANDIDATES,
    }
}
"""The OpenAPI example of ``POST /v1/candidates/convert``."""


@router.post(
    "/candidates/convert",
    response_model=ConvertedCandidates,
    summary="Candidate sites: local metres ↔ a document's frame; GeoJSON sites → candidates",
)
async def post_convert(
    body: Annotated[CandidateConversion, Body(openapi_examples=CONVERT_EXAMPLES)],
) -> ConvertedCandidates:
    """``local`` (what the planner page edits) → the document's coordinates; ``document`` →
    local metres (:func:`ris_planner.io.frames.to_local`); ``sites`` (WGS84 mounting Points,
    e.g. the answer of ``POST /v1/sites``) → both, through the import's
    :func:`~ris_planner.io.site_points.import_sites`. 422 naming the field; 501 on a server
    without the GIS extra when a frame is given."""
    return await anyio.to_thread.run_sync(convert_candidates, body)


class CandidatesFileRequest(BaseModel):
    """The body of ``POST /v1/candidates/geojson``: candidates in local metres and the frame
    (and licence) of their document."""

    model_config = ConfigDict(extra="forbid")

    frame: GeoFrame = Field(description='The frame of the document: {"origin": [lon, lat, h]}')
    local: list[dict[str, Any]] = Field(
        max_length=MAX_CONVERT_CANDIDATES,
        description="Candidates in local metres: position [x, y, z], orientation [yaw, pitch,"
        " roll] in radians, name, cost (the plan candidates of the page's list or of plan.json)",
    )
    properties: list[dict[str, Any] | None] | None = Field(
        None,
        max_length=MAX_CONVERT_CANDIDATES,
        description="Per candidate (null: none), what POST /v1/sites said of it ("
        + ", ".join(SITE_PROPERTIES)
        + "): written beside its pose, as ris-planner sites writes them",
    )
    license: str | None = Field(None, max_length=MAX_LICENSE_CHARS, description="Data licence")
    licence: str | None = Field(None, max_length=MAX_LICENSE_CHARS, description="Data licence")
    attribution: str | None = Field(None, max_length=MAX_LICENSE_CHARS, description="Attribution")
    copyright: str | None = Field(None, max_length=MAX_LICENSE_CHARS, description="Copyright")
    source: str | None = Field(None, max_length=MAX_LICENSE_CHARS, description="Data source")

    @model_validator(mode="after")
    def _aligned(self) -> CandidatesFileRequest:
        if self.properties is not None and len(self.properties) != len(self.local):
            raise ValueError(
                f"properties has {len(self.properties)} entries for {len(self.local)} candidates"
            )
        bad = sorted({k for p in self.properties or [] for k in p or {}} - set(SITE_PROPERTIES))
        if bad:
            raise ValueError(f"properties: unknown keys {bad}; allowed: {list(SITE_PROPERTIES)}")
        return self


class CandidatesFile(BaseModel):
    """A candidates file (:func:`ris_planner.io.candidates.candidates_geojson`)."""

    model_config = ConfigDict(extra="allow")

    type: str = Field("FeatureCollection", description="Always FeatureCollection")
    frame: dict[str, Any] = Field(description='{"origin": [lon, lat, h]} of azimuth_deg, height_m')
    features: list[dict[str, Any]] = Field(
        description="Point features [lon, lat, h] with name, azimuth_deg, tilt_deg, height_m"
        " (roll_deg, cost where not 0) and the given properties"
    )


def candidates_file(req: CandidatesFileRequest) -> dict[str, Any]:
    """The file of :func:`post_candidates_file` (pure; errors name the field)."""
    frame_json = req.frame.model_dump(mode="json", exclude_none=True)
    frame = parse_frame(frame_json)
    local = _checked(req.local, "local")
    members = {k: v for k in ATTRIBUTION_KEYS if isinstance(v := getattr(req, k), str)}
    return candidates_geojson(frame, local, members, req.properties)


FILE_EXAMPLES: dict[str, Any] = {
    "two": {
        "summary": "Two candidates of a document framed in central Helsinki",
        "value": {**EXAMPLE_FRAMED_CANDIDATES, "license": "© OpenStreetMap contributors, ODbL 1.0"},
    }
}
"""The OpenAPI example of ``POST /v1/candidates/geojson``."""


@router.post(
    "/candidates/geojson",
    response_model=CandidatesFile,
    summary="Candidate sites → the candidates file (what ris-planner sites writes)",
)
async def post_candidates_file(
    body: Annotated[CandidatesFileRequest, Body(openapi_examples=FILE_EXAMPLES)],
) -> JSONResponse:
    """Candidates in local metres (the page's list, or a plan's ``candidates``) → the GeoJSON
    candidates file of ``ris-planner sites`` and ``POST /v1/sites``, from the same function
    (:func:`ris_planner.io.candidates.candidates_geojson`): WGS84 Points with ``name``,
    ``azimuth_deg``, ``tilt_deg``, ``height_m``, the top-level ``frame`` the import reads the
    azimuths in, and the licence members given. ``properties`` carries what the generator said
    of a site (kind, building, sees_points, …). 422 naming ``local.N.field``; 501 on a server
    without the GIS extra."""
    return JSONResponse(await anyio.to_thread.run_sync(candidates_file, body))


class SitePreview(BaseModel):
    """What the page draws of a document before it can be planned."""

    tx_map: MapPreview | None = Field(description="The TX map's points (absent: none yet)")
    rx_map: MapPreview | None = Field(description="The RX map's points (absent: none yet)")
    obstacles: list[dict[str, Any]] = Field(description="environment.obstacles in local metres")
    frame: dict[str, Any] | None = Field(description="The frame (origin, local_crs), if any")


def site_preview(document: Any) -> SitePreview:
    """The obstacles and UE maps of a document (local or with a frame) in local metres; only
    these fields are validated (422 naming them)."""
    local, frame = to_local(document)
    if not isinstance(local, dict):
        raise DocumentFieldError("(document)", "a plan document is a JSON object")
    maps: dict[str, MapPreview | None] = {}
    for name in ("tx_map", "rx_map"):
        spec = local.get(name)
        maps[name] = (
            None if spec is None else _map_preview(build_map(_valid(UEMap, spec, name), name))
        )
    env = local.get("environment")
    obstacles = (
        []
        if env is None
        else _valid(Environment, env, "environment").model_dump(mode="json")["obstacles"]
    )
    return SitePreview(
        tx_map=maps["tx_map"],
        rx_map=maps["rx_map"],
        obstacles=obstacles,
        frame=None if frame is None else frame.describe(),
    )


def _valid(model: Any, value: Any, where: str) -> Any:
    try:
        return model.model_validate(value)
    except ValidationError as exc:
        size = size_limit(exc.errors())
        if size is not None:  # 413 with the limit, the field named from the document's top
            raise LimitExceededError(f"{where}.{size}", size.limit) from None
        first = exc.errors()[0]
        loc = ".".join(str(p) for p in first["loc"])
        raise DocumentFieldError(f"{where}.{loc}" if loc else where, first["msg"]) from None


@router.post(
    "/site/preview",
    response_model=SitePreview,
    responses={**TOO_LARGE_RESPONSE, **GIS_EXTRA_RESPONSE},
    summary="Obstacles and UE maps of a plan document in local metres (no candidates needed)",
    openapi_extra={
        "requestBody": {
            "required": True,
            "description": "A plan document, or the start of one (an import's): its tx_map,"
            " rx_map, environment and frame are read, in local metres or in the frame's"
            " coordinates; nothing else is needed",
            "content": {
                "application/json": {
                    "schema": {"$ref": "#/components/schemas/SiteDocument"},
                    "examples": plan_examples(),
                }
            },
        }
    },
)
async def post_site_preview(request: Request) -> SitePreview:
    """The parts of ``POST /v1/plans/validate``'s preview that need no candidate sites: the
    page draws an imported site with it before any candidate is placed. 422 naming the field;
    413 above the map-point limit; 501 for a frame without the GIS extra."""
    body = await request.body()
    return await anyio.to_thread.run_sync(lambda: site_preview(json_document(body)))
