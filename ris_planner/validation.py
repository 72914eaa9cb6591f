"""The one validation path of a run's document, shared by the command line, the service's
POST routes and the job functions: the document model, the rules that tie its fields
together, then the sizes against their limits (:mod:`ris_planner.limits`). A document that
passes here is one the run accepts; what fails names its field (``DocumentFieldError``) or its
limit (``LimitExceededError``).
"""

from __future__ import annotations

from typing import Any

from ris_planner.errors import DocumentFieldError
from ris_planner.limits import (
    Sizes,
    check_sizes,
    estimate_plan,
    estimate_power,
    explain_plan_memory,
    job_memory_mb,
    largest_plan_shape,
    plan_sites,
)
from ris_planner.planning.document import PlanDocument
from ris_planner.power.options import OBJECTIVES
from ris_planner.scenario import ExpectedRandomCodebook, Scenario, load_scenario


def _budget(memory_mb: int | None) -> int:
    return job_memory_mb() if memory_mb is None else memory_mb


def validate_plan(
    document: PlanDocument | dict[str, Any], memory_mb: int | None = None
) -> PlanDocument:
    """A plan document that ``run_plan`` accepts: the model, the candidate count against
    ``ris_count``, the sizes against their limits and the job memory budget (default
    ``RIS_PLANNER_JOB_MEMORY_MB``)."""
    doc = document if isinstance(document, PlanDocument) else PlanDocument.model_validate(document)
    plan_check(doc, memory_mb)
    return doc


def plan_check(doc: PlanDocument, memory_mb: int | None = None) -> Sizes:
    """The cross-field and size rules of a validated plan document; its sizes."""
    sites = plan_sites(doc)
    if doc.ris_count is not None and max(doc.ris_count) > sites:
        raise DocumentFieldError(
            "ris_count",
            f"ris_count {max(doc.ris_count)} exceeds the {sites} candidate sites",
        )
    sizes = estimate_plan(doc)
    shape = largest_plan_shape(doc)
    check_sizes(
        sizes,
        max_pairs=doc.max_pairs,
        memory_mb=_budget(memory_mb),
        explain=lambda budget: explain_plan_memory(shape, budget),
    )
    return sizes


def validate_power(
    scenario: Scenario | dict[str, Any], objective: str, memory_mb: int | None = None
) -> Scenario:
    """A scenario and objective that ``run_power`` accepts: concrete beams (not
    ``expected_random``), an objective whose bound is not known, the SDP's sizes within their
    limits and the job memory budget."""
    sc = load_scenario(scenario)
    power_check(sc, objective, memory_mb)
    return sc


def power_check(sc: Scenario, objective: str, memory_mb: int | None = None) -> Sizes:
    """The power rules of a validated scenario; its sizes."""
    if objective not in OBJECTIVES:
        raise DocumentFieldError(
            "objective",
            f"objective must be one of {', '.join(OBJECTIVES)}, got {objective!r}",
        )
    if isinstance(sc.codebook, ExpectedRandomCodebook):
        raise DocumentFieldError(
            "codebook.kind",
            "power allocation needs concrete beams; codebook 'expected_random' has none"
            " (use 'random', 'explicit', 'directional' or 'directional_derivative')",
        )
    if "tx" in sc.known and objective in ("tx", "sum"):
        raise DocumentFieldError("known", f"objective {objective!r} needs PEB_T, but 'tx' is known")
    sizes = estimate_power(sc)
    check_sizes(sizes, memory_mb=_budget(memory_mb))
    return sizes
