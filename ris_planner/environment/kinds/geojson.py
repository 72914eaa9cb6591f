"""Obstacles as GeoJSON features and back, for every registered kind
(docs/guides/adding-an-obstacle-kind.md): the fields every obstacle has go to and from the
feature's properties here; each kind's ``to_geojson`` / ``from_geojson`` handles its geometry
and its own fields. The ``plan.geojson`` export writes these features
(:mod:`ris_planner.io.export`) and the GeoJSON import reads them back (a feature whose
properties carry an obstacle ``kind``), so an exported plan re-imports the same obstacles.
"""

from __future__ import annotations

from typing import Any

from ris_planner.environment.kinds import kind_named, kind_of
from ris_planner.environment.kinds.base import GeoJSON, ObstacleModel, ToOutput

COMMON_PROPERTIES = ("name", "base_m", "height_m", "material")
"""The fields of every obstacle (:class:`~ris_planner.environment.kinds.base.ObstacleModel`
beside ``kind``) that a feature carries as properties of the same name."""


def obstacle_feature(
    obstacle: ObstacleModel, xy: ToOutput, z0: float = 0.0
) -> tuple[GeoJSON, GeoJSON]:
    """(geometry, properties) of an obstacle in local metres: its kind's geometry through
    ``xy``, ``kind`` and :data:`COMMON_PROPERTIES` (``base_m`` plus ``z0``, the frame origin's
    height) and the kind's own properties."""
    kind = kind_of(obstacle)
    geometry, own = kind.to_geojson(obstacle, xy)
    props: dict[str, Any] = {"kind": kind.name}
    props |= {k: getattr(obstacle, k) for k in COMMON_PROPERTIES}
    props["base_m"] = float(obstacle.base_m) + z0
    return geometry, props | own


def obstacle_from_feature(geometry: GeoJSON, properties: GeoJSON) -> dict[str, Any]:
    """The obstacle (a document dict, in the geometry's coordinates, not validated) of a
    feature whose properties name its ``kind``; :class:`UnknownObstacleKindError` /
    :class:`~ris_planner.environment.kinds.base.GeometryError` say what is wrong."""
    kind = kind_named(properties.get("kind"))
    out: dict[str, Any] = {"kind": kind.name}
    out |= {k: properties[k] for k in COMMON_PROPERTIES if properties.get(k) is not None}
    return out | kind.from_geojson(geometry, properties)
