"""The job kinds: kind name → module-level function ``(document, progress, out_dir) ->
JobOutput`` run in a worker process (:mod:`api.worker`). Each kind's POST route validates the
document first, so a job starts from a valid document."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from api.worker import JobFunction, JobOutput
from ris_planner.runtime.progress import ProgressCallback


def plan_job(document: dict[str, Any], progress: ProgressCallback, out_dir: Path) -> JobOutput:
    """``ris-planner plan``: a plan document (local metres or with a geographic ``frame``) →
    plan.json content and the figures ``topview``, ``heatmap``, ``cdf`` (PNG) and, with the
    GIS extra, the files ``geojson`` (plan.geojson), ``geotiff`` (heatmap.tif) and
    ``points_csv`` (points.csv) of ``ris-planner plan --out`` – the same function writes both
    (:func:`ris_planner.io.geoplan.plan_document`), with ``resources`` (the estimate made at
    submission beside the run's measured time and peak memory,
    :mod:`ris_planner.io.estimates`). The search runs on a local process pool
    started by this worker, as on the command line (``RIS_PLANNER_PLAN_WORKERS`` processes,
    default one per core: the same executor, so the same results), or on the Dask cluster
    of ``RIS_PLANNER_DASK_SCHEDULER``. The pool's processes are in the worker's process
    group: cancelling the job stops them with it (:func:`api.worker.terminate_job`)."""
    from api.settings import Settings
    from ris_planner.io.estimates import plan_measured
    from ris_planner.io.plan_request import admit_request
    from ris_planner.planning import DaskExecutor, Executor, LocalExecutor

    t0 = time.perf_counter()
    settings = Settings()
    address = settings.dask_scheduler
    executor: Executor = (
        DaskExecutor(address) if address else LocalExecutor(settings.plan_workers or None)
    )
    # admitted once here, as at submission (the same document and budget): its estimate is
    # kept in plan.json "resources"
    startup = time.perf_counter() - t0  # the settings and the executor, as the command's
    request = admit_request(document, settings.job_memory_mb)
    done = plan_measured(executor, request, out_dir, progress)
    # a stage of its own, as on the command line (ris_planner.cli.plan): the stages then sum to
    # the job's time (a missing 20–40 ms was 3–5 % of a small plan's, the stage-sum test's limit)
    done.plan["timing_s"] = {"startup": startup, **done.plan["timing_s"]}
    return JobOutput(done.plan, done.files)


def power_job(document: dict[str, Any], progress: ProgressCallback, out_dir: Path) -> JobOutput:
    """``ris-planner power``: {"scenario": …, "objective": …, "solver": …} → PowerResult JSON,
    or {"layout": …} (a layout + UE maps document) → the beam report; either document in
    local metres or with a geographic ``frame`` (converted first, as at submission)."""
    from ris_planner.io.frames import to_local
    from ris_planner.power import run_power

    if "layout" in document:
        from ris_planner.planning.beams import run_layout_beams

        return JobOutput(run_layout_beams(to_local(document["layout"])[0], progress))

    scenario = to_local(document["scenario"])[0]
    result = run_power(
        scenario, progress, objective=document["objective"], solver=document["solver"]
    )
    return JobOutput(result.to_json())


def city_job(document: dict[str, Any], progress: ProgressCallback, out_dir: Path) -> JobOutput:
    """``ris-planner city``: {"document": …, "cell_m": M} → the city's plan.json and the files
    ``geojson``, ``geotiff`` and ``points_csv`` over the whole city – the same function writes
    them for the command line (:func:`ris_planner.io.cityplan.plan_city_document`). The cells
    are planned on a local process pool started by this worker (``RIS_PLANNER_PLAN_WORKERS``
    processes, default one per core), or on the Dask cluster of
    ``RIS_PLANNER_DASK_SCHEDULER``: either gives the same answer."""
    from api.settings import Settings
    from ris_planner.io.cityplan import admit_city, plan_city_document
    from ris_planner.planning import DaskExecutor, Executor, LocalExecutor

    settings = Settings()
    address = settings.dask_scheduler
    executor: Executor = (
        DaskExecutor(address) if address else LocalExecutor(settings.plan_workers or None)
    )
    request = admit_city(document["document"], document["cell_m"], settings.job_memory_mb)
    done = plan_city_document(request, out_dir, executor, progress)
    return JobOutput(done.plan, done.files)


JOB_KINDS: dict[str, JobFunction] = {"plan": plan_job, "power": power_job, "city": city_job}
