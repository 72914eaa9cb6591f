"""What every obstacle kind shares: the protocol a kind module implements, the common document
fields (heights, name, material) and the faces reflections use (docs/concepts/environment.md).

A kind is one module in :mod:`ris_planner.environment.kinds` that defines

* its pydantic model (a subclass of :class:`ObstacleModel` with a ``kind`` literal: the JSON
  discriminator), which knows its ``faces()`` (for reflections), its ``outline()`` (the 2-D
  points of its box) and its ``work_units()`` (the REST work limit);
* an :class:`ObstacleKind` object: ``pack`` turns a list of its obstacles into arrays and
  ``blocks`` is its exact narrow phase (one leg against one obstacle per row, numpy, the rules
  of :mod:`ris_planner.environment.scene`); a ``solid`` kind also answers ``depth`` (how far
  points lie inside), and ``compiled`` says whether the compiled engine
  (:mod:`ris_planner.environment._jit`) implements it (scenes with other kinds use numpy);

and is registered in :data:`ris_planner.environment.kinds.KINDS`.
"""

from __future__ import annotations

from typing import Any, ClassVar, NamedTuple, Protocol

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from ris_planner.core.document import MAX_COORDINATE_M, DocumentModel
from ris_planner.environment.materials import DEFAULT_MATERIAL, Material

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int_]


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


class ObstacleKind(Protocol):
    """One obstacle kind for the visibility engine (see the module docstring)."""

    name: str
    model: type[ObstacleModel]
    solid: bool
    compiled: bool

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
