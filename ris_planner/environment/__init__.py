"""Obstacles, visibility of legs and reflections (docs/concepts/environment.md,
"The contract").

A :class:`Scene` is built once from a document's :class:`~ris_planner.environment.model.Environment`
and answers batched questions: which legs (segments) are blocked, which points lie inside a
prism. The rules and their tolerance are documented in :mod:`ris_planner.environment.scene`;
first-order reflections off the obstacles' faces in :mod:`ris_planner.environment.reflections`.

The names below are loaded on first access, so that the obstacle models (imported by the
scenario model) can import the environment's leaf modules without a circle. The visibility of
a RIS path's legs and fields of view (which need the geometry) is :mod:`ris_planner.bounds.paths`.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ris_planner.environment.scene import (
        INSIDE_MARGIN_M,
        VISIBILITY_TOLERANCE_M,
        Scene,
    )

_LAZY = {
    "INSIDE_MARGIN_M": "scene",
    "VISIBILITY_TOLERANCE_M": "scene",
    "Scene": "scene",
}

__all__ = [
    "INSIDE_MARGIN_M",
    "VISIBILITY_TOLERANCE_M",
    "Scene",
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(importlib.import_module(f"ris_planner.environment.{_LAZY[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'ris_planner.environment' has no attribute {name!r}")
