"""The ``environment`` of scenario and plan documents: obstacles (docs/concepts/environment.md, "The
contract"). Pydantic models only – the JSON contract; the
visibility engine that uses them is :mod:`ris_planner.environment`.

* ``prism``: a vertical extrusion of a simple polygon ``footprint`` ([x, y] vertices in
  metres, any winding, convex or not) between z = ``base_m`` and z = ``base_m + height_m``.
* ``wall``: a zero-thickness vertical rectangle over ``start``–``end`` between the same heights.
"""

from __future__ import annotations

from typing import Annotated, Literal, NamedTuple

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, field_validator, model_validator

from ris_planner.document import MAX_COORDINATE_M, DocumentModel, finite_point
from ris_planner.environment.materials import DEFAULT_MATERIAL, Material

FloatArray = NDArray[np.float64]

MIN_FOOTPRINT_AREA_M2 = 1e-6
"""A footprint with a smaller area (1 mm²) is degenerate (collinear or repeated vertices)."""

MIN_EDGE_M = 1e-6
"""Footprint edges and walls shorter than 1 µm are degenerate."""

MAX_FOOTPRINT_VERTICES = 10_000
"""Vertices per footprint (OSM buildings have tens; a city block outline a few hundred)."""

MAX_OBSTACLES = 100_000
"""Obstacles per environment."""

Point2 = Annotated[
    list[float],
    Field(min_length=2, max_length=2, description="[x, y] in metres (global frame)"),
]


class Faces(NamedTuple):
    """Vertical rectangular faces of one obstacle (between its ``base_m`` and top), [F] rows:
    face f runs from ``start[f]`` to ``end[f]`` ([F, 2]); ``normal`` [F, 2] the unit horizontal
    normal of its front (reflecting) side; ``two_sided``: it reflects on both sides."""

    start: FloatArray
    end: FloatArray
    normal: FloatArray
    two_sided: bool


def _label(kind: str, name: str | None) -> str:
    return f"{kind} {name!r}" if name else kind


def segments_cross(a: FloatArray, b: FloatArray, c: FloatArray, d: FloatArray) -> NDArray[np.bool_]:
    """Whether 2-D segments a–b and c–d intersect (touching included), batched [..., 2]."""

    def orient(p: FloatArray, q: FloatArray, r: FloatArray) -> FloatArray:
        return np.asarray(
            (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1])
            - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])
        )

    def on_segment(p: FloatArray, q: FloatArray, r: FloatArray) -> NDArray[np.bool_]:
        """r within the bounding box of p–q (used when p, q, r are collinear)."""
        return np.asarray(
            (np.minimum(p[..., 0], q[..., 0]) <= r[..., 0])
            & (r[..., 0] <= np.maximum(p[..., 0], q[..., 0]))
            & (np.minimum(p[..., 1], q[..., 1]) <= r[..., 1])
            & (r[..., 1] <= np.maximum(p[..., 1], q[..., 1]))
        )

    o1, o2, o3, o4 = orient(a, b, c), orient(a, b, d), orient(c, d, a), orient(c, d, b)
    proper = (np.sign(o1) * np.sign(o2) < 0) & (np.sign(o3) * np.sign(o4) < 0)
    touch = (
        ((o1 == 0) & on_segment(a, b, c))
        | ((o2 == 0) & on_segment(a, b, d))
        | ((o3 == 0) & on_segment(c, d, a))
        | ((o4 == 0) & on_segment(c, d, b))
    )
    return np.asarray(proper | touch)


def footprint_problem(vertices: FloatArray) -> str | None:
    """Why a footprint [n, 2] is not a simple polygon with area, or ``None``."""
    n = vertices.shape[0]
    if n < 3:
        return f"a footprint needs at least 3 vertices, got {n}"
    edges = np.roll(vertices, -1, axis=0) - vertices
    short = np.hypot(edges[:, 0], edges[:, 1]) < MIN_EDGE_M
    if np.any(short):
        k = int(np.argmax(short))
        return f"footprint vertices {k} and {(k + 1) % n} coincide ({vertices[k].tolist()})"
    if n > 3:
        a, b = vertices, np.roll(vertices, -1, axis=0)
        i, j = np.triu_indices(n, k=2)
        keep = ~((i == 0) & (j == n - 1))  # the first and last edges are adjacent
        i, j = i[keep], j[keep]
        hit = segments_cross(a[i], b[i], a[j], b[j])
        if np.any(hit):
            k = int(np.argmax(hit))
            return (
                f"footprint is self-intersecting: edge {int(i[k])}–{int(i[k]) + 1} crosses"
                f" edge {int(j[k])}–{(int(j[k]) + 1) % n}"
            )
    x, y = vertices[:, 0], vertices[:, 1]
    area = 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
    if area < MIN_FOOTPRINT_AREA_M2:
        return f"footprint has zero area ({area:.3g} m²): its vertices are collinear"
    return None


class _Heights(DocumentModel):
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


class Prism(_Heights):
    """A vertical extrusion of a simple polygon between ``base_m`` and ``base_m + height_m``."""

    kind: Literal["prism"] = Field("prism", description="Obstacle kind (discriminator)")
    footprint: list[Point2] = Field(
        min_length=1,
        max_length=MAX_FOOTPRINT_VERTICES,
        description="Polygon vertices [x, y] in metres, any winding, not closed",
    )

    @field_validator("footprint")
    @classmethod
    def _finite(cls, v: list[list[float]]) -> list[list[float]]:
        pts = [finite_point(p, "footprint vertex") for p in v]
        if len(pts) > 3 and pts[0] == pts[-1]:  # a closed ring (GeoJSON habit): open it
            pts = pts[:-1]
        return pts

    @model_validator(mode="after")
    def _simple(self) -> Prism:
        problem = footprint_problem(np.asarray(self.footprint, dtype=float))
        if problem is not None:
            raise ValueError(f"{_label('prism', self.name)}: {problem}")
        return self

    @property
    def vertices(self) -> FloatArray:
        """[n, 2] footprint vertices."""
        return np.asarray(self.footprint, dtype=float)

    def faces(self) -> Faces:
        """One outward-facing face per footprint edge (edge k from vertex k to k + 1)."""
        v = self.vertices
        w = np.roll(v, -1, axis=0)
        e = w - v
        area2 = float(np.dot(v[:, 0], w[:, 1]) - np.dot(v[:, 1], w[:, 0]))
        side = 1.0 if area2 > 0 else -1.0  # counter-clockwise: the outside is on the right
        length = np.hypot(e[:, 0], e[:, 1])
        normal = side * np.column_stack([e[:, 1], -e[:, 0]]) / length[:, None]
        return Faces(v, w, normal, False)


class WallObstacle(_Heights):
    """A zero-thickness vertical rectangle over the segment ``start``–``end``."""

    kind: Literal["wall"] = Field("wall", description="Obstacle kind (discriminator)")
    start: Point2
    end: Point2

    @field_validator("start", "end")
    @classmethod
    def _finite(cls, v: list[float]) -> list[float]:
        return finite_point(v, "wall end point")

    @model_validator(mode="after")
    def _length(self) -> WallObstacle:
        length = float(np.hypot(self.end[0] - self.start[0], self.end[1] - self.start[1]))
        if length < MIN_EDGE_M:
            raise ValueError(f"{_label('wall', self.name)}: zero length (start = end)")
        return self

    def faces(self) -> Faces:
        """The wall's rectangle, reflecting on both sides (normal to the left of start→end)."""
        s = np.asarray([self.start], dtype=float)
        e = np.asarray([self.end], dtype=float)
        u = (e - s) / np.hypot(*(e - s)[0])
        return Faces(s, e, np.column_stack([-u[:, 1], u[:, 0]]), True)


Obstacle = Annotated[Prism | WallObstacle, Field(discriminator="kind")]


class Environment(DocumentModel):
    """Obstacles of a site; absent, every result is the free-space one."""

    obstacles: list[Obstacle] = Field(
        default_factory=list,
        max_length=MAX_OBSTACLES,
        description="Prisms (buildings, machines) and walls that block legs",
    )

    def label(self, index: int) -> str:
        """'obstacle 3 (prism 'b1')' – how messages name an obstacle."""
        ob = self.obstacles[index]
        return f"obstacle {index} ({_label(ob.kind, ob.name)})"
