"""GIS output of a plan: ``plan.geojson`` (:mod:`ris_planner.io.geojson_write`),
``heatmap.tif`` (:mod:`ris_planner.io.geotiff`) and ``points.csv``
(:mod:`ris_planner.io.points_csv`), written together by :func:`write_gis_files` (guide:
``docs/guides/gis.md``).

Pure functions over a ``plan.json`` dict (:meth:`PlanResult.to_json`) and the plan document as
it was given (with or without a ``frame``). Per-point results come from ``plan["points"]``
(entries ``{"index", "position", "weight", "bound_m": {"L": …}, "serving": {"L": […]},
"reason": {"L": …}}``, local metres); without them the heatmap's RX points can be passed
(:func:`heatmap_points`), else only sites, candidates and obstacles are written.

Licence: a document's top-level ``license`` and ``attribution`` (an import copies them from
its input – :data:`~ris_planner.io.import_options.OSM_LICENSE` for OpenStreetMap data) go
into every file: top-level members ``license`` / ``attribution`` of ``plan.geojson``, the
GeoTIFF's ``TIFFTAG_COPYRIGHT`` (and ``license`` / ``attribution`` metadata tags), and comment
lines ``# license: …`` / ``# attribution: …`` before the CSV header (read with
``pandas.read_csv(..., comment="#")``; a document without them writes none).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.io_json import readable_json
from ris_planner.io.frames import Converted, to_local
from ris_planner.io.geojson_write import plan_geojson
from ris_planner.io.geotiff import write_geotiff
from ris_planner.io.points_csv import points_csv

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class PlanWriter:
    """One GIS file of a plan (:data:`PLAN_WRITERS`): the command line writes it into its
    output folder, a service job stores it under its ``name`` with its ``media_type``, the
    web page offers it for download."""

    name: str
    """The job's file name (``GET /v1/jobs/{id}/files/{name}``)."""
    filename: str
    """The file written into the output folder."""
    media_type: str
    description: str
    per_point: bool
    """Written only with per-point results."""
    write: Callable[[dict[str, Any], dict[str, Any], Converted, Points, Path], None]
    """(plan.json, the document as given, it converted, the per-point results, the path)."""


Points = list[dict[str, Any]]


def _geojson(
    plan: dict[str, Any], doc: dict[str, Any], conv: Converted, pts: Points, to: Path
) -> None:
    to.write_text(readable_json(plan_geojson(plan, doc, pts, conv)))


def _csv(plan: dict[str, Any], doc: dict[str, Any], conv: Converted, pts: Points, to: Path) -> None:
    to.write_text(points_csv(pts, doc, conv))


def _tif(plan: dict[str, Any], doc: dict[str, Any], conv: Converted, pts: Points, to: Path) -> None:
    write_geotiff(to, pts, doc, converted=conv)


PLAN_WRITERS: tuple[PlanWriter, ...] = (
    PlanWriter(
        "geojson",
        "plan.geojson",
        "application/geo+json",
        "chosen sites, candidates, UE results, buildings",
        False,
        _geojson,
    ),
    PlanWriter(
        "geotiff",
        "heatmap.tif",
        "image/tiff",
        "the largest count's bound per RX point (GeoTIFF, the frame's CRS)",
        True,
        _tif,
    ),
    PlanWriter(
        "points_csv",
        "points.csv",
        "text/csv",
        "every RX point's bound, serving sites and reason per count",
        True,
        _csv,
    ),
)
"""The GIS files of a plan, in the order they are written: the one list the command line,
the service's media types and the web page's downloads read (``GET /v1/plan-files``)."""

GIS_FILES = {w.name: w.filename for w in PLAN_WRITERS}
"""Job file name → file written by :func:`write_gis_files`."""


def heatmap_points(
    positions: FloatArray, values: FloatArray, weights: FloatArray, ris_count: int
) -> list[dict[str, Any]]:
    """Per-point entries (``plan["points"]`` format: index, position, weight, bound_m for one
    count; ``null`` = blind) from heatmap arrays [M, 3], [M], [M] (NaN values are left out)."""
    out = []
    for i, (p, v, w) in enumerate(
        zip(positions.tolist(), values.tolist(), weights.tolist(), strict=True)
    ):
        if math.isnan(v):
            continue
        out.append(
            {
                "index": i,
                "position": p,
                "weight": w,
                "bound_m": {str(ris_count): v if math.isfinite(v) else None},
            }
        )
    return out


def write_gis_files(
    plan: dict[str, Any],
    document: dict[str, Any],
    out_dir: Path,
    points: list[dict[str, Any]] | None = None,
    converted: Converted | None = None,
) -> dict[str, Path]:
    """Write every :data:`PLAN_WRITERS` file – the per-point ones only with per-point results
    (``plan["points"]`` or ``points``); returns name → path. ``converted``: the document in
    local metres and its frame when the caller converted it already."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    pts = plan.get("points") or points or []
    conv = to_local(document) if converted is None else converted
    paths: dict[str, Path] = {}
    for writer in PLAN_WRITERS:
        if writer.per_point and not pts:
            continue
        path = out_dir / writer.filename
        writer.write(plan, document, conv, pts, path)
        paths[writer.name] = path
    return paths


def plan_outputs(
    result: Any,
    plan: dict[str, Any],
    document: dict[str, Any],
    out_dir: Path,
    converted: Converted | None = None,
) -> dict[str, Path]:
    """:func:`write_gis_files` for a :class:`~ris_planner.planning.PlanResult` (of the
    local document): per-point results from ``plan["points"]``, else from the heatmap (the
    RX map points, the bound of the best layout of the largest count)."""
    points = None
    if not plan.get("points"):
        pts, vals, layout = result.heatmap()
        points = heatmap_points(pts, vals, result.rx_map.weights, len(layout))
    return write_gis_files(plan, document, out_dir, points, converted)
