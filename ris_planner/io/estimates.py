"""A plan's resource estimate at the boundary: made from the document as given (local metres or
a geographic ``frame``) before any work, and set beside what the run measured in plan.json
``resources`` (docs/validation/resources.md).

``ris-planner plan`` prints :func:`document_estimate` on stderr before it plans; the service
makes it when a plan job is submitted (the job's ``estimate``); both run the plan through
:func:`plan_measured`, which writes ``resources`` into plan.json – for a district plan too.
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import TYPE_CHECKING, Any

from ris_planner.io.candidates import in_document_coordinates
from ris_planner.io.frames import to_local
from ris_planner.planning.resources.time_estimate import PlanEstimate, plan_estimate, resources_json
from ris_planner.runtime.progress import ProgressCallback, no_progress

if TYPE_CHECKING:
    from pathlib import Path

    from ris_planner.io.geoplan import PlanFiles
    from ris_planner.planning.figure_process import FigureProcess


def document_estimate(document: dict[str, Any], memory_mb: int | None = None) -> PlanEstimate:
    """The estimate of a plan document as given: converted from its frame, checked as the run
    checks it (:func:`~ris_planner.planning.resources.admission.validate_plan`: a document above a
    limit
    or the budget raises the refusal, which names the estimate), then
    :func:`~ris_planner.planning.resources.time_estimate.plan_estimate`. ``memory_mb``: the job
    memory budget
    (default ``RIS_PLANNER_JOB_MEMORY_MB``)."""
    from ris_planner.planning.resources.admission import validate_plan

    t0 = time.perf_counter()
    local, frame = to_local(document)
    with in_document_coordinates(frame):
        doc = validate_plan(local, memory_mb)
    est = plan_estimate(doc, memory_mb)
    return replace(est, seconds=time.perf_counter() - t0)


def plan_measured(
    executor: Any,
    document: dict[str, Any],
    out_dir: Path,
    progress: ProgressCallback = no_progress,
    figures: FigureProcess | None = None,
    estimate: PlanEstimate | None = None,
) -> PlanFiles:
    """:func:`~ris_planner.io.geoplan.plan_on` with plan.json ``resources``: ``estimate``
    (:func:`document_estimate` when not given) and what the run measured – its wall seconds
    from here to plan.json's content and its process's peak resident memory; making the
    estimate is a stage of ``timing_s`` (``estimate``)."""
    from ris_planner.io.geoplan import plan_on

    est = document_estimate(document) if estimate is None else estimate
    t0 = time.perf_counter()
    done = plan_on(executor, document, out_dir, progress, figures)
    done.plan["resources"] = resources_json(est, time.perf_counter() - t0)
    done.plan["timing_s"] = {"estimate": est.seconds, **done.plan["timing_s"]}
    return done
