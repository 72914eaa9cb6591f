"""GeoJSON / OSM import: buildings → prisms, roads → UE roads, density areas → weighted UE
points, mounting points and lines → candidate sites.

Input coordinates are WGS84 [lon, lat] (RFC 7946). The output is a plain JSON document
fragment in the same coordinates with a ``frame`` (the given origin, or the centre of the
features' bounding box), ready for :func:`ris_planner.io.frames.to_local`:

``{"frame": …, "environment": {"obstacles": [prism…]}, "ue_map": {"roads": […], "points": […],
"weights": […]}}`` (:func:`import_features`) and ``{"frame": …, "candidates": […], "walls":
[…]}`` (:func:`import_sites`). Copy ``ue_map``'s entries into ``tx_map``/``rx_map``.

Rules (each applied count is in the :class:`ImportSummary`):

* Buildings: (Multi)Polygons with a ``building`` property other than ``no`` (or any polygon
  without a density property when no feature of the file has ``building``: a plain building
  layer). Top = ``height`` (metres; ``"12 m"``, ``"40 ft"`` parsed), else ``building:levels``
  × ``metres_per_level`` (default :data:`METRES_PER_LEVEL`), else ``default_height_m``
  (:data:`DEFAULT_BUILDING_HEIGHT_M`, listed in the summary); base = ``min_height``, else
  ``building:min_level`` × metres per level, else 0. A MultiPolygon gives one prism per part;
  holes (courtyards) are dropped – the outer ring is extruded, which can only block more legs –
  and counted.
* Roads: (Multi)LineStrings with a ``highway`` class of :data:`HIGHWAY_WIDTH_M` (other
  classes are skipped and counted), or with a ``width``. Width = ``width`` property, else the
  class default of :data:`HIGHWAY_WIDTH_M`; sampled every ``road_step_m`` at ``ue_height_m``.
* UE areas: Polygons with a numeric ``density_key`` property (default ``density``, UEs per m²
  or any relative unit): a grid of cell centres every ``area_step_m`` inside the polygon (holes
  excluded), each weighing density × cell area; a polygon smaller than a cell gets one point
  of weight density × area at its representative point.
* Invalid geometries – empty, unclosed rings, self-intersecting outlines, coordinates outside
  ±180°/±90° or farther than :data:`~ris_planner.io.frames.MAX_FRAME_RADIUS_M` from the origin
  (lat/lon swapped) – raise :class:`RisPlannerError` naming the feature (index, id, name).

``.osm`` XML (JOSM, Overpass, openstreetmap.org exports) is read with the standard library's
:mod:`xml.etree.ElementTree` (:func:`osm_xml_features`): the format is flat (nodes, ways with
node references, tags), so no binary dependency is needed; for ``.pbf`` files convert with
``osmium export`` or read them with the ``osmium`` package as ``examples/helsinki/extract.py``
does.
"""

from __future__ import annotations

import itertools
import math
import re
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.errors import DocumentFieldError, RisPlannerError
from ris_planner.io import require
from ris_planner.io.frames import MAX_FRAME_RADIUS_M, Frame

FloatArray = NDArray[np.float64]

METRES_PER_LEVEL = 3.0
"""Storey height used for ``building:levels`` and ``building:min_level`` [m]."""

DEFAULT_BUILDING_HEIGHT_M = 10.0
"""Height of a building with no ``height`` and no ``building:levels`` [m] (reported)."""

DEFAULT_ROAD_STEP_M = 5.0
"""Default UE sampling step along and across imported roads [m]."""

DEFAULT_UE_HEIGHT_M = 1.5
"""Default height of imported UE positions (roads, areas) [m]."""

DEFAULT_AREA_STEP_M = 5.0
"""Default grid step inside density polygons [m]."""

DEFAULT_SITE_SPACING_M = 5.0
"""Default spacing of candidate sites along an imported mounting line [m]."""

HIGHWAY_WIDTH_M: dict[str, float] = {
    "motorway": 15.0,
    "trunk": 12.0,
    "primary": 10.0,
    "secondary": 8.0,
    "tertiary": 7.0,
    "unclassified": 6.0,
    "residential": 6.0,
    "living_street": 5.0,
    "service": 4.0,
    "pedestrian": 5.0,
    "footway": 2.0,
    "cycleway": 2.0,
    "path": 1.5,
    "steps": 2.0,
}
"""Width of a road without a ``width`` property, per OSM ``highway`` class [m] (typical
carriageway widths: two 3–3.5 m lanes for residential and tertiary streets, more lanes up the
hierarchy; footways and paths one or two walkers wide)."""

_COORD_DIGITS = 9
"""Decimals of degrees kept in computed points (1e-9° ≈ 0.1 mm)."""


@dataclass
class ImportOptions:
    """Defaults of :func:`import_features` (see the module docstring)."""

    metres_per_level: float = METRES_PER_LEVEL
    default_height_m: float = DEFAULT_BUILDING_HEIGHT_M
    road_step_m: float = DEFAULT_ROAD_STEP_M
    ue_height_m: float = DEFAULT_UE_HEIGHT_M
    density_key: str = "density"
    area_step_m: float = DEFAULT_AREA_STEP_M
    site_spacing_m: float = DEFAULT_SITE_SPACING_M
    highways: tuple[str, ...] | None = None
    """Road classes to import (default: every class of :data:`HIGHWAY_WIDTH_M`)."""


@dataclass
class ImportSummary:
    """What an import did (printed by ``ris-planner import`` on stderr)."""

    buildings: int = 0
    prisms: int = 0
    heights_from_levels: int = 0
    default_height: list[str] = field(default_factory=list)
    holes_dropped: int = 0
    roads: int = 0
    roads_skipped: dict[str, int] = field(default_factory=dict)
    areas: int = 0
    area_points: int = 0
    candidates: int = 0
    walls: int = 0
    skipped: int = 0
    notes: list[str] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {k: v for k, v in self.__dict__.items() if v not in (0, [], {})}


class FeatureError(DocumentFieldError):
    """An error in one feature of a collection: the message names the feature (index, id,
    name; :func:`feature_label`), ``field`` is its path in the collection (``features.3``),
    which the service's 422 lists."""

    def __init__(self, index: int, message: str) -> None:
        super().__init__(f"features.{index}", message)
        self.index = index
        self.args = (message,)  # the message already names the feature

    def __reduce__(self) -> tuple[type, tuple[object, ...]]:
        return type(self), (self.index, self.reason)


@contextmanager
def _feature_errors(index: int) -> Iterator[None]:
    """Re-raise an error about feature ``index`` as a :class:`FeatureError`."""
    try:
        yield
    except DocumentFieldError:
        raise
    except RisPlannerError as exc:
        raise FeatureError(index, str(exc)) from None


def feature_label(index: int, feature: Any) -> str:
    """'feature 3 (id way/42, name 'Kirjasto')' – how errors name a feature."""
    props = (feature.get("properties") or {}) if isinstance(feature, dict) else {}
    fid = feature.get("id") if isinstance(feature, dict) else None
    if fid is None:
        fid = props.get("@id", props.get("osm_id", props.get("id")))
    parts = [f"id {fid}"] if fid is not None else []
    if props.get("name"):
        parts.append(f"name {props['name']!r}")
    return f"feature {index}" + (f" ({', '.join(parts)})" if parts else "")


_NUMBER = re.compile(r"^\s*([-+]?\d+(?:[.,]\d+)?)\s*(m|meters?|metres?|ft|feet|')?\s*$", re.I)


def parse_length(value: Any) -> float | None:
    """Metres from ``12``, ``"12.5"``, ``"12 m"``, ``"40 ft"``, ``"40'"``; ``None`` if not."""
    if isinstance(value, bool):
        return None
    if isinstance(value, int | float):
        return float(value) if math.isfinite(value) else None
    if not isinstance(value, str):
        return None
    m = _NUMBER.match(value)
    if m is None:
        return None
    x = float(m.group(1).replace(",", "."))
    unit = (m.group(2) or "m").lower()
    return x * 0.3048 if unit in ("ft", "feet", "'") else x


def _lonlat(pos: Any, label: str) -> list[float]:
    if (
        not isinstance(pos, list | tuple)
        or len(pos) < 2
        or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in pos)
    ):
        raise RisPlannerError(f"{label}: a position must be [lon, lat(, h)] numbers, got {pos!r}")
    lon, lat = float(pos[0]), float(pos[1])
    if not (math.isfinite(lon) and math.isfinite(lat) and -180 <= lon <= 180 and -90 <= lat <= 90):
        raise RisPlannerError(
            f"{label}: [{pos[0]}, {pos[1]}] is not a WGS84 [lon, lat] position (lon within ±180°,"
            " lat within ±90°)"
        )
    return [lon, lat, *(float(v) for v in pos[2:3])]


def _ring(coords: Any, label: str) -> list[list[float]]:
    """A closed GeoJSON linear ring → its open vertex list (consecutive repeats removed)."""
    if not isinstance(coords, list) or len(coords) == 0:
        raise RisPlannerError(f"{label}: empty ring")
    pts = [_lonlat(p, label)[:2] for p in coords]
    if pts[0] != pts[-1]:
        raise RisPlannerError(
            f"{label}: ring is not closed (first position {pts[0]} ≠ last {pts[-1]}; RFC 7946)"
        )
    open_pts = [p for i, p in enumerate(pts[:-1]) if i == 0 or p != pts[i - 1]]
    if len(open_pts) < 3:
        raise RisPlannerError(f"{label}: a ring needs at least 3 distinct positions")
    return open_pts


def _polygons(geom: dict[str, Any], label: str) -> list[list[list[list[float]]]]:
    """The rings of a Polygon / MultiPolygon as [polygon][ring][vertex] (open rings)."""
    coords = geom.get("coordinates")
    if not isinstance(coords, list) or not coords:
        raise RisPlannerError(f"{label}: empty {geom.get('type')} geometry")
    polys = coords if geom["type"] == "MultiPolygon" else [coords]
    out = []
    for k, poly in enumerate(polys):
        where = f"{label} polygon {k}" if len(polys) > 1 else label
        if not isinstance(poly, list) or not poly:
            raise RisPlannerError(f"{where}: empty polygon")
        out.append([_ring(r, f"{where} ring {j}") for j, r in enumerate(poly)])
    return out


def _lines(geom: dict[str, Any], label: str) -> list[list[list[float]]]:
    coords = geom.get("coordinates")
    lines = coords if geom["type"] == "MultiLineString" else [coords]
    if not isinstance(lines, list) or not lines or not all(isinstance(c, list) for c in lines):
        raise RisPlannerError(f"{label}: empty {geom.get('type')} geometry")
    out = []
    for line in lines:
        pts = [_lonlat(p, label)[:2] for p in line]
        if len(pts) < 2 or all(p == pts[0] for p in pts):
            raise RisPlannerError(f"{label}: a line needs at least 2 distinct positions")
        out.append(pts)
    return out


def _local(frame: Frame, pts: list[list[float]], label: str) -> FloatArray:
    """Local x, y [n, 2] of lon/lat positions; an error naming the feature when it lies
    farther than MAX_FRAME_RADIUS_M from the origin."""
    xy = frame.from_source(np.asarray(pts, dtype=float)[:, :2])
    d = np.hypot(xy[:, 0], xy[:, 1])
    if np.any(d > MAX_FRAME_RADIUS_M):
        k = int(np.argmax(d))
        raise RisPlannerError(
            f"{label}: position {pts[k][:2]} lies {d[k] / 1000:.0f} km from the origin"
            f" {list(frame.origin[:2])} (limit {MAX_FRAME_RADIUS_M / 1000:g} km): lat/lon"
            " swapped? (GeoJSON order is [lon, lat])"
        )
    return xy


def _check_outline(xy: FloatArray, label: str) -> Any:
    """A valid shapely Polygon of a local outline, or an error naming the feature."""
    shapely = require("shapely")
    poly = shapely.Polygon(xy)
    if not poly.is_valid:
        raise RisPlannerError(f"{label}: invalid outline ({shapely.is_valid_reason(poly)})")
    return poly


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


def _features(collection: Any) -> list[Any]:
    if isinstance(collection, dict) and collection.get("type") == "FeatureCollection":
        feats = collection.get("features")
        if isinstance(feats, list):
            return feats
    raise RisPlannerError("expected a GeoJSON FeatureCollection with a features list")


def _frame_of(features: list[Any], origin: tuple[float, ...] | None) -> Frame:
    if origin is None:
        return Frame(default_origin(features))
    o = tuple(float(v) for v in origin)
    return Frame((o[0], o[1], o[2] if len(o) > 2 else 0.0))


def _is_building(props: dict[str, Any], layer_has_building_tag: bool) -> bool:
    b = props.get("building")
    if b is not None:
        return str(b).lower() != "no"
    return not layer_has_building_tag or "height" in props or "building:levels" in props


def _heights(
    props: dict[str, Any], opts: ImportOptions, label: str, summary: ImportSummary
) -> tuple[float, float]:
    """(base_m, height_m) of a building (module docstring rules)."""
    top = parse_length(props.get("height"))
    if top is None:
        levels = parse_length(props.get("building:levels"))
        if levels is not None and levels > 0:
            top = levels * opts.metres_per_level
            summary.heights_from_levels += 1
    if top is None:
        top = opts.default_height_m
        summary.default_height.append(label)
    base = parse_length(props.get("min_height"))
    if base is None:
        min_level = parse_length(props.get("building:min_level"))
        base = min_level * opts.metres_per_level if min_level is not None else 0.0
    if not top > base >= 0:
        raise RisPlannerError(
            f"{label}: building top {top:g} m must lie above its base {base:g} m ≥ 0"
            " (height, building:levels, min_height)"
        )
    return base, top - base


def _area_points(poly: Any, density: float, opts: ImportOptions) -> tuple[FloatArray, FloatArray]:
    """(local x, y [n, 2], weights [n]) of the grid cells of a density polygon."""
    shapely = require("shapely")
    step = opts.area_step_m
    x0, y0, x1, y1 = poly.bounds
    xs = np.arange(x0 + step / 2, x1, step)
    ys = np.arange(y0 + step / 2, y1, step)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    inside = shapely.contains_xy(poly, gx.ravel(), gy.ravel())
    xy = np.column_stack([gx.ravel()[inside], gy.ravel()[inside]])
    if len(xy) == 0:
        p = poly.representative_point()
        return np.array([[p.x, p.y]]), np.array([density * poly.area])
    return xy, np.full(len(xy), density * step * step)


def import_features(
    collection: dict[str, Any],
    origin: tuple[float, ...] | None = None,
    options: ImportOptions | None = None,
) -> tuple[dict[str, Any], ImportSummary]:
    """A GeoJSON FeatureCollection of buildings, roads and density areas → (document fragment
    with ``frame``, ``environment`` and ``ue_map``, summary). See the module docstring."""
    shapely = require("shapely")
    opts = options or ImportOptions()
    feats = _features(collection)
    frame = _frame_of(feats, origin)
    h0 = frame.origin[2]
    summary = ImportSummary()
    obstacles: list[dict[str, Any]] = []
    roads: list[dict[str, Any]] = []
    points: list[list[float]] = []
    weights: list[float] = []
    has_building_tag = any(
        isinstance(f, dict) and "building" in (f.get("properties") or {}) for f in feats
    )
    for i, feat in enumerate(feats):
        with _feature_errors(i):
            label = feature_label(i, feat)
            if not isinstance(feat, dict) or feat.get("type") != "Feature":
                raise RisPlannerError(f"{label}: not a GeoJSON Feature")
            geom = feat.get("geometry")
            props = feat.get("properties") or {}
            if not isinstance(geom, dict):
                raise RisPlannerError(f"{label}: no geometry (empty)")
            kind = geom.get("type")
            name = props.get("name") or (str(feat["id"]) if feat.get("id") is not None else None)
            if kind in ("Polygon", "MultiPolygon"):
                rings = _polygons(geom, label)
                density = parse_length(props.get(opts.density_key))
                if density is not None:
                    if density < 0:
                        raise RisPlannerError(f"{label}: {opts.density_key} must be ≥ 0")
                    for k, poly_rings in enumerate(rings):
                        where = f"{label} polygon {k}" if len(rings) > 1 else label
                        local = [_local(frame, r, where) for r in poly_rings]
                        _check_outline(local[0], where)
                        poly = shapely.Polygon(local[0], local[1:])
                        if not poly.is_valid:
                            raise RisPlannerError(
                                f"{where}: invalid polygon ({shapely.is_valid_reason(poly)})"
                            )
                        xy, w = _area_points(poly, density, opts)
                        ll = frame.to_geographic(xy)
                        points += [
                            [
                                round(a, _COORD_DIGITS),
                                round(b, _COORD_DIGITS),
                                opts.ue_height_m + h0,
                            ]
                            for a, b in ll.tolist()
                        ]
                        weights += w.tolist()
                        summary.area_points += len(xy)
                    summary.areas += 1
                    continue
                if not _is_building(props, has_building_tag):
                    summary.skipped += 1
                    continue
                base, height = _heights(props, opts, label, summary)
                summary.buildings += 1
                for k, poly_rings in enumerate(rings):
                    where = f"{label} polygon {k}" if len(rings) > 1 else label
                    _check_outline(_local(frame, poly_rings[0], where), where)
                    summary.holes_dropped += len(poly_rings) - 1
                    prism: dict[str, Any] = {
                        "kind": "prism",
                        "footprint": poly_rings[0],
                        "base_m": base + h0,
                        "height_m": height,
                    }
                    if name is not None:
                        prism["name"] = f"{name}#{k}" if len(rings) > 1 else str(name)
                    obstacles.append(prism)
                    summary.prisms += 1
            elif kind in ("LineString", "MultiLineString"):
                highway = props.get("highway")
                width = parse_length(props.get("width"))
                if opts.highways is not None and str(highway) not in opts.highways:
                    key = f"{highway} (not chosen)"
                    summary.roads_skipped[key] = summary.roads_skipped.get(key, 0) + 1
                    continue
                if width is None:
                    if highway is None or str(highway) not in HIGHWAY_WIDTH_M:
                        key = str(highway) if highway is not None else "(no highway, no width)"
                        summary.roads_skipped[key] = summary.roads_skipped.get(key, 0) + 1
                        continue
                    width = HIGHWAY_WIDTH_M[str(highway)]
                if not width > 0:
                    raise RisPlannerError(f"{label}: road width must be > 0, got {width}")
                for line in _lines(geom, label):
                    _local(frame, line, label)
                    roads.append(
                        {
                            "points": line,
                            "width_m": width,
                            "step_m": opts.road_step_m,
                            "height_m": opts.ue_height_m + h0,
                        }
                    )
                summary.roads += 1
            else:
                summary.skipped += 1
    if summary.holes_dropped:
        summary.notes.append(
            f"{summary.holes_dropped} inner ring(s) (courtyards) dropped: outer rings extruded"
        )
    fragment: dict[str, Any] = {"frame": frame.to_json()}
    if obstacles:
        fragment["environment"] = {"obstacles": obstacles}
    ue_map: dict[str, Any] = {}
    if roads:
        ue_map["roads"] = roads
    if points:
        ue_map["points"] = points
        ue_map["weights"] = weights
    if ue_map:
        fragment["ue_map"] = ue_map
    return fragment, summary


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
    feats = _features(collection)
    frame = _frame_of(feats, origin)
    h0 = frame.origin[2]
    summary = ImportSummary()
    candidates: list[dict[str, Any]] = []
    walls: list[dict[str, Any]] = []
    for i, feat in enumerate(feats):
        with _feature_errors(i):
            label = feature_label(i, feat)
            if not isinstance(feat, dict) or not isinstance(feat.get("geometry"), dict):
                raise RisPlannerError(f"{label}: no geometry (empty)")
            geom, props = feat["geometry"], feat.get("properties") or {}
            name = props.get("name")
            if geom.get("type") == "Point":
                pos = _lonlat(geom.get("coordinates"), label)
                _local(frame, [pos], label)
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
                (line,) = _lines(geom, label)
                _local(frame, line, label)
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
    if candidates:
        fragment["candidates"] = candidates
    if walls:
        fragment["walls"] = walls
    return fragment, summary


def osm_xml_features(
    source: str | Path | IO[bytes], name: str | None = None
) -> tuple[dict[str, Any], ImportSummary]:
    """An ``.osm`` XML file (a path or a binary stream; ``name`` labels it in errors, default
    the path) → a GeoJSON FeatureCollection (building ways → Polygons, building multipolygon
    relations → MultiPolygons of their closed outer ways, highway ways → LineStrings), tags as
    properties, ids ``way/N`` / ``relation/N``."""
    summary = ImportSummary()
    what = name if name is not None else str(source)
    try:
        root = ET.parse(source).getroot()
    except (ET.ParseError, OSError) as exc:
        raise RisPlannerError(f"{what}: not a readable OSM XML file ({exc})") from None
    if root.tag != "osm":
        raise RisPlannerError(f"{what}: not OSM XML (root element <{root.tag}>)")
    nodes: dict[str, list[float]] = {}
    for n in root.iter("node"):
        try:
            nodes[n.attrib["id"]] = [float(n.attrib["lon"]), float(n.attrib["lat"])]
        except (KeyError, ValueError):
            raise RisPlannerError(f"{what}: node {n.attrib.get('id')} has no lon/lat") from None
    ways: dict[str, tuple[list[list[float]], dict[str, str]]] = {}
    missing = 0
    for w in root.iter("way"):
        refs = [nd.attrib.get("ref", "") for nd in w.iter("nd")]
        if not all(r in nodes for r in refs):
            missing += 1
            continue
        tags = {t.attrib["k"]: t.attrib.get("v", "") for t in w.iter("tag") if "k" in t.attrib}
        ways[w.attrib.get("id", "?")] = ([nodes[r] for r in refs], tags)
    if missing:
        summary.notes.append(f"{missing} way(s) reference nodes outside the file: skipped")
    features: list[dict[str, Any]] = []
    for wid, (pts, tags) in ways.items():
        closed = len(pts) >= 4 and pts[0] == pts[-1]
        if "building" in tags and closed:
            geom: dict[str, Any] = {"type": "Polygon", "coordinates": [pts]}
        elif "highway" in tags and not closed:
            geom = {"type": "LineString", "coordinates": pts}
        else:
            continue
        features.append(
            {"type": "Feature", "id": f"way/{wid}", "properties": tags, "geometry": geom}
        )
    for rel in root.iter("relation"):
        tags = {t.attrib["k"]: t.attrib.get("v", "") for t in rel.iter("tag") if "k" in t.attrib}
        if tags.get("type") != "multipolygon" or "building" not in tags:
            continue
        outers = [
            ways[m.attrib["ref"]][0]
            for m in rel.iter("member")
            if m.attrib.get("type") == "way"
            and m.attrib.get("role") == "outer"
            and m.attrib.get("ref") in ways
        ]
        closed_outers = [p for p in outers if len(p) >= 4 and p[0] == p[-1]]
        if len(closed_outers) < len(outers) or not closed_outers:
            summary.notes.append(
                f"relation/{rel.attrib.get('id')}: outer ring split over several ways: skipped"
            )
            continue
        features.append(
            {
                "type": "Feature",
                "id": f"relation/{rel.attrib.get('id')}",
                "properties": tags,
                "geometry": {"type": "MultiPolygon", "coordinates": [[p] for p in closed_outers]},
            }
        )
    return {"type": "FeatureCollection", "features": features}, summary
