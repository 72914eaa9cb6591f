"""``plan.geojson`` (:func:`plan_geojson`): a plan as a GeoJSON FeatureCollection (guide:
``docs/guides/gis.md``).

A pure function over a ``plan.json`` dict (:meth:`PlanResult.to_json`) and the plan document as
it was given (with or without a ``frame``; :func:`~ris_planner.io.frames.to_local` is applied
here to recover the frame and the local obstacles). Each feature has a ``role`` property –
``site`` (a chosen RIS: one Point per site of each ranked layout of each count, with
``ris_count``, ``rank`` (1 = best), ``azimuth_deg`` (compass direction it faces, clockwise from
north), ``tilt_deg`` (downwards), ``roll_deg``, ``height_m``, ``size_m`` [width along the face,
height], ``rows``, ``cols``; angles in degrees, as a GIS and the import's input give them – the
radians stay in ``plan.json``), ``candidate``, ``ue`` (the per-point results of
``plan["points"]``, local metres) and ``obstacle`` (:func:`obstacle_features`: each obstacle's
kind writes its own geometry – prisms as Polygons, walls as LineStrings – and the properties
``kind``, ``name``, ``base_m``, ``height_m``, ``material`` and its own, which the GeoJSON import
reads back; :mod:`ris_planner.environment.kinds.geojson`). With a geographic frame the
coordinates are WGS84 [lon, lat] (RFC 7946: closed rings, exteriors counter-clockwise); without
one they are local metres and the collection says so in its foreign member
``ris_planner_frame`` (a GIS then reads them as an unknown CRS). The document's ``license`` /
``attribution`` are top-level members (:mod:`ris_planner.io.gis_outputs`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.environment.kinds.geojson import obstacle_feature
from ris_planner.environment.model import Environment
from ris_planner.io.frames import Converted, Frame, license_of_document, to_local

FloatArray = NDArray[np.float64]

LONLAT_DIGITS = 9
"""Decimals of exported degrees (1e-9° ≈ 0.1 mm)."""


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


def obstacle_features(
    obstacles: list[dict[str, Any]], out: _Out, h0: float
) -> list[dict[str, Any]]:
    """The ``obstacle`` features of a local document's obstacles (module docstring): each
    kind's geometry and properties
    (:func:`~ris_planner.environment.kinds.geojson.obstacle_feature`), ``base_m`` back in the
    document's datum (``h0``)."""
    env = Environment.model_validate({"obstacles": obstacles})
    feats = []
    for k, ob in enumerate(env.obstacles):
        geom, props = obstacle_feature(ob, out.xy, h0)
        feats.append(_feature(geom, {"role": "obstacle", "index": k, **props}))
    return feats


def plan_geojson(
    plan: dict[str, Any],
    document: dict[str, Any],
    points: list[dict[str, Any]] | None = None,
    converted: Converted | None = None,
) -> dict[str, Any]:
    """The FeatureCollection of a plan (module docstring); ``points`` defaults to
    ``plan["points"]`` (absent: no UE features); ``converted``: the document in local metres
    and its frame when the caller converted it already."""
    local, frame = to_local(document) if converted is None else converted
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
    feats += obstacle_features(env.get("obstacles") or [], out, h0)
    fc: dict[str, Any] = {"type": "FeatureCollection", **license_of_document(document)}
    fc["features"] = feats
    if frame is None:
        fc["ris_planner_frame"] = "local metres (no geographic frame): x east, y north"
    else:
        fc["ris_planner_frame"] = frame.describe()
    return fc
