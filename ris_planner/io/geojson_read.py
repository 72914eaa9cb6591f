"""GeoJSON import: buildings → prisms, roads → UE roads, density areas → weighted UE points
(:func:`import_features`; guide: ``docs/guides/import.md``).

Input coordinates are WGS84 [lon, lat] (RFC 7946), or those of the CRS a ``crs`` member names
(:mod:`ris_planner.io.crs`). The output is a plain JSON document fragment in WGS84 with a
``frame`` (the given origin, or the centre of the features' bounding box;
:mod:`ris_planner.io.feature_positions`), ready for :func:`ris_planner.io.frames.to_local`:

``{"frame": …, "environment": {"obstacles": [prism…]}, "ue_map": {"roads": […], "points": […],
"weights": […]}}``, plus the input's ``license`` / ``attribution``
(:mod:`ris_planner.io.import_options`). Copy ``ue_map``'s entries into ``tx_map``/``rx_map``.
Mounting points and lines are the ``sites`` format (:mod:`ris_planner.io.site_points`),
``.osm`` XML is read into a collection first (:mod:`ris_planner.io.osm_xml`).

Rules (each one applied is in the :class:`~ris_planner.io.import_options.ImportSummary`; a
feature is named by its index, its ``id`` / ``@id`` / ``osm_id``, its ``name`` and the lon/lat
of its first position):

* Obstacles of a kind (:func:`is_obstacle_feature`: properties naming a registered obstacle
  ``kind``, or ``role`` ``obstacle``, as the ``plan.geojson`` export writes them): read by that
  kind (:mod:`ris_planner.environment.kinds.geojson`), with ``name``, ``base_m`` (in the
  file's datum), ``height_m`` and ``material``; an exported plan re-imports its obstacles.
  Any other rule below applies to the other features.
* Buildings: (Multi)Polygons with a ``building`` property other than ``no`` (or any polygon
  without a density property when no feature of the file has ``building``: a plain building
  layer). Top = ``height`` (metres; ``"12 m"``, ``"40 ft"`` parsed), else ``building:levels``
  × ``metres_per_level`` (default :data:`~ris_planner.io.import_options.METRES_PER_LEVEL`),
  else ``default_height_m`` (:data:`~ris_planner.io.import_options.DEFAULT_BUILDING_HEIGHT_M`,
  listed in the summary); base = ``min_height``, else ``building:min_level`` × metres per
  level, else 0. A tag that is present but not a length (``"tall"``, ``""``, ``"-5"``,
  ``"nan"``, ``"10-12"``) is listed in ``tag_problems`` with what was used instead; a list of
  values (``"3;4"``, OSM's separator) uses the largest and says so. A MultiPolygon gives one
  prism per part.
* Courtyards (inner rings) stay open space: a polygon with holes is cut into simple polygons
  by one north–south line through each hole (:func:`simple_pieces`), and each piece grows by
  :data:`PIECE_OVERLAP_M` into its neighbours (never into a hole or outside), so a leg along
  a cut is inside a piece, not on two faces.
* Invalid outlines (self-intersections, unclosed or degenerate rings) follow
  ``options.invalid``: ``"repair"`` (default: ``shapely.make_valid``, keeping the polygonal
  parts; unclosed rings closed; listed in ``repaired`` with the areas before and after and a
  ``warning`` when the area changed by more than :data:`REPAIR_AREA_WARNING`), ``"skip"``
  (listed in ``skipped_invalid``) or ``"error"``. Density areas follow the same rule.
* Roads: (Multi)LineStrings with a ``highway`` class of :data:`HIGHWAY_WIDTH_M` (other
  classes are skipped and counted), or with a ``width``. Width = ``width`` property, else the
  class default of :data:`HIGHWAY_WIDTH_M`; sampled every ``road_step_m`` at ``ue_height_m``.
* UE areas: Polygons with a numeric ``density_key`` property (default ``density``, UEs per m²
  or any relative unit; a value that is not a number ≥ 0 is listed in ``tag_problems`` and
  the feature skipped): a grid of cell centres every ``area_step_m`` inside the polygon (holes
  excluded), each weighing density × cell area; a polygon smaller than a cell gets one point
  of weight density × area at its representative point.
* lat/lon swapped: the checks of :mod:`ris_planner.io.swap_check`, each an error whose message
  says "swapped?" and names the feature (or ``origin``).
* No buildings: an import that gives no obstacle (no building polygon, or none usable) gets
  :data:`NO_BUILDINGS_WARNING` in the summary's ``warnings``: a plan of it would treat every
  leg as clear.
"""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.errors import RisPlannerError
from ris_planner.environment.kinds import KINDS, UnknownObstacleKindError
from ris_planner.environment.kinds.base import GeometryError
from ris_planner.environment.kinds.geojson import obstacle_from_feature
from ris_planner.environment.kinds.prism import footprint_problem
from ris_planner.io import require
from ris_planner.io.crs import record_crs, wgs84_collection
from ris_planner.io.feature_positions import (
    collection_features,
    geojson_lines,
    geojson_position,
    import_frame,
    local_positions,
)
from ris_planner.io.frames import Frame
from ris_planner.io.import_options import (
    ImportOptions,
    ImportSummary,
    add_license,
    feature_entry,
    feature_errors,
    feature_ident,
    feature_label,
    lonlat_text,
    parse_tag_length,
)

FloatArray = NDArray[np.float64]

REPAIR_AREA_WARNING = 0.01
"""A repair that changes the area enclosed by an outline by more than this fraction (1 %) gets
a ``warning`` in its ``repaired`` entry (the area before is that of every region the outline's
lines enclose, the area after that of the polygonal parts kept)."""


MIN_PART_AREA_M2 = 0.01
"""Polygonal parts of a repair smaller than this (100 cm²: the slivers of a spike or a
doubled vertex) are dropped (counted in the ``repaired`` entry)."""


PIECE_OVERLAP_M = 0.05
"""How far each simple piece of a building with courtyards reaches into its neighbours [m]:
more than the 1 cm a visibility tolerance may ignore, so a leg that runs along a cut is deep
inside a piece (the pieces' union is the building, the courtyards stay open)."""


NO_BUILDINGS_WARNING = (
    "no buildings: the file gives no building (no polygon with a building tag, or none"
    " usable), so the site has no obstacles and a plan of it treats every leg as clear (line"
    " of sight through where the buildings stand); import the buildings with the roads (OSM:"
    " ways tagged building=*) or check the skipped and invalid features"
)
"""The import report's warning when an import gives no obstacle (a plan of such a document
with a ``frame`` repeats it: :func:`ris_planner.io.geoplan.site_warnings`)."""


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


class _OutlineError(RisPlannerError):
    """An outline that ``options.invalid`` decides about (unusable as given)."""


def _ring(coords: Any, label: str, notes: list[str]) -> list[list[float]]:
    """A GeoJSON linear ring → its open vertex list (consecutive repeats removed). An unclosed
    ring is closed with a note in ``notes``; fewer than 3 distinct positions is an
    :class:`_OutlineError`."""
    if not isinstance(coords, list) or len(coords) == 0:
        raise _OutlineError(f"{label}: empty ring")
    pts = [geojson_position(p, label)[:2] for p in coords]
    if pts[0] != pts[-1]:
        notes.append(f"ring not closed (first position {pts[0]} ≠ last {pts[-1]}; RFC 7946)")
        pts = [*pts, pts[0]]
    open_pts = [p for i, p in enumerate(pts[:-1]) if i == 0 or p != pts[i - 1]]
    if len(open_pts) < 3:
        raise _OutlineError(f"{label}: a ring needs at least 3 distinct positions")
    return open_pts


def _polygons(geom: dict[str, Any], label: str) -> list[Any]:
    """The raw polygons of a Polygon / MultiPolygon (lists of rings), or an error."""
    coords = geom.get("coordinates")
    if not isinstance(coords, list) or not coords:
        raise _OutlineError(f"{label}: empty {geom.get('type')} geometry")
    polys = coords if geom["type"] == "MultiPolygon" else [coords]
    return list(polys)


_REASON_AT = re.compile(r"\[(-?[\d.e+-]+) (-?[\d.e+-]+)\]")


def _reason_lonlat(reason: str, frame: Frame) -> str:
    """shapely's validity reason with its local point ``[x y]`` given as lon/lat."""
    m = _REASON_AT.search(reason)
    if m is None:
        return reason
    try:
        ll = frame.to_geographic(np.array([[float(m.group(1)), float(m.group(2))]]))[0]
    except ValueError:
        return reason
    return reason[: m.start()] + f" at {lonlat_text(ll.tolist())}" + reason[m.end() :]


def _is_building(props: dict[str, Any], layer_has_building_tag: bool) -> bool:
    b = props.get("building")
    if b is not None:
        return str(b).lower() != "no"
    return not layer_has_building_tag or "height" in props or "building:levels" in props


def _heights(
    props: dict[str, Any],
    opts: ImportOptions,
    label: str,
    summary: ImportSummary,
    entry: dict[str, Any],
) -> tuple[float, float]:
    """(base_m, height_m) of a building (module docstring rules); every tag present but not
    usable is listed in ``summary.tag_problems`` (``entry`` names the feature) with what was
    used instead."""
    problems: list[tuple[str, Any, str, str]] = []

    def tag(key: str, positive: bool) -> float | None:
        if key not in props or props[key] is None:
            return None
        v, note = parse_tag_length(props[key], positive)
        if note is not None:
            used = f"{v:g} (the largest value)" if v is not None else ""
            problems.append((key, props[key], note, used))
        return v

    top = tag("height", True)
    used_top = "height"
    if top is None:
        levels = tag("building:levels", True)
        if levels is not None:
            top = levels * opts.metres_per_level
            used_top = f"building:levels {levels:g} × {opts.metres_per_level:g} m = {top:g} m"
            summary.heights_from_levels += 1
    if top is None:
        top = opts.default_height_m
        used_top = f"the default height {top:g} m"
        summary.default_height.append(label)
    base = tag("min_height", False)
    used_base = "min_height"
    if base is None:
        min_level = tag("building:min_level", False)
        if min_level is not None:
            base = min_level * opts.metres_per_level
            used_base = (
                f"building:min_level {min_level:g} × {opts.metres_per_level:g} m = {base:g} m"
            )
        else:
            base = 0.0
            used_base = "base 0 m"
    for key, value, note, used in problems:
        if not used:
            used = used_top if key in ("height", "building:levels") else used_base
        summary.tag_problems.append(
            {**entry, "tag": key, "value": value, "problem": note, "used": used}
        )
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


def _polygonal_parts(geom: Any) -> list[Any]:
    """The Polygons of any geometry (a GeometryCollection's lines and points dropped)."""
    shapely = require("shapely")
    return [
        g
        for g in shapely.get_parts(geom)
        if g.geom_type == "Polygon" or g.geom_type == "MultiPolygon"
        for g in ([g] if g.geom_type == "Polygon" else shapely.get_parts(g))
    ]


def _enclosed_area(poly: Any) -> float:
    """Area of every region the outline's lines enclose (shell regions less hole regions)."""
    shapely = require("shapely")

    def faces(ring: Any) -> Any:
        return shapely.union_all(
            shapely.get_parts(shapely.polygonize(shapely.get_parts(shapely.node(ring))))
        )

    shell = faces(poly.exterior)
    holes = [faces(r) for r in poly.interiors]
    return float(shapely.difference(shell, shapely.union_all(holes)).area if holes else shell.area)


def simple_pieces(poly: Any, overlap_m: float = PIECE_OVERLAP_M) -> list[Any]:
    """Simple polygons (no holes) whose union is ``poly`` (a valid shapely Polygon, local
    metres): ``[poly]`` without holes; else ``poly`` is cut by one north–south line through each
    hole, at the middle of the widest gap between the x of its vertices inside the hole's
    x-range (never through a vertex), and each piece grows by ``overlap_m`` into its
    neighbours (mitred buffer ∩ ``poly``), so pieces overlap along every cut and no leg can
    pass between two of them along a shared edge."""
    shapely = require("shapely")
    from shapely.ops import split

    if not poly.interiors:
        return [poly]
    xs = np.unique(
        np.concatenate([np.asarray(r.coords)[:, 0] for r in [poly.exterior, *poly.interiors]])
    )
    _, y0, _, y1 = poly.bounds
    cuts = []
    for hole in poly.interiors:
        hx = np.asarray(hole.coords)[:, 0]
        lo, hi = float(hx.min()), float(hx.max())
        cand = np.concatenate([[lo], xs[(xs > lo) & (xs < hi)], [hi]])
        k = int(np.argmax(np.diff(cand)))
        x = float((cand[k] + cand[k + 1]) / 2)
        cuts.append([(x, y0 - 1.0), (x, y1 + 1.0)])
    pieces = [p for p in split(poly, shapely.MultiLineString(cuts)).geoms if p.area > 0]
    out = []
    for piece in pieces:
        grown = shapely.intersection(
            piece.buffer(overlap_m, join_style="mitre", mitre_limit=2.0), poly
        )
        inner = piece.representative_point()
        best = [g for g in _polygonal_parts(grown) if g.contains(inner) or g.covers(inner)]
        g = best[0] if best else piece
        ok = g.is_valid and not g.interiors and g.area >= piece.area * (1 - 1e-9)
        out.append(shapely.normalize(g) if ok else piece)
    return out


def _footprints(poly: Any, frame: Frame, where: str, shapely: Any) -> list[list[list[float]]]:
    """Lon/lat footprints (open rings, full float digits: the round trip to metres is exact to
    nanometres) of the simple pieces of a valid local polygon, each checked as a prism
    footprint after the round trip."""
    out = []
    for piece in simple_pieces(poly):
        ring = np.asarray(piece.exterior.coords)[:-1]
        ll = frame.to_geographic(ring)
        keep = np.any(ll != np.roll(ll, 1, axis=0), axis=1)
        ll = ll[keep]
        problem = footprint_problem(frame.from_source(ll)) if len(ll) >= 3 else "degenerate"
        if problem is not None:
            if piece.area < MIN_PART_AREA_M2:
                continue
            raise RisPlannerError(f"{where}: a piece of the outline is unusable ({problem})")
        out.append(ll.tolist())
    return out


def _clean(
    raw: Any,
    frame: Frame,
    where: str,
    opts: ImportOptions,
    summary: ImportSummary,
    entry: dict[str, Any],
) -> tuple[list[Any], bool]:
    """(valid local Polygons (holes kept) of one raw GeoJSON polygon, whether it is the
    polygon as given), following ``opts.invalid``: no polygons when skipped (listed in
    ``summary``)."""
    shapely = require("shapely")
    notes: list[str] = []
    try:
        if not isinstance(raw, list) or not raw:
            raise _OutlineError(f"{where}: empty polygon")
        rings = [
            _ring(r, f"{where} ring {j}" if len(raw) > 1 else where, notes)
            for j, r in enumerate(raw)
        ]
    except _OutlineError as exc:
        if opts.invalid == "error":
            raise
        summary.skipped_invalid.append(
            {**entry, "part": where, "reason": str(exc).split(": ", 1)[-1]}
        )
        return [], False
    local = [local_positions(frame, r, where) for r in rings]
    poly = shapely.Polygon(local[0], local[1:])
    if poly.is_valid and not notes:
        return [poly], True
    reasons = [*notes] + (
        [] if poly.is_valid else [_reason_lonlat(shapely.is_valid_reason(poly), frame)]
    )
    reason = "; ".join(reasons)
    if opts.invalid == "error":
        raise RisPlannerError(
            f"{where}: invalid outline ({reason}); import with invalid='repair' or 'skip'"
        )
    if opts.invalid == "skip":
        summary.skipped_invalid.append({**entry, "part": where, "reason": reason})
        return [], False
    before = _enclosed_area(poly)
    parts = _polygonal_parts(shapely.make_valid(poly)) if not poly.is_valid else [poly]
    kept = [p for p in parts if p.area >= MIN_PART_AREA_M2]
    after = float(sum(p.area for p in kept))
    rec: dict[str, Any] = {
        **entry,
        "part": where,
        "reason": reason,
        "parts": len(kept),
        "area_before_m2": round(before, 2),
        "area_after_m2": round(after, 2),
    }
    if len(parts) > len(kept):
        rec["slivers_dropped"] = len(parts) - len(kept)
    if not kept:
        summary.skipped_invalid.append({**rec, "reason": f"{reason}; no area left after repair"})
        return [], False
    change = abs(after - before) / before if before > 0 else math.inf
    if change > REPAIR_AREA_WARNING:
        rec["warning"] = (
            f"the repair changed the enclosed area by {change:.1%} (more than"
            f" {REPAIR_AREA_WARNING:.0%}): check the outline"
        )
    summary.repaired.append(rec)
    return kept, False


def is_obstacle_feature(props: dict[str, Any]) -> bool:
    """Whether a feature is an obstacle of a given kind: its properties name a registered
    obstacle ``kind``, or its ``role`` is ``obstacle`` (an exported ``plan.geojson``'s)."""
    kind = props.get("kind")
    return props.get("role") == "obstacle" or (isinstance(kind, str) and kind in KINDS)


def _obstacle(geom: dict[str, Any], props: dict[str, Any], label: str) -> dict[str, Any]:
    """The obstacle of an obstacle feature, read by its kind (its coordinates as given)."""
    try:
        return obstacle_from_feature(geom, props)
    except (UnknownObstacleKindError, GeometryError) as exc:
        raise RisPlannerError(f"{label}: {exc}") from None


def import_features(
    collection: dict[str, Any],
    origin: tuple[float, ...] | None = None,
    options: ImportOptions | None = None,
) -> tuple[dict[str, Any], ImportSummary]:
    """A GeoJSON FeatureCollection of buildings, roads and density areas → (document fragment
    with ``frame``, ``environment``, ``ue_map`` and the licence, summary). See the module
    docstring."""
    shapely = require("shapely")
    opts = options or ImportOptions()
    collection, crs = wgs84_collection(collection)
    feats = collection_features(collection)
    frame = import_frame(feats, origin, opts)
    h0 = frame.origin[2]
    summary = ImportSummary()
    record_crs(summary, crs)
    obstacles: list[dict[str, Any]] = []
    roads: list[dict[str, Any]] = []
    points: list[list[float]] = []
    weights: list[float] = []
    has_building_tag = any(
        isinstance(f, dict) and "building" in (f.get("properties") or {}) for f in feats
    )
    for i, feat in enumerate(feats):
        with feature_errors(i):
            label = feature_label(i, feat)
            if not isinstance(feat, dict) or feat.get("type") != "Feature":
                raise RisPlannerError(f"{label}: not a GeoJSON Feature")
            geom = feat.get("geometry")
            props = feat.get("properties") or {}
            if not isinstance(geom, dict):
                raise RisPlannerError(f"{label}: no geometry (empty)")
            entry = feature_entry(i, feat)
            kind = geom.get("type")
            fid = feature_ident(feat)[0]
            name = props.get("name") or (str(fid) if fid is not None else None)
            if is_obstacle_feature(props):
                obstacles.append(_obstacle(geom, props, label))
                summary.obstacle_features += 1
                continue
            if kind in ("Polygon", "MultiPolygon"):
                try:
                    raw_polys = _polygons(geom, label)
                except _OutlineError as exc:
                    if opts.invalid == "error":
                        raise
                    summary.skipped_invalid.append({**entry, "reason": str(exc).split(": ", 1)[-1]})
                    continue
                density = None
                if props.get(opts.density_key) is not None:
                    density, note = parse_tag_length(props[opts.density_key])
                    if note is not None:
                        summary.tag_problems.append(
                            {
                                **entry,
                                "tag": opts.density_key,
                                "value": props[opts.density_key],
                                "problem": note,
                                "used": f"{density:g} (the largest value)"
                                if density is not None
                                else "feature skipped",
                            }
                        )
                    if density is None:
                        summary.skipped += 1
                        continue
                wheres = [
                    f"{label} polygon {k}" if len(raw_polys) > 1 else label
                    for k in range(len(raw_polys))
                ]
                if density is not None:
                    for raw, where in zip(raw_polys, wheres, strict=True):
                        for poly in _clean(raw, frame, where, opts, summary, entry)[0]:
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
                base, height = _heights(props, opts, label, summary, entry)
                footprints: list[list[list[float]]] = []
                for raw, where in zip(raw_polys, wheres, strict=True):
                    polys, as_given = _clean(raw, frame, where, opts, summary, entry)
                    for poly in polys:
                        summary.courtyards += len(poly.interiors)
                        if as_given and not poly.interiors:
                            footprints.append(_ring(raw[0], where, []))
                        else:
                            footprints += _footprints(poly, frame, where, shapely)
                if not footprints:
                    continue
                summary.buildings += 1
                for k, fp in enumerate(footprints):
                    prism: dict[str, Any] = {
                        "kind": "prism",
                        "footprint": fp,
                        "base_m": base + h0,
                        "height_m": height,
                    }
                    if name is not None:
                        prism["name"] = f"{name}#{k}" if len(footprints) > 1 else str(name)
                    obstacles.append(prism)
                    summary.prisms += 1
            elif kind in ("LineString", "MultiLineString"):
                highway = props.get("highway")
                width = None
                if props.get("width") is not None:
                    width, note = parse_tag_length(props["width"], positive=True)
                    if note is not None:
                        fallback = HIGHWAY_WIDTH_M.get(str(highway))
                        summary.tag_problems.append(
                            {
                                **entry,
                                "tag": "width",
                                "value": props["width"],
                                "problem": note,
                                "used": note
                                if width is not None
                                else (
                                    f"the {highway} default {fallback:g} m"
                                    if fallback is not None
                                    else "not a road (skipped)"
                                ),
                            }
                        )
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
                for line in geojson_lines(geom, label):
                    local_positions(frame, line, label)
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
    if summary.courtyards:
        summary.notes.append(
            f"{summary.courtyards} inner ring(s) (courtyards) kept open: their buildings cut"
            " into simple prisms"
        )
    fragment: dict[str, Any] = {"frame": frame.to_json()}
    add_license(fragment, collection, summary)
    if obstacles:
        fragment["environment"] = {"obstacles": obstacles}
    else:
        summary.warnings.append(NO_BUILDINGS_WARNING)
    ue_map: dict[str, Any] = {}
    if roads:
        ue_map["roads"] = roads
    if points:
        ue_map["points"] = points
        ue_map["weights"] = weights
    if ue_map:
        fragment["ue_map"] = ue_map
    return fragment, summary
