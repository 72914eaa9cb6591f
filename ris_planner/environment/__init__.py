"""Obstacles, visibility of legs, fields of view and reflections (docs/concepts/environment.md,
"The contract").

A :class:`Scene` is built once from a document's :class:`~ris_planner.obstacles.Environment`
and answers batched questions: which legs (segments) are blocked, which points lie inside a
prism. The rules and their tolerance are documented in :mod:`ris_planner.environment.scene`;
first-order reflections off the obstacles' faces in :mod:`ris_planner.environment.reflections`.

The names below are loaded on first access, so that the obstacle models (imported by the
scenario model) can import the environment's leaf modules without a circle.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ris_planner.environment.paths import (
        in_field_of_view,
        los_clear,
        path_presence,
        pattern_factor,
        ris_serves,
    )
    from ris_planner.environment.scene import (
        INSIDE_MARGIN_M,
        VISIBILITY_TOLERANCE_M,
        Scene,
    )

_LAZY = {
    "in_field_of_view": "paths",
    "los_clear": "paths",
    "path_presence": "paths",
    "pattern_factor": "paths",
    "ris_serves": "paths",
    "INSIDE_MARGIN_M": "scene",
    "VISIBILITY_TOLERANCE_M": "scene",
    "Scene": "scene",
}

__all__ = [
    "INSIDE_MARGIN_M",
    "VISIBILITY_TOLERANCE_M",
    "Scene",
    "in_field_of_view",
    "los_clear",
    "path_presence",
    "pattern_factor",
    "ris_serves",
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(importlib.import_module(f"ris_planner.environment.{_LAZY[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'ris_planner.environment' has no attribute {name!r}")
