"""The ``environment`` of scenario and plan documents (docs/concepts/environment.md, "The
contract"): a list of obstacles, each of a registered kind
(:mod:`ris_planner.environment.kinds`: ``prism``, ``wall``). Pydantic models only – the JSON
contract; the visibility engine that uses them is :class:`ris_planner.environment.Scene`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any, Union

from pydantic import BeforeValidator, Field
from pydantic_core import PydanticCustomError

from ris_planner.core.document import DocumentModel
from ris_planner.environment.kinds import KINDS, known_kinds
from ris_planner.environment.kinds.base import ObstacleModel, label

MAX_OBSTACLES = 100_000
"""Obstacles per environment."""


def _known_kind(value: Any) -> Any:
    """An obstacle whose ``kind`` is not registered: an error naming the known kinds."""
    if isinstance(value, dict) and "kind" in value and value["kind"] not in KINDS:
        raise PydanticCustomError(
            "unknown_obstacle_kind",
            "unknown obstacle kind {kind}; known kinds: {known}",
            {"kind": repr(value["kind"]), "known": known_kinds()},
        )
    return value


if TYPE_CHECKING:
    Obstacle = ObstacleModel
else:
    Obstacle = Annotated[
        Union[tuple(k.model for k in KINDS.values())],  # noqa: UP007 – built from the registry
        Field(discriminator="kind"),
        BeforeValidator(_known_kind),
    ]
"""One obstacle: the registered kinds' models, told apart by ``kind``."""


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
        return f"obstacle {index} ({label(ob.kind_name, ob.name)})"
