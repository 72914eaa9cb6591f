"""GIS output of a plan: ``plan.geojson``, ``heatmap.tif`` and ``points.csv``.

Pure functions over a ``plan.json`` dict (:meth:`PlanResult.to_json`) and the plan document as
it was given (with or without a ``frame``; :func:`~ris_planner.io.frames.to_local` is applied
here to recover the frame and the local obstacles). Per-point results come from
``plan["points"]`` (entries ``{"index", "position", "weight", "bound_m": {"L": …},
"serving": {"L": […]}, "reason": {"L": …}}``, local metres); without them the heatmap's RX
points can be passed (:func:`heatmap_points`), else only sites, candidates and obstacles are
written.

* ``plan.geojson`` (:func:`plan_geojson`): a FeatureCollection with a ``role`` property per
  feature – ``site`` (a chosen RIS: one Point per site of each ranked layout of each count,
  with ``ris_count``, ``rank`` (1 = best), ``azimuth_deg`` (compass direction it faces,
  clockwise from north), ``tilt_deg`` (downwards), ``roll_deg``, ``height_m``, ``size_m`` [width
  along the face, height], ``rows``, ``cols``; angles in degrees, as a GIS and the import's
  input give them – the radians stay in ``plan.json``), ``candidate``, ``ue`` (the per-point
  results) and
  ``obstacle`` (prisms as Polygons with ``base_m``/``height_m``, walls as LineStrings). With a
  geographic frame the coordinates are WGS84 [lon, lat] (RFC 7946: closed rings, exteriors
  counter-clockwise); without one they are local metres and the collection says so in its
  foreign member ``ris_planner_frame`` (a GIS then reads them as an unknown CRS).
* ``heatmap.tif`` (:func:`write_geotiff`): band 1 = the bound [m] (float32) of the best layout of
  the largest count on a regular grid over the UE points (pixel = the median spacing between
  neighbouring points unless given; a pixel holding several points – heights – keeps the
  smallest bound), ``+inf`` at blind spots, nodata (:data:`NODATA`) where no point falls and
  inside buildings (pixel centres inside a prism footprint). CRS: the local transverse
  Mercator frame of the document (a real projected CRS, so a GIS reprojects it exactly), or an
  engineering CRS in metres (``LOCAL_CS``) for local documents.
* ``points.csv`` (:func:`points_csv`): one row per point: index, local x/y/z, lon/lat/h with a
  frame, weight, and per count the bound, the serving RISs and the blind reason.

Licence: a document's top-level ``license`` and ``attribution`` (an import copies them from
its input – :data:`~ris_planner.io.geojson_import.OSM_LICENSE` for OpenStreetMap data) go
into every file: top-level members ``license`` / ``attribution`` of ``plan.geojson``, the
GeoTIFF's ``TIFFTAG_COPYRIGHT`` (and ``license`` / ``attribution`` metadata tags), and comment
lines ``# license: …`` / ``# attribution: …`` before the CSV header (read with
``pandas.read_csv(..., comment="#")``; a document without them writes none).
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.io_json import readable_json
from ris_planner.io import require
from ris_planner.io.frames import Frame, license_of_document, to_local

FloatArray = NDArray[np.float64]

NODATA = -1.0
"""GeoTIFF nodata value: no UE point in the pixel, or inside a building (bounds are ≥ 0)."""

MAX_RASTER_PIXELS = 4_000_000
"""The GeoTIFF grid is coarsened until it has at most this many pixels."""

MIN_PIXEL_M = 0.01
"""Smallest GeoTIFF pixel size [m]."""

LONLAT_DIGITS = 9
"""Decimals of exported degrees (1e-9° ≈ 0.1 mm)."""

LOCAL_CS_WKT = (
    'LOCAL_CS["ris_planner local frame (metres)",LOCAL_DATUM["site origin",0],'
    'UNIT["metre",1],AXIS["x",EAST],AXIS["y",NORTH]]'
)
"""Engineering CRS of the GeoTIFF of a document without a geographic frame."""

GIS_FILES = {"geojson": "plan.geojson", "geotiff": "heatmap.tif", "points_csv": "points.csv"}
"""Job file name → file written by :func:`write_gis_files`."""


def _signed_area(ring: FloatArray) -> float:
    x, y = ring[:, 0], ring[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def closed_ccw_ring(vertices: FloatArray) -> list[list[float]]:
    """An open vertex list [n, 2] → a closed, counter-clockwise GeoJSON ring."""
    v = np.asarray(vertices, dtype=float)
    if len(v) > 1 and np.array_equal(v[0], v[-1]):
        v = v[:-1]
    if _signed_area(v) < 0:
        v = v[::-1]
    ring = v.tolist()
    return [*ring, ring[0]]


class _Out:
    """Local metres → output coordinates (WGS84 with a frame, else local)."""

    def __init__(self, frame: Frame | None) -> None:
        self.frame = frame

    def xy(self, pts: Any) -> FloatArray:
        arr = np.asarray(pts, dtype=float).reshape(-1, np.asarray(pts).shape[-1])[:, :2]
        if self.frame is None:
            return arr
        return np.round(self.frame.to_geographic(arr), LONLAT_DIGITS)


def _feature(geometry: dict[str, Any], props: dict[str, Any]) -> dict[str, Any]:
    return {"type": "Feature", "geometry": geometry, "properties": props}


def _point(xy: FloatArray) -> dict[str, Any]:
    return {"type": "Point", "coordinates": [float(xy[0]), float(xy[1])]}


def _pose(orientation: list[float]) -> dict[str, float]:
    """Compass azimuth, downward tilt and roll in degrees of an engine orientation [yaw,
    pitch, roll] (radians, yaw counter-clockwise from east)."""
    yaw, pitch, roll = (float(v) for v in orientation)
    return {
        "azimuth_deg": (90.0 - math.degrees(yaw)) % 360.0,
        "tilt_deg": math.degrees(pitch),
        "roll_deg": math.degrees(roll),
    }


def _ris_size(document: dict[str, Any]) -> dict[str, Any]:
    from ris_planner.model.plan import RISDefaults
    from ris_planner.model.scenario import SystemParams

    grid = RISDefaults.model_validate(document.get("ris") or {})
    lam = SystemParams.model_validate(document.get("system") or {}).wavelength
    d = lam / 2 if grid.spacing_m is None else grid.spacing_m
    return {"rows": grid.rows, "cols": grid.cols, "size_m": [grid.cols * d, grid.rows * d]}


def plan_geojson(
    plan: dict[str, Any],
    document: dict[str, Any],
    points: list[dict[str, Any]] | None = None,
) -> dict[str, Any]:
    """The FeatureCollection of a plan (module docstring); ``points`` defaults to
    ``plan["points"]`` (absent: no UE features)."""
    local, frame = to_local(document)
    out = _Out(frame)
    h0 = frame.origin[2] if frame is not None else 0.0  # heights back in the document's datum
    size = _ris_size(local)
    cands = plan.get("candidates") or []
    cand_xy = out.xy([c["position"] for c in cands]) if cands else np.zeros((0, 2))
    feats: list[dict[str, Any]] = []
    for entry in plan.get("by_count") or []:
        for rank, lay in enumerate(entry.get("top_layouts") or [], start=1):
            for s in lay["sites"]:
                c = cands[s]
                feats.append(
                    _feature(
                        _point(cand_xy[s]),
                        {
                            "role": "site",
                            "ris_count": entry["ris_count"],
                            "rank": rank,
                            "objective": lay.get("objective"),
                            "candidate": s,
                            "name": c.get("name"),
                            "height_m": float(c["position"][2]) + h0,
                            **_pose(c["orientation"]),
                            **size,
                        },
                    )
                )
    for i, c in enumerate(cands):
        props = {k: v for k, v in c.items() if k not in ("position", "orientation")}
        feats.append(
            _feature(
                _point(cand_xy[i]),
                {
                    "role": "candidate",
                    **props,
                    "height_m": float(c["position"][2]) + h0,
                    **_pose(c["orientation"]),
                },
            )
        )
    pts = plan.get("points") if points is None else points
    if pts:
        pxy = out.xy([p["position"] for p in pts])
        for p, xy in zip(pts, pxy, strict=True):
            props = {k: v for k, v in p.items() if k != "position"}
            feats.append(
                _feature(
                    _point(xy), {"role": "ue", **props, "height_m": float(p["position"][2]) + h0}
                )
            )
    env = local.get("environment") or {}
    for k, ob in enumerate(env.get("obstacles") or []):
        props = {
            "role": "obstacle",
            "index": k,
            "kind": ob.get("kind", "prism"),
            "name": ob.get("name"),
            "base_m": float(ob.get("base_m", 0.0)) + h0,
            "height_m": float(ob["height_m"]),
        }
        if props["kind"] == "prism":
            ring = closed_ccw_ring(out.xy(ob["footprint"]))
            geom: dict[str, Any] = {"type": "Polygon", "coordinates": [ring]}
        else:
            geom = {"type": "LineString", "coordinates": out.xy([ob["start"], ob["end"]]).tolist()}
        feats.append(_feature(geom, props))
    fc: dict[str, Any] = {"type": "FeatureCollection", **license_of_document(document)}
    fc["features"] = feats
    if frame is None:
        fc["ris_planner_frame"] = "local metres (no geographic frame): x east, y north"
    else:
        fc["ris_planner_frame"] = frame.describe()
    return fc


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


def write_geotiff(
    path: Path,
    points: list[dict[str, Any]],
    document: dict[str, Any],
    ris_count: str | None = None,
    pixel_m: float | None = None,
) -> Path:
    """The heatmap GeoTIFF (module docstring) of per-point results for ``ris_count`` (default
    the largest count the points carry)."""
    rasterio = require("rasterio")
    shapely = require("shapely")
    local, frame = to_local(document)
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
    for ob in (local.get("environment") or {}).get("obstacles") or []:
        if ob.get("kind", "prism") != "prism":
            continue
        poly = shapely.Polygon(ob["footprint"])
        x_lo, y_lo, x_hi, y_hi = poly.bounds
        cols = np.nonzero((cx > x_lo) & (cx < x_hi))[0]  # only the pixels of its bounding box
        rows = np.nonzero((cy > y_lo) & (cy < y_hi))[0]
        if len(cols) and len(rows):
            gx, gy = np.meshgrid(cx[cols], cy[rows])
            inside = shapely.contains_xy(poly, gx, gy)
            grid[np.ix_(rows, cols)] = np.where(inside, np.nan, grid[np.ix_(rows, cols)])
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


def points_csv(points: list[dict[str, Any]], document: dict[str, Any]) -> str:
    """The per-point CSV text (module docstring)."""
    _, frame = to_local(document)
    counts = sorted({k for p in points for k in (p.get("bound_m") or {})}, key=int)
    geo = ["lon", "lat", "h_m"] if frame is not None else []
    head = ["index", "x_m", "y_m", "z_m", *geo, "weight"]
    for c in counts:
        head += [f"bound_m_{c}", f"serving_{c}", f"reason_{c}"]
    buf = io.StringIO()
    for k, v in license_of_document(document).items():
        buf.write(f"# {k}: {' '.join(v.split())}\n")
    wr = csv.writer(buf, lineterminator="\n")
    wr.writerow(head)
    pos = np.array([p["position"] for p in points], dtype=float).reshape(-1, 3)
    ll = frame.to_geographic(pos) if frame is not None and len(pos) else None
    for i, p in enumerate(points):
        row: list[Any] = [p.get("index", i), *pos[i].tolist()]
        if ll is not None:
            row += [round(ll[i, 0], LONLAT_DIGITS), round(ll[i, 1], LONLAT_DIGITS), ll[i, 2]]
        row.append(p.get("weight"))
        for c in counts:
            b = (p.get("bound_m") or {}).get(c)
            serving = (p.get("serving") or {}).get(c)
            row += [
                "" if b is None else b,
                "" if serving is None else " ".join(map(str, serving)),
                (p.get("reason") or {}).get(c) or "",
            ]
        wr.writerow(row)
    return buf.getvalue()


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
