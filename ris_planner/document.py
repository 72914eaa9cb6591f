"""The base of every JSON document model and the coordinate rule, shared by the scenario
document (:mod:`ris_planner.scenario`), its environment (:mod:`ris_planner.environment.model`) and
the plan and simulation documents."""

from __future__ import annotations

from typing import Annotated, Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError
from pydantic.json_schema import JsonDict
from pydantic_core import InitErrorDetails, PydanticCustomError

MIN_UE_RIS_DISTANCE_M = 1e-3
"""A UE closer than this to a RIS centre (or to the other UE) is rejected: the path gains of
the Simulation Parameters section diverge there (|ρ| ∝ 1/d)."""

MAX_COORDINATE_M = 1e6
"""Coordinates beyond ±1000 km are rejected as unit mistakes (mm or degrees passed as metres)."""

_COORDINATE_SCHEMA: JsonDict = {
    "type": "number",
    "minimum": -MAX_COORDINATE_M,
    "maximum": MAX_COORDINATE_M,
}
_POINT_SCHEMA: JsonDict = {
    "type": "array",
    "items": _COORDINATE_SCHEMA,
    "minItems": 3,
    "maxItems": 3,
}
_POINTS_SCHEMA: JsonDict = {
    "anyOf": [_POINT_SCHEMA, {"type": "array", "items": _POINT_SCHEMA, "minItems": 1}]
}
"""JSON-schema form of the bounds the validators enforce (documentation for OpenAPI clients)."""

Point3 = Annotated[
    list[float],
    Field(
        min_length=3,
        max_length=3,
        description="[x, y, z] in metres (global frame), each within ±1e6 m",
        json_schema_extra={"items": _COORDINATE_SCHEMA},
    ),
]


def finite_point(value: list[float], what: str) -> list[float]:
    """Finite coordinates within ±MAX_COORDINATE_M, as floats; a ValueError naming ``what``."""
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{what} must be finite numbers, got {value}")
    if np.any(np.abs(arr) > MAX_COORDINATE_M):
        raise ValueError(f"{what} must lie within ±{MAX_COORDINATE_M:g} m, got {value}")
    return [float(v) for v in arr]


class DocumentModel(BaseModel):
    """Base of every JSON document model: unknown fields are errors, instances are frozen."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)


def field_error(
    title: str, loc: tuple[str | int, ...], message: str, value: Any
) -> ValidationError:
    """A validation error at the field path ``loc`` (e.g. ``("tx", 3)``) for checks that need
    the whole document (a model validator's own errors carry no field path). Raised inside a
    validator, pydantic keeps the path and prefixes the enclosing fields' (CLI ``tx.3: …``,
    REST 422 ``fields[].field``)."""
    error = PydanticCustomError("value_error", "{message}", {"message": message})
    details = InitErrorDetails(type=error, loc=loc, input=value)
    return ValidationError.from_exception_data(title, [details])
