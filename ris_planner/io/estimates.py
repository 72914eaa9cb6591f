"""A plan's resource estimate at the boundary: made from the document as given (local metres or
a geographic ``frame``) before any work, and set beside what the run measured in plan.json
``resources`` (docs/validation/resources.md).

``ris-planner plan`` prints :func:`document_estimate` on stderr before it plans; the service
makes it when a plan job is submitted (the job's ``estimate``); both run the plan through
:func:`plan_measured`, which writes ``resources`` into plan.json – for a district plan too.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

from ris_planner.io.plan_request import PlanRequest, admit_request
from ris_planner.planning.resources.time_estimate import PlanEstimate, resources_json
from ris_planner.runtime.progress import ProgressCallback, no_progress

if TYPE_CHECKING:
    from pathlib import Path

    from ris_planner.io.geoplan import PlanFiles
    from ris_planner.planning.figure_process import FigureProcess


def document_estimate(document: dict[str, Any], memory_mb: int | None = None) -> PlanEstimate:
    """The estimate of a plan document as given (:func:`~ris_planner.io.plan_request.
    admit_request`: converted, admitted and estimated once; a refusal raises)."""
    return admit_request(document, memory_mb).estimate


def plan_measured(
    executor: Any,
    request: PlanRequest | dict[str, Any],
    out_dir: Path,
    progress: ProgressCallback = no_progress,
    figures: FigureProcess | None = None,
) -> PlanFiles:
    """:func:`~ris_planner.io.geoplan.plan_on` with plan.json ``resources``: the request's
    estimate and what the run measured – its wall seconds from here to plan.json's content and
    its process's peak resident memory (a document as given is admitted first); making the
    estimate (the admission) is a stage of ``timing_s`` (``estimate``)."""
    from ris_planner.io.geoplan import plan_on

    if not isinstance(request, PlanRequest):
        request = admit_request(request)
    est = request.estimate
    t0 = time.perf_counter()
    done = plan_on(executor, request, out_dir, progress, figures)
    done.plan["resources"] = resources_json(est, time.perf_counter() - t0)
    done.plan["timing_s"] = {"estimate": est.seconds, **done.plan["timing_s"]}
    return done
