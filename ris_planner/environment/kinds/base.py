"""What every obstacle kind shares: the protocol a kind module implements, the common document
fields (heights, name, material) and the faces reflections use (docs/concepts/environment.md;
docs/guides/adding-an-obstacle-kind.md walks through writing one).

A kind is one module in :mod:`ris_planner.environment.kinds` that defines

* its pydantic model (a subclass of :class:`ObstacleModel` with a ``kind`` literal: the JSON
  discriminator), which knows its ``faces()`` (for reflections), its ``outline()`` (the 2-D
  points of its box) and its ``work_units()`` (the REST work limit);
* an :class:`ObstacleKind` object: ``pack`` turns a list of its obstacles into arrays and
  ``blocks`` is its exact narrow phase (one leg against one obstacle per row, numpy, the rules
  of :mod:`ris_planner.environment.scene`); a ``solid`` kind also answers ``depth`` (how far
  points lie inside), and ``compiled`` says whether the compiled engine
  (:mod:`ris_planner.environment._jit`) implements it (scenes with other kinds use numpy);
  ``point_fields`` names the fields that hold [x, y] points (a geographic document's are
  converted from its frame); ``to_geojson`` / ``from_geojson`` are its GeoJSON feature (the
  ``plan.geojson`` export and the import read each other's); ``draw`` tells the web page how
  to draw it (:data:`DRAW_SHAPES`);

and is registered in :data:`ris_planner.environment.kinds.KINDS`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, ClassVar, NamedTuple, Protocol

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from ris_planner.core.document import MAX_COORDINATE_M, DocumentModel
from ris_planner.environment.materials import DEFAULT_MATERIAL, Material

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int_]

ToOutput = Callable[[FloatArray], FloatArray]
"""Local [x, y] points [n, 2] → the coordinates a GeoJSON file holds ([lon, lat] with a frame,
else the same metres)."""

GeoJSON = dict[str, Any]
"""A GeoJSON geometry or a feature's ``properties``."""

DRAW_SHAPES: dict[str, tuple[str, ...]] = {
    "polygon": ("points",),
    "polyline": ("points",),
    "circle": ("center", "radius"),
}
"""The shapes of a kind's ``draw`` spec and the members each names fields with. ``points``: the
name of a field holding a list of [x, y] points, or a list of names of fields each holding
one; ``center``: a field holding one [x, y] point, ``radius``: a field holding metres; an
optional ``label`` names the kind in the page's legend (prism: "building"). The
page (``api/static/app.js``) reads the spec from ``GET /v1/obstacle-kinds`` and draws every
kind from it; a ``solid`` kind's polygon or circle is also its footprint there (the inside
check and the facade snap of candidates)."""


class Faces(NamedTuple):
    """Vertical rectangular faces of one obstacle (between its ``base_m`` and top), [F] rows:
    face f runs from ``start[f]`` to ``end[f]`` ([F, 2]); ``normal`` [F, 2] the unit horizontal
    normal of its front (reflecting) side; ``two_sided``: it reflects on both sides."""

    start: FloatArray
    end: FloatArray
    normal: FloatArray
    two_sided: bool


def label(kind: str, name: str | None) -> str:
    """How messages name an obstacle: "prism 'b1'" or "wall"."""
    return f"{kind} {name!r}" if name else kind


class ObstacleModel(DocumentModel):
    """The fields every obstacle has; a kind's model adds its geometry and ``kind`` literal."""

    kind_name: ClassVar[str] = ""
    kind: str

    name: str | None = Field(None, max_length=200, description="Label used in messages")
    base_m: float = Field(
        0.0,
        ge=0,
        le=MAX_COORDINATE_M,
        allow_inf_nan=False,
        description="z of the bottom [m] (≥ 0)",
    )
    height_m: float = Field(
        gt=0, le=1e5, allow_inf_nan=False, description="Vertical extent above base_m [m] (> 0)"
    )
    material: Material = Field(
        DEFAULT_MATERIAL,
        description="Facade material for reflections (ITU-R P.2040-1 Table 3; default concrete)",
    )

    @property
    def top_m(self) -> float:
        return self.base_m + self.height_m

    def faces(self) -> Faces:
        """The obstacle's vertical faces (reflections)."""
        raise NotImplementedError

    def outline(self) -> FloatArray:
        """[n, 2] points whose bounding box holds the obstacle's footprint."""
        raise NotImplementedError

    def work_units(self) -> int:
        """Cost of deciding one leg against it, in footprint edges (the REST work limit)."""
        raise NotImplementedError


class GeometryError(ValueError):
    """A GeoJSON geometry that is not the one a kind reads (the message says what it needs)."""


def coordinates(geometry: Any, kind: str, want: str) -> Any:
    """The ``coordinates`` of a GeoJSON geometry of type ``want``; else :class:`GeometryError`
    saying what a ``kind`` feature needs."""
    got = geometry.get("type") if isinstance(geometry, dict) else type(geometry).__name__
    if got != want:
        raise GeometryError(f"a {kind} feature's geometry is a {want}, got {got}")
    return geometry.get("coordinates")


def position_xy(position: Any) -> list[float]:
    """[x, y] of a GeoJSON position ([x, y] or [x, y, z]; a height is dropped: the obstacle's
    heights are its ``base_m`` and ``height_m``)."""
    if not isinstance(position, list | tuple) or len(position) not in (2, 3):
        raise GeometryError(f"a position is [x, y] or [x, y, z], got {position!r}")
    return list(position[:2])


class ObstacleKind(Protocol):
    """One obstacle kind (see the module docstring): every member is required."""

    name: str
    """The JSON ``kind`` value."""
    model: type[ObstacleModel]
    """Its document model (``kind: Literal[name]``)."""
    solid: bool
    """Points can lie inside it (``depth``; UE points and candidates inside are refused)."""
    compiled: bool
    """The compiled engine implements it (only the built-in kinds)."""
    point_fields: tuple[tuple[str, ...], ...]
    """Paths inside an obstacle of its [x, y] points (``*``: every list entry), e.g.
    ``(("footprint", "*"),)``; :func:`ris_planner.io.frames.to_local` converts them."""
    draw: dict[str, Any]
    """How the web page draws it: ``{"shape": …, …}`` of :data:`DRAW_SHAPES`."""

    def to_geojson(self, obstacle: Any, xy: ToOutput) -> tuple[GeoJSON, GeoJSON]:
        """(geometry, properties) of one obstacle's feature: its geometry with coordinates
        through ``xy`` and the properties its geometry does not hold (the fields every obstacle
        has are added by :func:`ris_planner.environment.kinds.geojson.obstacle_feature`)."""
        ...

    def from_geojson(self, geometry: GeoJSON, properties: GeoJSON) -> dict[str, Any]:
        """The fields of :meth:`to_geojson` back from a feature, in the geometry's coordinates
        (not validated; :class:`GeometryError` when the geometry is of another type)."""
        ...

    def pack(self, obstacles: list[Any]) -> Any:
        """Arrays of these obstacles (in the given order) for :meth:`blocks` and :meth:`depth`."""
        ...

    def blocks(
        self, packed: Any, rows: IntArray, a: FloatArray, b: FloatArray, tol: float
    ) -> BoolArray:
        """[K] whether leg a[k]–b[k] ([K, 3]) is blocked by obstacle rows[k] of ``packed``."""
        ...

    def depth(self, packed: Any, rows: IntArray, points: FloatArray) -> FloatArray:
        """[K] how far points[k] lie inside obstacle rows[k] (0 outside; non-solid kinds: 0)."""
        ...
