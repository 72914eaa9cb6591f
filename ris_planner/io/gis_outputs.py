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
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.io_json import readable_json
from ris_planner.io.geojson_write import plan_geojson
from ris_planner.io.geotiff import write_geotiff
from ris_planner.io.points_csv import points_csv

FloatArray = NDArray[np.float64]

GIS_FILES = {"geojson": "plan.geojson", "geotiff": "heatmap.tif", "points_csv": "points.csv"}
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
) -> dict[str, Path]:
    """Write ``plan.geojson``, and with per-point results (``plan["points"]`` or ``points``)
    ``heatmap.tif`` and ``points.csv``; returns :data:`GIS_FILES` name → path."""

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    pts = plan.get("points") or points
    paths = {"geojson": out_dir / GIS_FILES["geojson"]}
    fc = plan_geojson(plan, document, pts)
    paths["geojson"].write_text(readable_json(fc))
    if pts:
        paths["geotiff"] = write_geotiff(out_dir / GIS_FILES["geotiff"], pts, document)
        paths["points_csv"] = out_dir / GIS_FILES["points_csv"]
        paths["points_csv"].write_text(points_csv(pts, document))
    return paths


def plan_outputs(
    result: Any, plan: dict[str, Any], document: dict[str, Any], out_dir: Path
) -> dict[str, Path]:
    """:func:`write_gis_files` for a :class:`~ris_planner.planning.PlanResult` (of the
    local document): per-point results from ``plan["points"]``, else from the heatmap (the
    RX map points, the bound of the best layout of the largest count)."""
    points = None
    if not plan.get("points"):
        pts, vals, layout = result.heatmap()
        points = heatmap_points(pts, vals, result.rx_map.weights, len(layout))
    return write_gis_files(plan, document, out_dir, points)
