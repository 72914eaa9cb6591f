"""Positions of a GeoJSON collection's features → the frame of an import (guide:
``docs/guides/import.md``): checked WGS84 [lon, lat] positions and lines
(:func:`geojson_position`, :func:`geojson_lines`), local metres within
:data:`~ris_planner.io.frames.MAX_FRAME_RADIUS_M` of the origin (:func:`local_positions`), and
the frame (:func:`import_frame`: the given origin, or the centre of the features' bounding box,
:func:`default_origin`, after the lat/lon swap checks of :mod:`ris_planner.io.swap_check`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.errors import RisPlannerError
from ris_planner.io.frames import MAX_FRAME_RADIUS_M, Frame, great_circle_m
from ris_planner.io.import_options import ImportOptions, lonlat_text
from ris_planner.io.swap_check import check_positions

FloatArray = NDArray[np.float64]


def geojson_position(pos: Any, label: str) -> list[float]:
    if (
        not isinstance(pos, list | tuple)
        or len(pos) < 2
        or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in pos)
    ):
        raise RisPlannerError(f"{label}: a position must be [lon, lat(, h)] numbers, got {pos!r}")
    lon, lat = float(pos[0]), float(pos[1])
    if not (math.isfinite(lon) and math.isfinite(lat) and -180 <= lon <= 180 and -90 <= lat <= 90):
        hint = ""
        if math.isfinite(lon) and abs(lon) <= 90 and abs(lat) <= 180:
            hint = " – lat/lon swapped? (it would be a position read as [lat, lon])"
        elif math.isfinite(lon) and math.isfinite(lat) and max(abs(lon), abs(lat)) > 1000:
            hint = (
                " – projected coordinates (metres) without a crs member? Name their CRS in the"
                ' collection\'s crs member ({"type": "name", "properties": {"name":'
                ' "EPSG:3067"}}) or convert the file: ogr2ogr -f GeoJSON -t_srs EPSG:4326'
                " out.geojson in.geojson"
            )
        raise RisPlannerError(
            f"{label}: [{pos[0]}, {pos[1]}] is not a WGS84 [lon, lat] position (lon within ±180°,"
            f" lat within ±90°; GeoJSON order is [lon, lat]){hint}"
        )
    return [lon, lat, *(float(v) for v in pos[2:3])]


def geojson_lines(geom: dict[str, Any], label: str) -> list[list[list[float]]]:
    coords = geom.get("coordinates")
    lines = coords if geom["type"] == "MultiLineString" else [coords]
    if not isinstance(lines, list) or not lines or not all(isinstance(c, list) for c in lines):
        raise RisPlannerError(f"{label}: empty {geom.get('type')} geometry")
    out = []
    for line in lines:
        pts = [geojson_position(p, label)[:2] for p in line]
        if len(pts) < 2 or all(p == pts[0] for p in pts):
            raise RisPlannerError(f"{label}: a line needs at least 2 distinct positions")
        out.append(pts)
    return out


def local_positions(frame: Frame, pts: list[list[float]], label: str) -> FloatArray:
    """Local x, y [n, 2] of lon/lat positions; an error naming the feature when it lies
    farther than MAX_FRAME_RADIUS_M from the origin."""
    src = np.asarray(pts, dtype=float)[:, :2]
    arc = great_circle_m(src, frame.origin)
    xy = frame.from_source(src) if np.all(arc <= 2 * MAX_FRAME_RADIUS_M) else None
    d = np.hypot(xy[:, 0], xy[:, 1]) if xy is not None else arc
    if np.any(d > MAX_FRAME_RADIUS_M):
        k = int(np.argmax(d))
        swapped = great_circle_m(src[k : k + 1, ::-1], frame.origin)[0]
        hint = (
            f"lat/lon swapped? (read as [lat, lon] it lies {swapped / 1000:.1f} km away; GeoJSON"
            " order is [lon, lat])"
            if swapped <= MAX_FRAME_RADIUS_M
            else "a stray position or the wrong frame origin?"
        )
        raise RisPlannerError(
            f"{label}: position {lonlat_text(pts[k])} lies {d[k] / 1000:.0f} km from the origin"
            f" {lonlat_text(list(frame.origin))} (limit {MAX_FRAME_RADIUS_M / 1000:g} km): {hint}"
        )
    assert xy is not None
    return xy


def default_origin(features: list[Any]) -> tuple[float, float, float]:
    """Centre of the bounding box of every position (lon, lat rounded to 1e-6°), h = 0."""
    pts: list[list[float]] = []

    def collect(c: Any) -> None:
        if isinstance(c, list) and c and isinstance(c[0], int | float):
            pts.append([float(c[0]), float(c[1])])
        elif isinstance(c, list):
            for x in c:
                collect(x)

    for f in features:
        if isinstance(f, dict) and isinstance(f.get("geometry"), dict):
            collect(f["geometry"].get("coordinates"))
    if not pts:
        raise RisPlannerError("no positions in the features: nothing to centre the frame on")
    arr = np.asarray(pts)
    ok = (np.abs(arr[:, 0]) <= 180) & (np.abs(arr[:, 1]) <= 90)
    arr = arr[ok] if np.any(ok) else arr
    lon, lat = np.round((arr.min(axis=0) + arr.max(axis=0)) / 2, 6)
    return float(lon), float(lat), 0.0


def collection_features(collection: Any) -> list[Any]:
    if isinstance(collection, dict) and collection.get("type") == "FeatureCollection":
        feats = collection.get("features")
        if isinstance(feats, list):
            return feats
    raise RisPlannerError("expected a GeoJSON FeatureCollection with a features list")


def import_frame(
    features: list[Any], origin: tuple[float, ...] | None, options: ImportOptions
) -> Frame:
    check_positions(features, origin, options)
    if origin is None:
        return Frame(default_origin(features))
    o = tuple(float(v) for v in origin)
    return Frame((o[0], o[1], o[2] if len(o) > 2 else 0.0))
