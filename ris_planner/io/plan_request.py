"""A plan document as given – local metres or a geographic ``frame`` – admitted once: the one
validation path of a run's document (docs/concepts/planning.md, "Pipeline").

:func:`admit_request` converts the document from its frame (:func:`~ris_planner.io.frames.
to_local`), validates it, resolves its search and checks its sizes
(:func:`~ris_planner.planning.resources.admission.admit`) and estimates its time and memory
(:func:`~ris_planner.planning.resources.time_estimate.plan_estimate`) – each exactly once; the
command line prints the estimate before any work, the service keeps it with the job, and the
run (:func:`ris_planner.io.geoplan.plan_document`) plans the same admitted document.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ris_planner.io.frames import Frame
    from ris_planner.planning.resources.admission import Admitted
    from ris_planner.planning.resources.time_estimate import PlanEstimate


@dataclass(frozen=True)
class PlanRequest:
    """A plan document admitted to run (:func:`admit_request`)."""

    given: dict[str, Any]
    """The document as given (a geographic one in its own coordinates): the GIS files and
    plan.json's licence and frame read it."""
    local: dict[str, Any]
    """The document in local metres."""
    frame: Frame | None
    admitted: Admitted
    estimate: PlanEstimate
    """Its resources, estimated before any work (``seconds``: the admission's time too)."""


def admit_request(document: dict[str, Any], memory_mb: int | None = None) -> PlanRequest:
    """Convert, admit and estimate a plan document as given, once (module docstring): a
    document above a limit or the budget raises the refusal (exit 2 / 413), one that asks a
    search method for what it cannot honour names the option (exit 2 / 422). ``memory_mb``:
    the job memory budget (default ``RIS_PLANNER_JOB_MEMORY_MB``). Its time, the planner's
    imports included (they load here, on first use), is the estimate's ``seconds``: plan.json
    ``timing_s["estimate"]``."""
    t0 = time.perf_counter()
    from ris_planner.io.candidates import in_document_coordinates
    from ris_planner.io.frames import to_local
    from ris_planner.planning.resources.admission import admit
    from ris_planner.planning.resources.time_estimate import PlanEstimate, plan_estimate

    local, frame = to_local(document)
    with in_document_coordinates(frame):
        admitted = admit(local, memory_mb)
    estimate = plan_estimate(admitted, memory_mb)
    estimate = PlanEstimate(
        estimate.time_s, estimate.memory_mib, estimate.budget_mib, time.perf_counter() - t0
    )
    return PlanRequest(document, local, frame, admitted, estimate)
