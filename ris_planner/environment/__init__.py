"""Obstacles, visibility of legs and fields of view (docs/concepts/environment.md,
"The contract").

A :class:`Scene` is built once from a document's
:class:`~ris_planner.environment.model.Environment`
and answers batched questions: which legs (segments) are blocked, which points lie inside a
prism. The rules and their tolerance are documented in :mod:`ris_planner.environment.scene`.
"""

from ris_planner.environment.scene import (
    INSIDE_MARGIN_M,
    VISIBILITY_TOLERANCE_M,
    Scene,
)

__all__ = [
    "INSIDE_MARGIN_M",
    "VISIBILITY_TOLERANCE_M",
    "Scene",
]
