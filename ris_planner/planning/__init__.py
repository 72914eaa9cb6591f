"""Planning engine: UE probability maps, candidate RIS sites, coverage-weighted objectives,
placement search and RIS-count comparison (built on :mod:`ris_planner.bounds.compute`)."""

from ris_planner.model.plan import PlanDocument
from ris_planner.planning.pipeline import run_plan
from ris_planner.planning.presets import PLAN_PRESET_NAMES, load_plan_file, plan_preset
from ris_planner.planning.report import write_figures
from ris_planner.planning.result import PlanResult
from ris_planner.runtime.executor import DaskExecutor, Executor, LocalExecutor, SerialExecutor

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
