"""The obstacle kinds: one module per kind (its pydantic model, faces and narrow phase, see
:mod:`ris_planner.environment.kinds.base`), registered here.

Adding a kind: write ``kinds/<name>.py`` with a model (``kind: Literal["<name>"]``) and a
``KIND`` object implementing :class:`~ris_planner.environment.kinds.base.ObstacleKind`, and add
it to :data:`KINDS`. The document model (:mod:`ris_planner.environment.model`) and the
visibility engine (:class:`~ris_planner.environment.scene.Scene`) take their kinds from here;
an obstacle of an unregistered kind is an error naming the known kinds, in a document (422 over
REST) and in the engine.
"""

from __future__ import annotations

from typing import Any

from ris_planner.environment.kinds import prism, wall
from ris_planner.environment.kinds.base import Faces, ObstacleKind, ObstacleModel

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


__all__ = [
    "KINDS",
    "Faces",
    "ObstacleKind",
    "ObstacleModel",
    "UnknownObstacleKindError",
    "kind_of",
    "known_kinds",
]
