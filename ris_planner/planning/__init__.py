"""Planning engine: UE probability maps, candidate RIS sites, coverage-weighted objectives,
placement search and RIS-count comparison (built on :mod:`ris_planner.bounds.compute`).

The names below load on first use (PEP 562): a worker process that needs only the search
(``ris_planner.planning.search.layouts``) does not import the whole pipeline, its figures and the
estimator with it (docs/validation/benchmarks.md, "Interactive planning")."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ris_planner.model.plan import PlanDocument
    from ris_planner.planning.inputs.presets import PLAN_PRESET_NAMES, load_plan_file, plan_preset
    from ris_planner.planning.outputs.report import write_figures
    from ris_planner.planning.outputs.result import PlanResult
    from ris_planner.planning.pipeline import run_plan
    from ris_planner.runtime.executor import (
        DaskExecutor,
        Executor,
        LocalExecutor,
        SerialExecutor,
    )

_SOURCES = {
    "PLAN_PRESET_NAMES": "ris_planner.planning.inputs.presets",
    "DaskExecutor": "ris_planner.runtime.executor",
    "Executor": "ris_planner.runtime.executor",
    "LocalExecutor": "ris_planner.runtime.executor",
    "PlanDocument": "ris_planner.model.plan",
    "PlanResult": "ris_planner.planning.outputs.result",
    "SerialExecutor": "ris_planner.runtime.executor",
    "load_plan_file": "ris_planner.planning.inputs.presets",
    "plan_preset": "ris_planner.planning.inputs.presets",
    "run_plan": "ris_planner.planning.pipeline",
    "write_figures": "ris_planner.planning.outputs.report",
}

__all__ = [
    "PLAN_PRESET_NAMES",
    "DaskExecutor",
    "Executor",
    "LocalExecutor",
    "PlanDocument",
    "PlanResult",
    "SerialExecutor",
    "load_plan_file",
    "plan_preset",
    "run_plan",
    "write_figures",
]


def __getattr__(name: str) -> Any:
    source = _SOURCES.get(name)
    if source is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(source), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_SOURCES))
