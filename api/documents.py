"""Documents in request bodies: read the raw body, convert a geographic ``frame`` to local
metres (:func:`ris_planner.io.frames.to_local`, the one boundary the command line uses too),
then validate – so every route that takes a document takes it in local metres or in WGS84 /
projected coordinates alike.

The routes read their bodies themselves (FastAPI would validate the body model before any
conversion and refuse ``frame``); their OpenAPI request bodies are :func:`document_body`:
the local document's schema, or any object with a ``frame`` (:class:`GeoFrame`).
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import FastAPI
from fastapi.exceptions import RequestValidationError
from pydantic import BaseModel, ConfigDict, Field
from pydantic.json_schema import models_json_schema

from ris_planner.core.io_json import parse_json
from ris_planner.environment.model import Environment
from ris_planner.io.candidates import CandidateOptions
from ris_planner.io.frames import MAX_CRS_CHARS
from ris_planner.io.plan_request import PlanRequest, admit_request
from ris_planner.model.limits import prescan_document
from ris_planner.model.plan import LayoutBeamsDocument, UEMap
from ris_planner.model.scenario import Scenario
from ris_planner.planning import PlanDocument

Longitude = Annotated[float, Field(ge=-180, le=180, strict=True, description="Longitude [deg]")]
Latitude = Annotated[
    float, Field(ge=-84, le=84, strict=True, description="Latitude [deg] (polar sites refused)")
]
Number = Annotated[float, Field(strict=True, allow_inf_nan=False)]
"""A coordinate: a JSON number (a boolean or a string is refused, as in every document)."""


class GeoFrame(BaseModel):
    """A document's WGS84 frame (README "Real sites and GIS"): ``origin`` [lon, lat(, h)] – the
    document's coordinates are then [lon, lat(, h)]."""

    model_config = ConfigDict(extra="forbid")

    origin: tuple[Longitude, Latitude] | tuple[Longitude, Latitude, Number] = Field(
        description="[lon, lat(, h)]: WGS84 degrees (|lat| ≤ 84°), height in metres"
    )


class CrsFrame(BaseModel):
    """A document's projected frame: its coordinates are metres of ``crs``; ``origin`` in the
    same CRS (default: the bounding-box centre of the document's positions)."""

    model_config = ConfigDict(extra="forbid")

    crs: str = Field(
        min_length=1,
        max_length=MAX_CRS_CHARS,
        pattern=r"\S",
        description="A projected CRS in metres, e.g. 'EPSG:32635' (UTM 35N): an EPSG code, a PROJ"
        " string or WKT, not blank (an unknown or geographic CRS is a 422)",
    )
    origin: tuple[Number, Number] | tuple[Number, Number, Number] | None = Field(
        None, description="[E, N(, h)] in the CRS's metres"
    )


class GeoDocument(BaseModel):
    """The same document in geographic coordinates: every field as in the local document,
    positions in the frame's coordinates; converted to local metres before validation (the
    field paths of a 422 are those of the document)."""

    model_config = ConfigDict(extra="allow")

    frame: GeoFrame | CrsFrame = Field(description="The frame of the document's coordinates")
    license: str | None = Field(
        None,
        max_length=2000,
        description="Licence of the site data (an import copies it from its input, e.g."
        " '© OpenStreetMap contributors, ODbL 1.0'); carried into plan.json, plan.geojson,"
        " heatmap.tif and points.csv",
    )
    attribution: str | None = Field(
        None, max_length=2000, description="Attribution of the site data (carried like license)"
    )


class SiteDocument(BaseModel):
    """What ``POST /v1/site/preview`` reads of a plan document: its UE maps, its obstacles and
    its frame; every other field is ignored (a site before any candidate is placed)."""

    model_config = ConfigDict(extra="allow")

    tx_map: UEMap | None = Field(None, description="The TX map (in the frame's coordinates)")
    rx_map: UEMap | None = Field(None, description="The RX map (in the frame's coordinates)")
    environment: Environment | None = Field(None, description="The obstacles")
    frame: GeoFrame | CrsFrame | None = Field(
        None, description="The frame of the document's coordinates (absent: local metres)"
    )


DOCUMENT_MODELS: tuple[type[BaseModel], ...] = (
    PlanDocument,
    Scenario,
    LayoutBeamsDocument,
    GeoDocument,
    CandidateOptions,
    SiteDocument,
)
"""Models the request bodies of :func:`document_body` refer to (added to the OpenAPI
components by :func:`install_document_schemas`)."""


def document_body(
    schema: str | tuple[str, ...], description: str, examples: dict[str, Any]
) -> dict[str, Any]:
    """The ``openapi_extra`` of a route that reads a document itself: the local document
    (``#/components/schemas/{schema}``, or one of several) or a :class:`GeoDocument`."""
    names = (schema,) if isinstance(schema, str) else schema
    refs = [{"$ref": f"#/components/schemas/{name}"} for name in (*names, "GeoDocument")]
    return {
        "requestBody": {
            "required": True,
            "description": description,
            "content": {"application/json": {"schema": {"anyOf": refs}, "examples": examples}},
        }
    }


def install_document_schemas(app: FastAPI) -> None:
    """Add :data:`DOCUMENT_MODELS` (and the models they use) to ``app``'s OpenAPI components."""
    generate = app.openapi

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            schema = generate()
            _, defs = models_json_schema(
                [(m, "validation") for m in DOCUMENT_MODELS],
                ref_template="#/components/schemas/{model}",
            )
            components = schema.setdefault("components", {}).setdefault("schemas", {})
            for name, definition in defs.get("$defs", {}).items():
                components.setdefault(name, definition)
        return app.openapi_schema or {}

    app.openapi = openapi  # type: ignore[method-assign]


def json_document(body: bytes) -> Any:
    """The JSON value of a request body: 422 ``body: Field required`` when empty, 400 when it is
    not JSON (the shapes FastAPI gives a declared body), 413 when a list exceeds its limit
    (:func:`ris_planner.model.limits.prescan_document`, before validation)."""
    if not body.strip():
        raise RequestValidationError(
            [{"type": "missing", "loc": ("body",), "msg": "Field required"}]
        )
    value = parse_json(body, "request body")  # MalformedJsonError → 400, too many digits → 413
    prescan_document(value)  # list sizes → 413 before any model validation
    return value


def local_plan(document: Any, memory_mb: int) -> PlanRequest:
    """A plan document as sent → its admitted request (:func:`~ris_planner.io.plan_request.
    admit_request`): converted at the boundary, validated (422 naming the field), its search
    chosen (422 naming an option the method cannot honour), sizes checked against their limits
    and the job memory budget (413), its resources estimated – as ``ris-planner plan`` and the
    job itself do."""
    return admit_request(document, memory_mb)
