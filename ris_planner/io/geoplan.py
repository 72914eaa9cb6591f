"""An admitted plan document (:mod:`ris_planner.io.plan_request`) → ``plan.json``, the PNG
figures and the GIS files: the one path of ``ris-planner plan --out`` and of the service's plan
jobs, whatever the search method, so both write the same files for the same document.

The document was converted once (:func:`~ris_planner.io.frames.to_local`), is planned in local
metres, and its ``plan.json`` gains ``"frame": {"origin": [lon, lat, h], "local_crs": proj4}``
when it had a frame, the document's ``license`` / ``attribution``, and a warning first in
``warnings`` when such a real site has no obstacles (:func:`site_warnings`); ``plan.geojson`` /
``heatmap.tif`` / ``points.csv`` are written from the document as given (WGS84 with a frame,
:func:`~ris_planner.io.gis_outputs.plan_outputs`, each carrying the licence).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ris_planner.io import MissingExtraError
from ris_planner.io.candidates import in_document_coordinates
from ris_planner.io.frames import license_of_document, search_region_lonlat
from ris_planner.io.plan_request import PlanRequest, admit_request
from ris_planner.runtime.progress import ProgressCallback, StageClock, Stages, no_progress

if TYPE_CHECKING:
    from ris_planner.planning.figure_process import FigureProcess

OUTPUTS = ("figures", "exports")
"""The output stages after plan.json's content, each timed in ``timing_s``."""

NO_OBSTACLES_WARNING = (
    "the document is a real site (a geographic frame or a licence) but has no environment"
    " obstacles: every leg was planned as clear (line of sight; only the RIS fields of view"
    " apply), as if the site had no buildings – an import without buildings? Import them"
    " (ris-planner import, whose report warns 'no buildings') or add environment.obstacles"
)
"""plan.json's warning for a real site planned without obstacles (:func:`site_warnings`)."""


def site_warnings(document: Any) -> list[str]:
    """plan.json warnings about the document as given: :data:`NO_OBSTACLES_WARNING` when it has
    a ``frame`` or a ``license`` / ``attribution`` (a real site, typically an import) and no
    ``environment.obstacles``."""
    if not isinstance(document, dict):
        return []
    real = "frame" in document or any(document.get(k) for k in ("license", "attribution"))
    env = document.get("environment")
    obstacles = env.get("obstacles") if isinstance(env, dict) else None
    return [NO_OBSTACLES_WARNING] if real and not obstacles else []


@dataclass(frozen=True)
class PlanFiles:
    """What :func:`plan_document` produced."""

    plan: dict[str, Any]
    """The ``plan.json`` content (:meth:`PlanResult.to_json`, plus ``frame``)."""
    files: dict[str, Path]
    """Figure / file name → path: ``topview``, ``heatmap``, ``cdf`` (PNG) and, with the GIS
    extra, ``geojson``, ``geotiff``, ``points_csv``."""
    note: str | None = None
    """Why the GIS files were skipped (the GIS extra is missing), else None."""
    cpu_s: dict[str, float] = field(default_factory=dict)
    """This process's CPU seconds per stage of ``timing_s`` (not in plan.json: the time
    estimate's calibration, ``benchmarks/resources/bench_memory.py``)."""


def plan_document(
    request: PlanRequest | dict[str, Any],
    out_dir: Path,
    progress: ProgressCallback = no_progress,
    executor: Any = None,
    figures: FigureProcess | None = None,
) -> PlanFiles:
    """Plan an admitted document (:func:`~ris_planner.io.plan_request.admit_request`; a
    document as given is admitted first; every
    search method through the one pipeline, :func:`~ris_planner.planning.pipeline.run_plan`
    with ``executor``), write the figures and GIS files into ``out_dir``; ``plan.json`` itself
    is the caller's to write (the command line writes it, a job stores it as its result).

    Progress goes over the stages ``plan`` (the search: cache, search, checks, beams),
    ``fields`` (every count's per-point bounds), ``report`` (the summary and plan.json),
    ``figures`` and ``exports``, each with a share proportional to its estimated work
    (:mod:`ris_planner.planning.resources.time_estimate`); 1.0 only once the files are
    written. plan.json's ``timing_s`` holds every stage's seconds, these outputs included
    (:class:`~ris_planner.runtime.progress.StageClock`): their sum is this call's wall time.
    Checks that run on a thread (:class:`~ris_planner.planning.certify.checks.PendingChecks`)
    run beside the fields and the figures; ``timing_s["checks"]`` is the part of them that
    those stages did not hide (the wait before plan.json). With ``figures`` (the command
    line's :class:`~ris_planner.planning.figure_process.FigureProcess`) a helper process
    draws the figures beside the checks, the report and the exports;
    ``timing_s["figures"]`` is then the hand-over plus the wait for the helper at the end."""
    t0, c0 = time.perf_counter(), time.process_time()  # the imports: the inputs' time too
    from ris_planner.planning.certify.checks import cancelled_on_error
    from ris_planner.planning.outputs.report import write_figures
    from ris_planner.planning.pipeline import pipeline_work, run_plan, settle_checks
    from ris_planner.planning.prepare import prepare_plan
    from ris_planner.planning.resources.time_estimate import report_work

    if not isinstance(request, PlanRequest):
        request = admit_request(request)
    document, frame = request.given, request.frame
    clock = StageClock()
    clock.add("inputs", time.perf_counter() - t0, time.process_time() - c0)
    with clock.stage("inputs"), in_document_coordinates(frame):
        inputs = prepare_plan(request.admitted)
    stages = Stages(
        progress, {**pipeline_work(inputs), **{k: report_work(inputs)[k] for k in OUTPUTS}}, clock
    )
    with in_document_coordinates(frame):
        result = run_plan(
            request.admitted,
            executor=executor,
            inputs=inputs,
            stages=stages,
            clock=clock,
            settle=False,
        )
    with cancelled_on_error(result.pending_checks):  # the figures beside the pending checks
        with clock.stage("figures"):
            stages.callback("figures")
            if figures is None:
                files = write_figures(result, out_dir)
            else:  # drawn by the helper beside the checks, plan.json and the exports
                figures.submit(result, out_dir)
                files = {}
        result = settle_checks(result, clock)
    with clock.stage("report"):
        plan = result.to_json()
        if frame is not None:
            plan["frame"] = frame.describe()
            if isinstance(plan.get("validation"), dict):
                val = plan["validation"]
                given = (document.get("validation") or {}).get("search_region")
                val["search_region"] = search_region_lonlat(frame, val["search_region"], given)
        plan.update(license_of_document(document))
        plan["warnings"] = [*site_warnings(document), *plan.get("warnings", [])]
    note = None
    with clock.stage("exports"):
        stages.callback("exports")
        try:
            from ris_planner.io.gis_outputs import plan_outputs

            converted = (request.local, frame)
            files.update(plan_outputs(result, plan, document, out_dir, converted))
        except MissingExtraError as exc:
            note = str(exc)
    if figures is not None:
        with clock.stage("figures"):  # the wait for the helper: what the stages above left
            files = {**figures.files(), **files}
    stages.finish("done")  # timed as the reports between stages (a job writes it)
    plan["timing_s"] = dict(clock.seconds)
    return PlanFiles(plan, files, note, dict(clock.cpu))


def plan_on(
    executor: Any,
    request: PlanRequest | dict[str, Any],
    out_dir: Path,
    progress: ProgressCallback = no_progress,
    figures: FigureProcess | None = None,
) -> PlanFiles:
    """:func:`plan_document` on ``executor``, which it closes afterwards: stopping the worker
    pool is the plan's time too (``timing_s["workers_close"]``, so that ``timing_s`` sums to
    the wall time of the command line's and a job's plan alike)."""
    with executor:  # the document is converted from its frame there (ris_planner.io.frames)
        done = plan_document(request, out_dir, progress, executor, figures)
        t_close = time.perf_counter()
    done.plan["timing_s"]["workers_close"] = time.perf_counter() - t_close
    return done
