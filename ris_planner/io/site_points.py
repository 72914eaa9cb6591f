"""The ``sites`` format: mounting points and lines (GeoJSON) → candidate sites and wall
segments (:func:`import_sites`; guide: ``docs/guides/import.md``).

Output: ``{"frame": …, "candidates": […], "walls": […]}`` in WGS84, plus the input's
``license`` / ``attribution`` (:func:`~ris_planner.io.import_options.license_of`); facings are
compass azimuths in the input, engine yaws in the output (:func:`yaw_from_azimuth`).
"""

from __future__ import annotations

import itertools
import math
from typing import Any

from ris_planner.core.errors import RisPlannerError
from ris_planner.io.crs import record_crs, wgs84_collection
from ris_planner.io.feature_positions import (
    collection_features,
    geojson_lines,
    geojson_position,
    import_frame,
    local_positions,
)
from ris_planner.io.import_options import (
    ImportOptions,
    ImportSummary,
    add_license,
    feature_errors,
    feature_label,
    parse_length,
)


def _degrees(props: dict[str, Any], keys: tuple[str, ...], label: str) -> float | None:
    for k in keys:
        if k in props and props[k] is not None:
            v = parse_length(props[k])
            if v is None:
                raise RisPlannerError(f"{label}: {k} must be a number of degrees, got {props[k]!r}")
            return v
    return None


def yaw_from_azimuth(azimuth_deg: float) -> float:
    """Engine yaw (radians from east, counter-clockwise) of a compass azimuth (degrees from
    north, clockwise) – both the direction the RIS faces, in (−π, π]."""
    yaw = math.pi / 2 - math.radians(azimuth_deg)
    return math.atan2(math.sin(yaw), math.cos(yaw))


def import_sites(
    collection: dict[str, Any],
    origin: tuple[float, ...] | None = None,
    options: ImportOptions | None = None,
) -> tuple[dict[str, Any], ImportSummary]:
    """Mounting points and lines (GeoJSON) → candidate sites.

    * Point → ``candidates`` entry: height = ``height``/``height_m`` property, else the
      position's third coordinate; facing = ``azimuth_deg``/``orientation`` (compass degrees,
      clockwise from north, required); downward tilt = ``tilt_deg``/``tilt`` (degrees, 0).
    * LineString → one ``walls`` segment per edge: ``heights_m`` (a list) or ``height``;
      ``spacing_m`` (default ``options.site_spacing_m``); ``side`` (``left``/``right`` of the
      drawing direction, default ``left``); ``tilts_deg`` (a list) or ``tilt_deg`` (0).
    """
    opts = options or ImportOptions()
    collection, crs = wgs84_collection(collection)
    feats = collection_features(collection)
    frame = import_frame(feats, origin, opts)
    h0 = frame.origin[2]
    summary = ImportSummary()
    record_crs(summary, crs)
    candidates: list[dict[str, Any]] = []
    walls: list[dict[str, Any]] = []
    for i, feat in enumerate(feats):
        with feature_errors(i):
            label = feature_label(i, feat)
            if not isinstance(feat, dict) or not isinstance(feat.get("geometry"), dict):
                raise RisPlannerError(f"{label}: no geometry (empty)")
            geom, props = feat["geometry"], feat.get("properties") or {}
            name = props.get("name")
            if geom.get("type") == "Point":
                pos = geojson_position(geom.get("coordinates"), label)
                local_positions(frame, [pos], label)
                height = parse_length(props.get("height", props.get("height_m")))
                if height is None:
                    if len(pos) < 3:
                        raise RisPlannerError(f"{label}: give a height property or a 3-D position")
                    height = pos[2] - h0
                az = _degrees(props, ("azimuth_deg", "orientation"), label)
                if az is None:
                    raise RisPlannerError(
                        f"{label}: give azimuth_deg (the compass direction the RIS faces)"
                    )
                tilt = _degrees(props, ("tilt_deg", "tilt"), label) or 0.0
                cand: dict[str, Any] = {
                    "position": [pos[0], pos[1], height + h0],
                    "orientation": [yaw_from_azimuth(az), math.radians(tilt), 0.0],
                }
                if name:
                    cand["name"] = str(name)
                candidates.append(cand)
                summary.candidates += 1
            elif geom.get("type") == "LineString":
                (line,) = geojson_lines(geom, label)
                local_positions(frame, line, label)
                heights = props.get("heights_m")
                if heights is None and props.get("height") is not None:
                    heights = [props["height"]]
                hs = [parse_length(h) for h in heights] if isinstance(heights, list) else [None]
                if not hs or any(h is None for h in hs):
                    raise RisPlannerError(f"{label}: give heights_m (a list) or height [m]")
                tilts = props.get("tilts_deg", [props.get("tilt_deg", 0.0)])
                ts = [parse_length(t) for t in tilts] if isinstance(tilts, list) else [None]
                if not ts or any(t is None for t in ts):
                    raise RisPlannerError(f"{label}: tilts_deg must be a list of degrees")
                side = props.get("side", "left")
                if side not in ("left", "right"):
                    raise RisPlannerError(f"{label}: side must be 'left' or 'right', got {side!r}")
                spacing = parse_length(props.get("spacing_m", opts.site_spacing_m))
                for a, b in itertools.pairwise(line):
                    if a == b:
                        continue
                    walls.append(
                        {
                            "start": a,
                            "end": b,
                            "side": side,
                            "heights_m": [float(h) + h0 for h in hs if h is not None],
                            "spacing_m": spacing,
                            "tilts_rad": [math.radians(t) for t in ts if t is not None],
                        }
                    )
                    summary.walls += 1
            else:
                summary.skipped += 1
    fragment: dict[str, Any] = {"frame": frame.to_json()}
    add_license(fragment, collection, summary)
    if candidates:
        fragment["candidates"] = candidates
    if walls:
        fragment["walls"] = walls
    return fragment, summary
