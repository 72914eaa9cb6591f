"""``POST /v1/import``: a site file (GeoJSON, OSM XML, DXF) as the raw request body → a starting
plan document, the import fragment and a report – ``ris-planner import FORMAT FILE --plan``
over HTTP (the same functions: :func:`ris_planner.io.site_import.import_data` and
:func:`~ris_planner.io.site_import.plan_from_import`).

The body is the file itself (no multipart): its size is refused by the service's body limit
before anything reads it (413), then it is parsed in a worker thread.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import APIRouter, Query, Request
from fastapi.responses import JSONResponse, Response
from pydantic import BaseModel, Field, StringConstraints

from api.errors import GIS_EXTRA_RESPONSE, TOO_LARGE_RESPONSE, ErrorBody
from api.models import SITE_OSM_XML, site_geojson
from api.offload import Answer, ParsePool
from ris_planner.core.errors import RisPlannerError
from ris_planner.io.dxf import LAYER_SPEC_PATTERN, parse_layer_spec
from ris_planner.io.import_options import (
    DEFAULT_AREA_STEP_M,
    DEFAULT_BUILDING_HEIGHT_M,
    DEFAULT_ROAD_STEP_M,
    DEFAULT_SITE_SPACING_M,
    DEFAULT_UE_HEIGHT_M,
    METRES_PER_LEVEL,
    ImportOptions,
)
from ris_planner.io.site_import import import_data, parse_origin, plan_from_import

router = APIRouter(tags=["import"])

Format = Literal["geojson", "osm", "sites", "dxf"]

MEDIA_FORMATS: dict[str, Format] = {
    "application/geo+json": "geojson",
    "application/json": "geojson",
    "application/xml": "osm",
    "text/xml": "osm",
    "application/osm+xml": "osm",
    "application/dxf": "dxf",
    "image/vnd.dxf": "dxf",
    "image/x-dxf": "dxf",
}
"""Content-Type → format, when the query gives none."""


class ImportAnswer(BaseModel):
    """The answer of ``POST /v1/import``."""

    document: dict[str, Any] = Field(
        description="A plan document of the site (frame, environment, candidates, tx_map ="
        " rx_map = the UE map, and the defaults listed in the report), ready for"
        " POST /v1/plans/validate"
    )
    fragment: dict[str, Any] = Field(
        description="What `ris-planner import` prints: the import in the input's coordinates"
    )
    report: dict[str, Any] = Field(
        description="format, the parser's counts (buildings, prisms, heights_from_levels,"
        " default_height – the features given the default height –, courtyards (inner rings"
        " kept open), roads, roads_skipped, areas, area_points, candidates, walls, skipped; for"
        " DXF units_to_m, walls, prisms, ignored), repaired / skipped_invalid (invalid"
        " outlines: feature index, id, name, lonlat, reason, areas before and after),"
        " tag_problems (tags that are not lengths and what was used instead), license, crs"
        " (a GeoJSON whose crs member names a projected CRS: converted to WGS84; given, crs,"
        " name, converted_to, positions), warnings (e.g. no buildings: every leg would be"
        " planned as clear), defaults_applied and notes"
    )


def _import_media(media: str) -> dict[str, Any]:
    """The OpenAPI entry of one media type the import takes (with an example for GeoJSON and
    OSM XML)."""
    fmt = MEDIA_FORMATS.get(media)
    if fmt == "geojson":
        example = {"summary": "A building and a street", "value": site_geojson()}
        return {"schema": {"type": "object"}, "examples": {"site": example}}
    if fmt == "osm":
        example = {"summary": "A building and a street", "value": SITE_OSM_XML}
        return {"schema": {"type": "string"}, "examples": {"site": example}}
    return {"schema": {"type": "string", "format": "binary"}}


IMPORT_BODY: dict[str, Any] = {
    "requestBody": {
        "required": True,
        "description": "The file itself: a GeoJSON FeatureCollection, OSM XML or a DXF drawing,"
        " sent with its media type (application/octet-stream for any format, with ?format=)",
        "content": {
            media: _import_media(media) for media in (*MEDIA_FORMATS, "application/octet-stream")
        },
    }
}


def _sniff(body: bytes) -> Format | None:
    head = body.lstrip()[:32]
    if head.startswith(b"{"):
        return "geojson"
    if head.startswith(b"<"):
        return "osm"
    if head.startswith(b"AutoCAD Binary DXF") or head.startswith(b"0"):
        return "dxf"
    return None


def detect_format(content_type: str | None, body: bytes) -> Format:
    """The format of a body without ``?format``: its Content-Type, else its first bytes."""
    media = (content_type or "").split(";")[0].strip().lower()
    fmt = MEDIA_FORMATS.get(media) or _sniff(body)
    if fmt is None:
        raise RisPlannerError(
            "format: give ?format=geojson|osm|sites|dxf (the Content-Type"
            f" {media or '(none)'!r} and the body's first bytes do not tell)"
        )
    return fmt


@router.post(
    "/import",
    response_model=ImportAnswer,
    responses={
        **TOO_LARGE_RESPONSE,
        **GIS_EXTRA_RESPONSE,
        422: {
            "model": ErrorBody,
            "description": "Not a usable file: the message names the feature, layer or option",
        },
    },
    summary="Import a site file (GeoJSON, OSM XML, DXF) into a plan document",
    openapi_extra=IMPORT_BODY,
)
async def post_import(
    request: Request,
    format: Annotated[
        Format | None,
        Query(
            description="geojson | osm | sites | dxf; default: from the Content-Type, else"
            " the body's first bytes ('{' GeoJSON, '<' OSM XML, else DXF)"
        ),
    ] = None,
    origin: Annotated[
        str | None,
        Query(
            max_length=100,
            description="Frame origin LON,LAT[,H] (default: the features' bounding-box centre)",
        ),
    ] = None,
    metres_per_level: Annotated[
        float, Query(gt=0, le=100, description="Storey height for building:levels [m]")
    ] = METRES_PER_LEVEL,
    default_height: Annotated[
        float, Query(gt=0, le=1000, description="Height of a building with no height [m]")
    ] = DEFAULT_BUILDING_HEIGHT_M,
    road_step: Annotated[
        float, Query(gt=0, le=1000, description="UE sampling step along and across roads [m]")
    ] = DEFAULT_ROAD_STEP_M,
    ue_height: Annotated[
        float, Query(ge=0, le=1000, description="Height of imported UE positions [m]")
    ] = DEFAULT_UE_HEIGHT_M,
    density_key: Annotated[
        str,
        Query(min_length=1, max_length=100, description="Property of UE density polygons"),
    ] = "density",
    area_step: Annotated[
        float,
        Query(gt=0, le=1000, description="Grid step inside density areas (DXF: the UE grid) [m]"),
    ] = DEFAULT_AREA_STEP_M,
    site_spacing: Annotated[
        float,
        Query(gt=0, le=1000, description="Site spacing along imported mounting lines [m]"),
    ] = DEFAULT_SITE_SPACING_M,
    highways: Annotated[
        str | None, Query(max_length=1000, description="Road classes, comma-separated")
    ] = None,
    layer: Annotated[
        list[Annotated[str, StringConstraints(min_length=3, pattern=LAYER_SPEC_PATTERN)]] | None,
        Query(
            max_length=100,
            description="dxf: LAYER=wall:HEIGHT_M or"
            " LAYER=prism:HEIGHT_M[:BASE_M] (repeat the parameter)",
        ),
    ] = None,
    units: Annotated[
        Literal["mm", "cm", "m", "in", "ft"] | None, Query(description="dxf: override $INSUNITS")
    ] = None,
    invalid: Annotated[
        Literal["repair", "skip", "error"],
        Query(
            description="Invalid outlines (self-intersecting, unclosed, degenerate): repair"
            " (shapely make_valid; listed in report.repaired), skip (listed in"
            " report.skipped_invalid) or error (422 naming the feature)"
        ),
    ] = "repair",
    swap_check: Annotated[
        bool,
        Query(
            description="Run the file-wide lat/lon swap test (building corners square only"
            " when read as [lat, lon]); the per-feature and origin checks always run"
        ),
    ] = True,
) -> Response:
    """The options are those of ``ris-planner import`` (``docs/guides/import.md``). 422 naming
    the feature by index, id, name and lon/lat in its message and ``features.N`` as its field
    (an invalid outline with ``invalid=error``, lat/lon swapped, a site without azimuth), the
    ``origin`` (swapped or far from the features), the ``crs`` member (a CRS that PROJ does
    not know: its value and how to convert the file), the layer (a DXF without the chosen
    layers) or the option; 413 above the body limit; 501 on a server without the GIS
    extra."""
    body = await request.body()
    options = ImportOptions(
        metres_per_level=metres_per_level,
        default_height_m=default_height,
        road_step_m=road_step,
        ue_height_m=ue_height,
        density_key=density_key,
        area_step_m=area_step,
        site_spacing_m=site_spacing,
        highways=tuple(h for h in highways.split(",") if h) if highways else None,
        invalid=invalid,
        swap_check=swap_check,
    )
    content_type = request.headers.get("content-type")
    pool: ParsePool = request.app.state.parse_pool
    args = (body, format, content_type, tuple(layer or ()), options, origin, units)
    answer: Answer = await pool.run(import_answer, *args)
    return answer.response()


def import_answer(
    body: bytes,
    format: Format | None,
    content_type: str | None,
    layer: tuple[str, ...],
    options: ImportOptions,
    origin: str | None,
    units: Any,
) -> Answer:
    """The import's answer, rendered (a parse process runs it, :mod:`api.offload`: the parsed
    file and the document never exist in the server process)."""
    fmt = format or detect_format(content_type, body)
    layers = dict(parse_layer_spec(s) for s in layer)
    fragment, summary = import_data(
        body, fmt, options, parse_origin(origin), layers, units, what="request body"
    )
    document, report = plan_from_import(fragment, fmt, summary, options)
    answer = ImportAnswer(document=document, fragment=fragment, report=report.to_json())
    return Answer.of(JSONResponse(answer.model_dump(mode="json")))
