"""``POST /v1/sites``: candidate RIS sites generated on a site's facades and along its roads –
``ris-planner sites`` over HTTP (the same function,
:func:`ris_planner.io.candidates.candidate_sites`; docs/guides/candidates.md).

Body ``{"site": <GeoJSON FeatureCollection in WGS84, or an imported document with a frame>,
"options": <CandidateOptions>}`` → 200 with the candidate FeatureCollection (Point features in
WGS84, top-level ``frame`` and the input's licence) and a top-level ``summary`` member. It is
synchronous (about a second for a few blocks): the body is refused above the body limit
before it is read (413), parsed and validated in a worker thread (422 naming ``options.…``
fields or the site's feature), and the layout's size is checked against the site and
visibility limits before any visibility test (413).
"""

from __future__ import annotations

from typing import Any

import anyio
from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse
from pydantic import BaseModel, ConfigDict, Field

from api.documents import json_document
from api.errors import GIS_EXTRA_RESPONSE, TOO_LARGE_RESPONSE, ErrorBody
from api.models import site_geojson
from ris_planner.io.candidates import CandidateOptions, candidate_sites

router = APIRouter(tags=["import"])


class SitesRequest(BaseModel):
    """The body of ``POST /v1/sites``."""

    model_config = ConfigDict(extra="forbid")

    site: dict[str, Any] = Field(
        description="A GeoJSON FeatureCollection of buildings and roads (WGS84 [lon, lat]), or an"
        " imported document with a frame (environment prisms, ue_map / tx_map / rx_map): the"
        " output of POST /v1/import"
    )
    options: CandidateOptions = Field(
        default_factory=CandidateOptions, description="Layout options (defaults documented)"
    )


class SitesAnswer(BaseModel):
    """The answer: a GeoJSON FeatureCollection plus ``summary``."""

    model_config = ConfigDict(extra="allow")

    type: str = Field("FeatureCollection", description="Always FeatureCollection")
    frame: dict[str, Any] = Field(description='{"origin": [lon, lat, h]} of azimuth_deg, height_m')
    features: list[dict[str, Any]] = Field(
        description="Point features [lon, lat, h] with name, kind (facade | pole), azimuth_deg,"
        " tilt_deg, height_m, building, obstacle, facade, road, sees_points"
    )
    summary: dict[str, Any] = Field(
        description="candidates, by_kind, buildings, roads, ue_points, ue_points_inside,"
        " generated, dropped_inside, dropped_unseen, dropped_max_candidates,"
        " buildings_without_candidates (label → why), notes"
    )


def _request_schema() -> dict[str, Any]:
    """:class:`SitesRequest`'s JSON schema, its options a reference to the CandidateOptions
    component (:data:`api.documents.DOCUMENT_MODELS`)."""
    schema = SitesRequest.model_json_schema(ref_template="#/components/schemas/{model}")
    schema.pop("$defs", None)
    return schema


SITES_BODY: dict[str, Any] = {
    "requestBody": {
        "required": True,
        "description": "The site and the layout options",
        "content": {
            "application/json": {
                "schema": _request_schema(),
                "examples": {
                    "block": {
                        "summary": "A building and a street, default options",
                        "value": {"site": site_geojson(), "options": {}},
                    }
                },
            }
        },
    }
}


@router.post(
    "/sites",
    response_model=SitesAnswer,
    responses={
        **TOO_LARGE_RESPONSE,
        **GIS_EXTRA_RESPONSE,
        422: {
            "model": ErrorBody,
            "description": "Bad options (fields options.…) or an unusable site (the message"
            " names the feature)",
        },
    },
    summary="Generate candidate RIS sites on facades and along roads",
    openapi_extra=SITES_BODY,
)
async def post_sites(
    request: Request,
) -> JSONResponse:
    """Facade sites (every ``spacing_m`` along each wall, corner clearance at both ends, every
    mounting height below the roof, facing outward) and poles (every ``pole_spacing_m`` along
    the roads, facing across them), kept where they see a UE point; what
    ``ris-planner sites`` writes, with its summary. 413 above the body limit, or when the layout
    gives more sites or site × UE point legs than the generator's limits (before any visibility
    test); 422 naming the option or feature."""
    body = await request.body()

    def run() -> dict[str, Any]:
        req = SitesRequest.model_validate(json_document(body))
        collection, summary = candidate_sites(req.site, req.options)
        return {**collection, "summary": summary.to_json()}

    limiter: anyio.CapacityLimiter = request.app.state.parse_limiter
    return JSONResponse(await anyio.to_thread.run_sync(run, limiter=limiter))
