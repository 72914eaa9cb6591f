"""``heatmap.tif`` (:func:`write_geotiff`): a plan's per-point bounds as a GeoTIFF (guide:
``docs/guides/gis.md``).

Band 1 = the bound [m] (float32) of the best layout of the largest count on a regular grid over
the UE points (pixel = the median spacing between neighbouring points unless given,
:func:`raster_grid`; a pixel holding several points – heights – keeps the smallest bound),
``+inf`` at blind spots, nodata (:data:`NODATA`) where no point falls and inside buildings
(pixel centres inside the footprint of a solid obstacle of any kind, :func:`without_buildings`).
CRS: the local transverse Mercator frame of the document (a real projected CRS, so a GIS
reprojects it exactly), or an engineering CRS in metres (``LOCAL_CS``) for local documents.
The document's ``license`` / ``attribution`` go into ``TIFFTAG_COPYRIGHT`` and metadata tags
of those names (:mod:`ris_planner.io.gis_outputs`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.environment.kinds import footprint_contains, kind_of
from ris_planner.environment.model import Environment
from ris_planner.io import require
from ris_planner.io.frames import Converted, license_of_document, to_local

FloatArray = NDArray[np.float64]

NODATA = -1.0
"""GeoTIFF nodata value: no UE point in the pixel, or inside a building (bounds are ≥ 0)."""


MAX_RASTER_PIXELS = 4_000_000
"""The GeoTIFF grid is coarsened until it has at most this many pixels."""


MIN_PIXEL_M = 0.01
"""Smallest GeoTIFF pixel size [m]."""


LOCAL_CS_WKT = (
    'LOCAL_CS["ris_planner local frame (metres)",LOCAL_DATUM["site origin",0],'
    'UNIT["metre",1],AXIS["x",EAST],AXIS["y",NORTH]]'
)
"""Engineering CRS of the GeoTIFF of a document without a geographic frame."""


def _largest_count(points: list[dict[str, Any]]) -> str:
    counts = {k for p in points for k in (p.get("bound_m") or {})}
    if not counts:
        raise ValueError("points carry no bound_m")
    return max(counts, key=int)


def raster_grid(
    xy: FloatArray, pixel_m: float | None = None
) -> tuple[float, float, float, int, int]:
    """(x of the first column's centre, y of the first row's centre, pixel size, width,
    height) of a north-up grid over points [M, 2] (pixel: the median nearest-neighbour
    spacing of the distinct points unless given, coarsened to ≤ MAX_RASTER_PIXELS)."""
    uniq = np.unique(np.round(xy, 6), axis=0)
    if pixel_m is None:
        if len(uniq) > 1:
            from scipy.spatial import cKDTree

            d, _ = cKDTree(uniq).query(uniq, k=2)
            pixel_m = float(np.median(d[:, 1]))
        else:
            pixel_m = 1.0
    res = max(float(pixel_m), MIN_PIXEL_M)
    x0, y1 = float(uniq[:, 0].min()), float(uniq[:, 1].max())
    span = np.ptp(uniq, axis=0)
    while True:
        w, h = (int(np.floor(s / res + 0.5)) + 1 for s in span)
        if w * h <= MAX_RASTER_PIXELS:
            return x0, y1, res, w, h
        res *= 2


def without_buildings(
    grid: FloatArray,
    cx: NDArray[np.floating[Any]],
    cy: NDArray[np.floating[Any]],
    obstacles: list[dict[str, Any]],
) -> FloatArray:
    """``grid`` [rows, cols] (pixel centres ``cx`` [cols], ``cy`` [rows], local metres) with
    NaN at the pixel centres inside the footprint of a solid obstacle of ``obstacles`` (a local
    document's; :func:`~ris_planner.environment.kinds.footprint_contains`)."""
    grid = grid.copy()
    for ob in Environment.model_validate({"obstacles": obstacles}).obstacles:
        if not kind_of(ob).solid:
            continue
        outline = ob.outline()
        (x_lo, y_lo), (x_hi, y_hi) = outline.min(axis=0), outline.max(axis=0)
        cols = np.nonzero((cx > x_lo) & (cx < x_hi))[0]  # only the pixels of its bounding box
        rows = np.nonzero((cy > y_lo) & (cy < y_hi))[0]
        if len(cols) and len(rows):
            gx, gy = np.meshgrid(cx[cols], cy[rows])
            inside = footprint_contains(ob, np.column_stack([gx.ravel(), gy.ravel()]))
            block = grid[np.ix_(rows, cols)]
            grid[np.ix_(rows, cols)] = np.where(inside.reshape(gx.shape), np.nan, block)
    return grid


def write_geotiff(
    path: Path,
    points: list[dict[str, Any]],
    document: dict[str, Any],
    ris_count: str | None = None,
    pixel_m: float | None = None,
    converted: Converted | None = None,
) -> Path:
    """The heatmap GeoTIFF (module docstring) of per-point results for ``ris_count`` (default
    the largest count the points carry); ``converted``: the document in local metres and its
    frame when the caller converted it already."""
    rasterio = require("rasterio")
    local, frame = to_local(document) if converted is None else converted
    key = ris_count or _largest_count(points)
    pos = np.array([p["position"] for p in points], dtype=float)
    val = np.array(
        [
            np.inf if (p.get("bound_m") or {}).get(key) is None else p["bound_m"][key]
            for p in points
        ],
        dtype=float,
    )
    x0, y1, res, w, h = raster_grid(pos[:, :2], pixel_m)
    col = np.floor((pos[:, 0] - x0) / res + 0.5).astype(int)
    row = np.floor((y1 - pos[:, 1]) / res + 0.5).astype(int)
    grid = np.full((h, w), np.nan)
    flat = row * w + col
    order = np.argsort(val, kind="stable")[::-1]  # the smallest bound written last wins
    grid.ravel()[flat[order]] = val[order]
    cx = x0 + res * np.arange(w)
    cy = y1 - res * np.arange(h)
    grid = without_buildings(grid, cx, cy, (local.get("environment") or {}).get("obstacles") or [])
    data = np.where(np.isnan(grid), NODATA, grid).astype(np.float32)
    crs = frame.local_crs().to_wkt() if frame is not None else LOCAL_CS_WKT
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        width=w,
        height=h,
        count=1,
        dtype="float32",
        crs=rasterio.crs.CRS.from_wkt(crs),
        # north up: x = c + col·res, y = f − row·res at pixel corners (no from_origin: it
        # multiplies Affine objects with `*`, deprecated by affine 3)
        transform=rasterio.Affine(res, 0.0, x0 - res / 2, 0.0, -res, y1 + res / 2),
        nodata=NODATA,
        compress="deflate",
    ) as ds:
        ds.write(data, 1)
        ds.set_band_description(1, f"bound_m for {key} RIS (inf = blind spot)")
        ds.update_tags(ris_count=key, units="m", blind="inf", nodata_meaning="no UE / building")
        lic = license_of_document(document)
        if lic:
            ds.update_tags(TIFFTAG_COPYRIGHT="; ".join(lic.values()), **lic)
    return path
