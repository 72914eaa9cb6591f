"""A city document as given (local metres or a geographic ``frame``) → the city's plan.json
and its GIS files: the one path of ``ris-planner city`` and of the service's city jobs
(``POST /v1/cities``), so both write the same files for the same document
(docs/concepts/district.md, "A city").

The document is converted once (:func:`~ris_planner.io.frames.to_local`), split and planned
in local metres (:mod:`ris_planner.planning.city`); plan.json gains the ``frame``, the
document's ``license`` / ``attribution`` and the real-site warning as a plan's does
(:func:`ris_planner.io.geoplan.site_warnings`), and ``plan.geojson``, ``heatmap.tif`` and
``points.csv`` are written through the plans' writer registry
(:data:`~ris_planner.io.gis_outputs.PLAN_WRITERS`) over the whole city: every cell's chosen
sites at city-level candidate indices, one heatmap, every RX point once.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ris_planner.io import MissingExtraError
from ris_planner.runtime.progress import ProgressCallback, no_progress

if TYPE_CHECKING:
    from ris_planner.io.frames import Frame
    from ris_planner.planning.city import City


@dataclass(frozen=True)
class CityRequest:
    """A city document split and admitted (:func:`admit_city`)."""

    given: dict[str, Any]
    """The document as given (a geographic one in its own coordinates)."""
    local: dict[str, Any]
    frame: Frame | None
    city: City


def admit_city(
    document: dict[str, Any], cell_m: float, memory_mb: int | None = None
) -> CityRequest:
    """Convert a city document from its frame, split it into cells and admit every cell
    (:func:`~ris_planner.planning.city.split_city`): a refusal names the field or the cell,
    before any cell is planned."""
    from ris_planner.io.candidates import in_document_coordinates
    from ris_planner.io.frames import to_local
    from ris_planner.planning.city import split_city

    local, frame = to_local(document)
    with in_document_coordinates(frame):
        city = split_city(local, cell_m, memory_mb)
    return CityRequest(document, local, frame, city)


@dataclass(frozen=True)
class CityFiles:
    """What :func:`plan_city_document` produced."""

    plan: dict[str, Any]
    files: dict[str, Path]
    note: str | None = None
    """Why the GIS files were skipped (the GIS extra is missing), else None."""


def plan_city_document(
    request: CityRequest,
    out_dir: Path,
    executor: Any = None,
    progress: ProgressCallback = no_progress,
) -> CityFiles:
    """Plan every cell of an admitted city on ``executor`` (closed afterwards; default this
    process), stitch the city's plan.json and write its GIS files into ``out_dir``;
    ``plan.json`` itself is the caller's to write (the command line writes it, a job stores
    it)."""
    from ris_planner.io.frames import license_of_document
    from ris_planner.io.geoplan import site_warnings
    from ris_planner.planning.city import plan_city
    from ris_planner.runtime.executor import SerialExecutor

    ex = SerialExecutor() if executor is None else executor
    with ex:
        plan = plan_city(request.city, ex, progress)
    if request.frame is not None:
        plan["frame"] = request.frame.describe()
    plan.update(license_of_document(request.given))
    plan["warnings"] = [*site_warnings(request.given), *plan["warnings"]]
    note = None
    files: dict[str, Path] = {}
    t0 = time.perf_counter()
    try:
        from ris_planner.io.gis_outputs import write_gis_files

        files = write_gis_files(
            plan, request.given, out_dir, converted=(request.local, request.frame)
        )
    except MissingExtraError as exc:
        note = str(exc)
    plan["timing_s"]["exports"] = time.perf_counter() - t0
    return CityFiles(plan, files, note)
