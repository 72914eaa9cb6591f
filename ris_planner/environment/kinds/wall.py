"""Obstacle kind ``wall``: a zero-thickness vertical rectangle over the segment ``start``–``end``
between z = ``base_m`` and z = ``base_m + height_m`` (docs/concepts/environment.md,
"Obstacles"): its model, its face and its exact float64 narrow phase (the rules of
:mod:`ris_planner.environment.scene`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from ris_planner.core.document import finite_point
from ris_planner.environment.kinds.base import (
    BoolArray,
    Faces,
    FloatArray,
    GeoJSON,
    GeometryError,
    IntArray,
    ObstacleModel,
    ToOutput,
    coordinates,
    label,
    position_xy,
)
from ris_planner.environment.kinds.prism import MIN_EDGE_M, Point2


class WallObstacle(ObstacleModel):
    """A zero-thickness vertical rectangle over the segment ``start``–``end``."""

    kind_name: ClassVar[str] = "wall"
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
            raise ValueError(f"{label('wall', self.name)}: zero length (start = end)")
        return self

    def faces(self) -> Faces:
        """The wall's rectangle, reflecting on both sides (normal to the left of start→end)."""
        s = np.asarray([self.start], dtype=float)
        e = np.asarray([self.end], dtype=float)
        u = (e - s) / np.hypot(*(e - s)[0])
        return Faces(s, e, np.column_stack([-u[:, 1], u[:, 0]]), True)

    def outline(self) -> FloatArray:
        return np.array([self.start, self.end], dtype=float)

    def work_units(self) -> int:
        return 1


# ---- the narrow phase -------------------------------------------------------------------


def wall_blocks(
    a: FloatArray,
    b: FloatArray,
    start: FloatArray,
    end: FloatArray,
    base: FloatArray,
    top: FloatArray,
    tol: float,
) -> BoolArray:
    """[K] whether leg a[k]–b[k] crosses wall k (start, end [K, 2], base, top [K]): its ends lie
    on strictly opposite sides of the wall's plane, each more than tol from it, and the
    crossing point lies inside the rectangle by more than tol from its four edges."""
    e = end - start
    length = np.hypot(e[:, 0], e[:, 1])
    u = e / length[:, None]
    nx, ny = -u[:, 1], u[:, 0]
    sa = (a[:, 0] - start[:, 0]) * nx + (a[:, 1] - start[:, 1]) * ny
    sb = (b[:, 0] - start[:, 0]) * nx + (b[:, 1] - start[:, 1]) * ny
    cand = (sa * sb < 0) & (np.abs(sa) > tol) & (np.abs(sb) > tol)
    t = np.where(cand, sa / np.where(cand, sa - sb, 1.0), 0.0)
    p = a + t[:, None] * (b - a)
    along = (p[:, 0] - start[:, 0]) * u[:, 0] + (p[:, 1] - start[:, 1]) * u[:, 1]
    return np.asarray(
        cand
        & (along > tol)
        & (along < length - tol)
        & (p[:, 2] > base + tol)
        & (p[:, 2] < top - tol)
    )


@dataclass(frozen=True)
class PackedWalls:
    """[N] walls: ``start``, ``end`` [N, 2], ``base``, ``top`` [N]."""

    start: FloatArray
    end: FloatArray
    base: FloatArray
    top: FloatArray


class WallKind:
    """The ``wall`` kind (not solid; compiled engine: yes; a GeoJSON LineString)."""

    name: str = "wall"
    model: type[ObstacleModel] = WallObstacle
    solid: bool = False
    compiled: bool = True
    point_fields: tuple[tuple[str, ...], ...] = (("start",), ("end",))
    draw: dict[str, Any] = {"shape": "polyline", "points": ["start", "end"], "label": "wall"}  # noqa: RUF012

    def to_geojson(self, obstacle: WallObstacle, xy: ToOutput) -> tuple[GeoJSON, GeoJSON]:
        """A LineString from ``start`` to ``end``."""
        line = xy(np.array([obstacle.start, obstacle.end], dtype=float))
        return {"type": "LineString", "coordinates": line.tolist()}, {}

    def from_geojson(self, geometry: GeoJSON, properties: GeoJSON) -> dict[str, Any]:
        """``start`` and ``end`` from a LineString of two positions."""
        line = coordinates(geometry, self.name, "LineString")
        if not isinstance(line, list) or len(line) != 2:
            raise GeometryError("a wall feature's LineString has exactly two positions")
        start, end = (position_xy(p) for p in line)
        return {"start": start, "end": end}

    def pack(self, obstacles: list[Any]) -> PackedWalls:
        n = len(obstacles)
        start, end = np.zeros((n, 2)), np.zeros((n, 2))
        for k, o in enumerate(obstacles):
            start[k], end[k] = np.array([o.start, o.end], dtype=float)
        return PackedWalls(
            start,
            end,
            np.array([o.base_m for o in obstacles], dtype=float),
            np.array([o.top_m for o in obstacles], dtype=float),
        )

    def blocks(
        self, packed: PackedWalls, rows: IntArray, a: FloatArray, b: FloatArray, tol: float
    ) -> BoolArray:
        return wall_blocks(
            a, b, packed.start[rows], packed.end[rows], packed.base[rows], packed.top[rows], tol
        )

    def depth(self, packed: PackedWalls, rows: IntArray, points: FloatArray) -> FloatArray:
        return np.zeros(rows.size)


KIND = WallKind()
