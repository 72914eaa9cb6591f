"""The ``environment`` of scenario and plan documents (docs/concepts/environment.md, "The
contract"): a list of obstacles, each of a registered kind
(:mod:`ris_planner.environment.kinds`: ``prism``, ``wall``). Pydantic models only – the JSON
contract; the visibility engine that uses them is :class:`ris_planner.environment.Scene`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any, Union

from pydantic import Field, PlainValidator, SerializeAsAny
from pydantic_core import PydanticCustomError

from ris_planner.core.document import DocumentModel
from ris_planner.environment.kinds import KINDS, UnknownObstacleKindError, kind_of, known_kinds
from ris_planner.environment.kinds.base import ObstacleModel, label

MAX_OBSTACLES = 100_000
"""Obstacles per environment."""


def _obstacle(value: Any) -> ObstacleModel:
    """An obstacle validated by the model of its registered ``kind``, looked up when it is
    validated (a kind registered at run time is accepted from then on); an unknown kind is an
    error naming the known kinds."""
    if isinstance(value, ObstacleModel):
        try:
            kind_of(value)
        except UnknownObstacleKindError as exc:
            raise PydanticCustomError("unknown_obstacle_kind", str(exc)) from None
        return value
    if not isinstance(value, dict) or "kind" not in value:
        raise PydanticCustomError(
            "obstacle_kind",
            "an obstacle is an object with a kind (known kinds: {known})",
            {"known": known_kinds()},
        )
    kind = KINDS.get(value["kind"]) if isinstance(value["kind"], str) else None
    if kind is None:
        raise PydanticCustomError(
            "unknown_obstacle_kind",
            "unknown obstacle kind {kind}; known kinds: {known}",
            {"kind": repr(value["kind"]), "known": known_kinds()},
        )
    return kind.model.model_validate(value)


if TYPE_CHECKING:
    Obstacle = ObstacleModel
else:
    Obstacle = Annotated[
        SerializeAsAny[ObstacleModel],
        PlainValidator(
            _obstacle,
            # the JSON schema lists the kinds registered at import
            json_schema_input_type=Annotated[
                Union[tuple(k.model for k in KINDS.values())],  # noqa: UP007 – from the registry
                Field(discriminator="kind"),
            ],
        ),
    ]
"""One obstacle: the model of its registered kind, told apart by ``kind``."""


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
