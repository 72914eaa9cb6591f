"""``run_plan``: the plan pipeline's entry points, gathered (docs/concepts/planning.md,
"Pipeline"). The stages live in modules named for them – :mod:`~ris_planner.planning.inputs`,
:mod:`~ris_planner.planning.pipeline` (visibility, site cache, search, checks, rollout,
beams, sweep, the per-point bounds and summary stages), :mod:`~ris_planner.planning.checks`,
:mod:`~ris_planner.planning.fields` – and the frozen result in
:mod:`~ris_planner.planning.result`; this module only re-exports them."""

from __future__ import annotations

from ris_planner.planning.checks import (
    RANDOM_CODEBOOK_MAX_PAIRS,
    RANDOM_CODEBOOK_SEEDS,
    ObjectiveTask,
    PlanCheck,
    bnb_certificate,
    objective_task,
    plan_check_task,
    random_codebook_summary,
    random_codebook_tasks,
    search_certificate,
)
from ris_planner.planning.fields import REASON_NO_TX, RxField, heatmap_rx_index, rx_fields
from ris_planner.planning.inputs import PlanInputs, needs_workers, prepare_plan, validate_document
from ris_planner.planning.pipeline import (
    StageClock,
    fields_stage,
    pipeline_work,
    plan_beams,
    plan_once,
    run_plan,
    sweep_rows,
)
from ris_planner.planning.result import (
    CDF_POINTS,
    REPORT_QUANTILES,
    CountResult,
    PlanResult,
    Summary,
    summarise,
)

__all__ = [
    "CDF_POINTS",
    "RANDOM_CODEBOOK_MAX_PAIRS",
    "RANDOM_CODEBOOK_SEEDS",
    "REASON_NO_TX",
    "REPORT_QUANTILES",
    "CountResult",
    "ObjectiveTask",
    "PlanCheck",
    "PlanInputs",
    "PlanResult",
    "RxField",
    "StageClock",
    "Summary",
    "bnb_certificate",
    "fields_stage",
    "heatmap_rx_index",
    "needs_workers",
    "objective_task",
    "pipeline_work",
    "plan_beams",
    "plan_check_task",
    "plan_once",
    "prepare_plan",
    "random_codebook_summary",
    "random_codebook_tasks",
    "run_plan",
    "rx_fields",
    "search_certificate",
    "summarise",
    "sweep_rows",
    "validate_document",
]
