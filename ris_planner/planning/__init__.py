"""Planning engine: UE probability maps, candidate RIS sites, coverage-weighted objectives,
placement search and RIS-count comparison (built on :mod:`ris_planner.bounds`)."""

from ris_planner.planning.document import PlanDocument
from ris_planner.planning.executor import DaskExecutor, Executor, LocalExecutor, SerialExecutor
from ris_planner.planning.pipeline import run_plan
from ris_planner.planning.presets import PLAN_PRESET_NAMES, load_plan_file, plan_preset
from ris_planner.planning.report import write_figures
from ris_planner.planning.result import PlanResult

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
