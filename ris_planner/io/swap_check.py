"""lat/lon swap detection of a GeoJSON collection before its frame is made
(:func:`check_positions`; guide: ``docs/guides/import.md``).

A position whose latitude is beyond ±90° while its longitude is not
(:func:`~ris_planner.io.feature_positions.geojson_position`); a feature far (beyond
:data:`~ris_planner.io.frames.MAX_FRAME_RADIUS_M`) from the origin – or, without one, from the
median of the features – that would lie near it read as [lat, lon]; an ``origin`` that lies
near the features only read as [lat, lon]; and a file whose building corners are square only
when read as [lat, lon] (:data:`SWAP_MIN_CORNERS`; ``options.swap_check``). Each is an error
whose message says "swapped?" and names the feature (or ``origin``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.errors import DocumentFieldError
from ris_planner.io.frames import MAX_FRAME_RADIUS_M, great_circle_m
from ris_planner.io.import_options import (
    FeatureError,
    ImportOptions,
    feature_anchor,
    feature_label,
    lonlat_text,
)

FloatArray = NDArray[np.float64]

SWAP_MIN_CORNERS = 12
"""The file-wide lat/lon swap test needs at least this many building corners."""


SWAP_RIGHT_ANGLE_DEG = 3.0
"""A building corner within this of 90° is square (the file-wide swap test)."""


def _corner_square_fraction(rings: list[FloatArray], lat0: float) -> tuple[int, float]:
    """(corners, fraction within :data:`SWAP_RIGHT_ANGLE_DEG` of 90°) of open lon/lat rings
    [n, 2] drawn with x = lon·cos(lat0), y = lat (straight corners within 10° of 180° are not
    counted)."""
    k = math.cos(math.radians(lat0))
    angles = []
    for r in rings:
        xy = np.column_stack([r[:, 0] * k, r[:, 1]])
        a = np.roll(xy, 1, axis=0) - xy
        b = np.roll(xy, -1, axis=0) - xy
        cos = np.sum(a * b, axis=1) / np.maximum(
            np.hypot(a[:, 0], a[:, 1]) * np.hypot(b[:, 0], b[:, 1]), 1e-300
        )
        angles.append(np.degrees(np.arccos(np.clip(cos, -1, 1))))
    ang = np.concatenate(angles) if angles else np.zeros(0)
    ang = ang[np.abs(ang - 180) > 10]
    if len(ang) == 0:
        return 0, 0.0
    return len(ang), float(np.mean(np.abs(ang - 90) < SWAP_RIGHT_ANGLE_DEG))


def _swapped_file(feats: list[Any]) -> str | None:
    """Why the whole file looks lat/lon swapped (its building corners are square only when
    read as [lat, lon]), or None. Needs :data:`SWAP_MIN_CORNERS`; at latitudes where a degree
    of longitude and one of latitude are about as long as read swapped, a swap is a mere
    mirror image and cannot be told from the shapes."""
    rings: list[FloatArray] = []
    first: int | None = None
    for i, f in enumerate(feats):
        geom = f.get("geometry") if isinstance(f, dict) else None
        if not isinstance(geom, dict) or geom.get("type") not in ("Polygon", "MultiPolygon"):
            continue
        coords: Any = geom.get("coordinates")
        polys: list[Any] = (coords if geom["type"] == "MultiPolygon" else [coords]) or []
        for poly in polys if isinstance(polys, list) else []:
            try:
                r: FloatArray = np.asarray(poly[0], dtype=np.float64)[:, :2]
            except (TypeError, ValueError, IndexError):
                continue
            if r.ndim != 2 or len(r) < 4:
                continue
            r = r[:-1] if np.array_equal(r[0], r[-1]) else r
            keep = np.any(np.diff(np.vstack([r, r[:1]]), axis=0) != 0, axis=1)
            if np.count_nonzero(keep) >= 3:
                rings.append(r[keep])
                first = i if first is None else first
    if not rings or first is None:
        return None
    allp = np.vstack(rings)
    if np.any(np.abs(allp[:, 0]) > 90):
        return None  # cannot be a latitude
    lat_as_given = float(np.median(allp[:, 1]))
    lat_swapped = float(np.median(allp[:, 0]))
    n, given = _corner_square_fraction(rings, lat_as_given)
    _, swapped = _corner_square_fraction([r[:, ::-1] for r in rings], lat_swapped)
    if n >= SWAP_MIN_CORNERS and swapped >= 0.5 and given < 0.5 * swapped:
        return (
            f"{given:.0%} of the {n} building corners are square as given, {swapped:.0%} read"
            " as [lat, lon]: lat/lon swapped? (GeoJSON order is [lon, lat]; if the data is"
            " right, turn the swap check off)"
        )
    return None


def check_positions(
    feats: list[Any], origin: tuple[float, ...] | None, options: ImportOptions
) -> None:
    """The lat/lon swap and distance checks of a collection before its frame is made (module
    docstring): each feature's first position against the ``origin`` (or, without one, the
    median of the features' first positions); raises :class:`FeatureError` naming the feature,
    or :class:`DocumentFieldError` on ``origin`` when it is the origin that is swapped or far."""
    anchors: list[tuple[int, list[float]]] = []
    for i, f in enumerate(feats):
        a = feature_anchor(f)
        if (
            a is not None
            and all(math.isfinite(v) for v in a)
            and abs(a[1]) <= 90
            and abs(a[0]) <= 180
        ):
            anchors.append((i, a))
    if anchors:
        pts = np.array([a for _, a in anchors])
        if origin is not None:
            centre = (float(origin[0]), float(origin[1]), 0.0)
            d = great_circle_m(pts, centre)
            if not np.any(d <= MAX_FRAME_RADIUS_M):
                where = lonlat_text(list(np.median(pts, axis=0)))
                swapped_o = great_circle_m(pts, (centre[1], centre[0], 0.0))
                near = int(np.argmin(d))
                example = feature_label(anchors[near][0], feats[anchors[near][0]])
                if abs(centre[0]) <= 90 and np.median(swapped_o) <= MAX_FRAME_RADIUS_M:
                    raise DocumentFieldError(
                        "origin",
                        f"{lonlat_text(list(centre))} lies {np.min(d) / 1000:.0f} km from the"
                        f" nearest feature, {example} (the features lie around {where}); read"
                        " as [lat, lon] the origin lies among them: lat/lon swapped? (in the"
                        " origin – give LON,LAT – or in every feature)",
                    )
                swapped_f = great_circle_m(pts[:, ::-1], centre)
                if np.median(swapped_f) > MAX_FRAME_RADIUS_M or np.any(np.abs(pts[:, 0]) > 90):
                    raise DocumentFieldError(
                        "origin",
                        f"{lonlat_text(list(centre))} lies {np.min(d) / 1000:.0f} km from the"
                        f" nearest feature, {example} (the features lie around {where}; limit"
                        f" {MAX_FRAME_RADIUS_M / 1000:g} km): the wrong origin?",
                    )
        else:
            centre = (float(np.median(pts[:, 0])), float(np.median(pts[:, 1])), 0.0)
            d = great_circle_m(pts, centre)
        far = d > MAX_FRAME_RADIUS_M
        if np.any(far):
            k = int(np.argmax(far))
            i, a = anchors[k]
            ref = "the origin" if origin is not None else "the median of the features"
            swapped = great_circle_m(np.array([a[::-1]]), centre)[0]
            hint = (
                f"lat/lon swapped? (read as [lat, lon] it lies {swapped / 1000:.1f} km away;"
                " GeoJSON order is [lon, lat])"
                if swapped <= MAX_FRAME_RADIUS_M and abs(a[0]) <= 90
                else "a stray feature?"
            )
            raise FeatureError(
                i,
                f"{feature_label(i, feats[i])}: lies {d[k] / 1000:.0f} km from {ref}"
                f" {lonlat_text(list(centre))} (limit {MAX_FRAME_RADIUS_M / 1000:g} km): {hint}",
            )
    if options.swap_check:
        why = _swapped_file(feats)
        if why is not None:
            i = next(
                j
                for j, f in enumerate(feats)
                if isinstance(f, dict)
                and isinstance(f.get("geometry"), dict)
                and f["geometry"].get("type") in ("Polygon", "MultiPolygon")
            )
            raise DocumentFieldError("features", f"{why}; e.g. {feature_label(i, feats[i])}")
