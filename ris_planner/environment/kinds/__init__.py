"""The obstacle kinds: one module per kind (its pydantic model, faces, narrow phase, GeoJSON
feature and drawing, see :mod:`ris_planner.environment.kinds.base`), registered here.

Adding a kind (docs/guides/adding-an-obstacle-kind.md): write ``kinds/<name>.py`` with a model
(``kind: Literal["<name>"]``) and a ``KIND`` object implementing
:class:`~ris_planner.environment.kinds.base.ObstacleKind`, and add it to :data:`KINDS` (or call
:func:`register`). Everything that reads, writes or draws obstacles takes their kinds from
here at the time it runs: the document model (:mod:`ris_planner.environment.model`), the
visibility engine (:class:`~ris_planner.environment.scene.Scene`), the GeoJSON export and
import (:mod:`ris_planner.environment.kinds.geojson`), a geographic document's conversion
(:func:`point_paths`) and the web page (``GET /v1/obstacle-kinds``, :func:`describe_kinds`).
An obstacle of an unregistered kind is an error naming the known kinds, in a document (422
over REST) and in the engine.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ris_planner.environment.kinds import prism, wall
from ris_planner.environment.kinds.base import (
    BoolArray,
    Faces,
    FloatArray,
    ObstacleKind,
    ObstacleModel,
)

KINDS: dict[str, ObstacleKind] = {k.name: k for k in (prism.KIND, wall.KIND)}
"""Every obstacle kind, by its JSON ``kind`` value."""


class UnknownObstacleKindError(ValueError):
    """An obstacle whose ``kind`` is not registered in :data:`KINDS`."""


def known_kinds() -> str:
    """'prism, wall': the registered kinds, for messages."""
    return ", ".join(sorted(KINDS))


def kind_of(obstacle: Any) -> ObstacleKind:
    """The registered kind of an obstacle model, or :class:`UnknownObstacleKindError`."""
    name = getattr(obstacle, "kind", None)
    kind = KINDS.get(name) if isinstance(name, str) else None
    if kind is None or not isinstance(obstacle, kind.model):
        raise UnknownObstacleKindError(
            f"unknown obstacle kind {name!r} ({type(obstacle).__name__}); known kinds:"
            f" {known_kinds()}"
        )
    return kind


def kind_named(name: Any) -> ObstacleKind:
    """The registered kind called ``name``, or :class:`UnknownObstacleKindError`."""
    kind = KINDS.get(name) if isinstance(name, str) else None
    if kind is None:
        raise UnknownObstacleKindError(
            f"unknown obstacle kind {name!r}; known kinds: {known_kinds()}"
        )
    return kind


def register(kind: ObstacleKind) -> None:
    """Add a kind to :data:`KINDS` (at run time: documents validated from now on accept it;
    the service's OpenAPI schema lists the kinds of its start)."""
    if kind.name in KINDS:
        raise ValueError(f"obstacle kind {kind.name!r} is registered already")
    if getattr(kind.model, "kind_name", None) != kind.name:
        raise ValueError(f"obstacle kind {kind.name!r}: its model's kind_name differs")
    KINDS[kind.name] = kind


def unregister(name: str) -> None:
    """Remove the kind ``name`` from :data:`KINDS` (the inverse of :func:`register`)."""
    del KINDS[name]


def describe_kinds() -> list[dict[str, Any]]:
    """Every kind as the web page needs it: ``{"kind", "solid", "draw"}`` (``GET
    /v1/obstacle-kinds``)."""
    return [{"kind": k.name, "solid": k.solid, "draw": k.draw} for k in KINDS.values()]


def point_paths() -> list[tuple[str, ...]]:
    """The paths of [x, y] points inside an obstacle, over every registered kind (a path a kind
    lacks is absent from its obstacles)."""
    return list(dict.fromkeys(p for k in KINDS.values() for p in k.point_fields))


def footprint_contains(obstacle: ObstacleModel, xy: FloatArray) -> BoolArray:
    """[n] whether points [n, 2] lie inside a solid obstacle's footprint, off its boundary
    (its depth at mid-height is positive; a kind that is not solid holds no point)."""
    kind = kind_of(obstacle)
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    if not kind.solid or not len(xy):
        return np.zeros(len(xy), dtype=bool)
    z = np.full(len(xy), obstacle.base_m + 0.5 * obstacle.height_m)
    rows = np.zeros(len(xy), dtype=int)
    depth = kind.depth(kind.pack([obstacle]), rows, np.column_stack([xy, z]))
    return np.asarray(depth > 0)


__all__ = [
    "KINDS",
    "Faces",
    "ObstacleKind",
    "ObstacleModel",
    "UnknownObstacleKindError",
    "describe_kinds",
    "footprint_contains",
    "kind_named",
    "kind_of",
    "known_kinds",
    "point_paths",
    "register",
    "unregister",
]
