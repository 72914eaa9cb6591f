"""GeoJSON / OSM import: buildings → prisms, roads → UE roads, density areas → weighted UE
points, mounting points and lines → candidate sites (guide: ``docs/guides/import.md``).

Input coordinates are WGS84 [lon, lat] (RFC 7946), or those of the CRS the collection names in
a ``crs`` member (the 2008 GeoJSON specification's ``{"type": "name", "properties": {"name":
"urn:ogc:def:crs:EPSG::3067"}}``, or ``"EPSG:3067"``), which are converted to WGS84 with pyproj
first and the conversion listed in the summary (:func:`wgs84_collection`; a CRS that PROJ does
not know is an error on ``crs`` saying how to convert the file). The output is a plain JSON
document fragment in WGS84 with a ``frame`` (the given origin, or the centre of the features'
bounding box), ready for :func:`ris_planner.io.frames.to_local`:

``{"frame": …, "environment": {"obstacles": [prism…]}, "ue_map": {"roads": […], "points": […],
"weights": […]}}`` (:func:`import_features`) and ``{"frame": …, "candidates": […], "walls":
[…]}`` (:func:`import_sites`), plus the input's ``license`` / ``attribution`` (below). Copy
``ue_map``'s entries into ``tx_map``/``rx_map``.

Rules (each one applied is in the :class:`ImportSummary`; a feature is named by its index,
its ``id`` / ``@id`` / ``osm_id``, its ``name`` and the lon/lat of its first position):

* Buildings: (Multi)Polygons with a ``building`` property other than ``no`` (or any polygon
  without a density property when no feature of the file has ``building``: a plain building
  layer). Top = ``height`` (metres; ``"12 m"``, ``"40 ft"`` parsed), else ``building:levels``
  × ``metres_per_level`` (default :data:`METRES_PER_LEVEL`), else ``default_height_m``
  (:data:`DEFAULT_BUILDING_HEIGHT_M`, listed in the summary); base = ``min_height``, else
  ``building:min_level`` × metres per level, else 0. A tag that is present but not a length
  (``"tall"``, ``""``, ``"-5"``, ``"nan"``, ``"10-12"``) is listed in ``tag_problems`` with
  what was used instead; a list of values (``"3;4"``, OSM's separator) uses the largest and
  says so. A MultiPolygon gives one prism per part.
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
* lat/lon swapped (:func:`check_positions`): a position whose latitude is beyond ±90° while
  its longitude is not; a feature far (beyond
  :data:`~ris_planner.io.frames.MAX_FRAME_RADIUS_M`) from the origin – or, without one, from
  the median of the features – that would lie near it read as [lat, lon]; an ``origin`` that
  lies near the features only read as [lat, lon]; and a file whose building corners are
  square only when read as [lat, lon] (:data:`SWAP_MIN_CORNERS`; ``options.swap_check``).
  Each is an error whose message says "swapped?" and names the feature (or ``origin``).
* No buildings: an import that gives no obstacle (no building polygon, or none usable) gets
  :data:`NO_BUILDINGS_WARNING` in the summary's ``warnings``: a plan of it would treat every
  leg as clear.
* Licence: the collection's top-level ``license`` and ``attribution`` are copied into the
  fragment; OSM data (an ``.osm`` file, or features with OSM ids such as ``way/42`` and no
  licence of their own) gets :data:`OSM_LICENSE`. The exports carry it
  (:mod:`ris_planner.io.export`).

``.osm`` XML (JOSM, Overpass, openstreetmap.org exports) is read with the standard library's
:mod:`xml.etree.ElementTree` (:func:`osm_xml_features`): the format is flat (nodes, ways with
node references, tags), so no binary dependency is needed; for ``.pbf`` files convert with
``osmium export`` or read them with the ``osmium`` package as ``examples/helsinki/extract.py``
does.
"""

from __future__ import annotations

import itertools
import json
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

from ris_planner.core.errors import DocumentFieldError, RisPlannerError
from ris_planner.environment.kinds.prism import footprint_problem
from ris_planner.io import MissingExtraError, require
from ris_planner.io.frames import (
    MAX_FRAME_RADIUS_M,
    Frame,
    great_circle_m,
    is_wgs84_lonlat,
    lonlat_of,
    resolve_crs,
)

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

INVALID_POLICIES = ("repair", "skip", "error")
"""What :func:`import_features` does with an invalid outline (``ImportOptions.invalid``)."""

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

SWAP_MIN_CORNERS = 12
"""The file-wide lat/lon swap test needs at least this many building corners."""

SWAP_RIGHT_ANGLE_DEG = 3.0
"""A building corner within this of 90° is square (the file-wide swap test)."""

OSM_LICENSE = "© OpenStreetMap contributors, ODbL 1.0"
"""Licence of OpenStreetMap data (https://www.openstreetmap.org/copyright)."""

NO_BUILDINGS_WARNING = (
    "no buildings: the file gives no building (no polygon with a building tag, or none"
    " usable), so the site has no obstacles and a plan of it treats every leg as clear (line"
    " of sight through where the buildings stand); import the buildings with the roads (OSM:"
    " ways tagged building=*) or check the skipped and invalid features"
)
"""The import report's warning when an import gives no obstacle (a plan of such a document
with a ``frame`` repeats it: :func:`ris_planner.io.geoplan.site_warnings`)."""

CRS_CONVERT_HINT = (
    "GeoJSON is WGS84 [lon, lat] (RFC 7946): convert the file, e.g. with"
    " ogr2ogr -f GeoJSON -t_srs EPSG:4326 out.geojson in.geojson, or name a CRS that PROJ"
    ' knows in the crs member ({"type": "name", "properties": {"name": "EPSG:3067"}})'
)
"""How to get a file the importer reads, in the errors about a ``crs`` member."""

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

_OSM_ID = re.compile(r"^(node|way|relation)/\d+$")


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
    invalid: str = "repair"
    """Invalid outlines: ``repair`` | ``skip`` | ``error`` (:data:`INVALID_POLICIES`)."""
    swap_check: bool = True
    """Run the file-wide lat/lon swap test (square corners; module docstring)."""

    def __post_init__(self) -> None:
        if self.invalid not in INVALID_POLICIES:
            raise DocumentFieldError(
                "invalid", f"choose one of {', '.join(INVALID_POLICIES)}, got {self.invalid!r}"
            )


@dataclass
class ImportSummary:
    """What an import did (printed by ``ris-planner import`` on stderr). Entries of
    ``repaired``, ``skipped_invalid`` and ``tag_problems`` name the feature (``feature``
    index, ``id``, ``name``, ``lonlat`` of its first position)."""

    buildings: int = 0
    prisms: int = 0
    heights_from_levels: int = 0
    default_height: list[str] = field(default_factory=list)
    courtyards: int = 0
    """Inner rings kept open (their buildings cut into simple pieces)."""
    roads: int = 0
    roads_skipped: dict[str, int] = field(default_factory=dict)
    areas: int = 0
    area_points: int = 0
    candidates: int = 0
    walls: int = 0
    skipped: int = 0
    repaired: list[dict[str, Any]] = field(default_factory=list)
    skipped_invalid: list[dict[str, Any]] = field(default_factory=list)
    tag_problems: list[dict[str, Any]] = field(default_factory=list)
    license: str | None = None
    crs: dict[str, Any] | None = None
    """The collection's ``crs`` member and what was done with it (:func:`wgs84_collection`)."""
    warnings: list[str] = field(default_factory=list)
    """What makes the import a poor model of the site (:data:`NO_BUILDINGS_WARNING`)."""
    notes: list[str] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {k: v for k, v in self.__dict__.items() if v not in (0, [], {}, None)}


class FeatureError(DocumentFieldError):
    """An error in one feature of a collection: the message names the feature (index, id,
    name, lon/lat; :func:`feature_label`), ``field`` is its path in the collection
    (``features.3``), which the service's 422 lists."""

    def __init__(self, index: int, message: str) -> None:
        super().__init__(f"features.{index}", message)
        self.index = index
        self.args = (message,)  # the message already names the feature

    def __reduce__(self) -> tuple[type, tuple[object, ...]]:
        return type(self), (self.index, self.reason)


class _OutlineError(RisPlannerError):
    """An outline that ``options.invalid`` decides about (unusable as given)."""


@contextmanager
def _feature_errors(index: int) -> Iterator[None]:
    """Re-raise an error about feature ``index`` as a :class:`FeatureError`."""
    try:
        yield
    except DocumentFieldError:
        raise
    except RisPlannerError as exc:
        raise FeatureError(index, str(exc)) from None


def _first_position(coords: Any) -> list[float] | None:
    """The first [x, y] number pair of nested GeoJSON coordinates, or None."""
    while isinstance(coords, list) and coords:
        if all(isinstance(v, int | float) and not isinstance(v, bool) for v in coords[:2]):
            return [float(coords[0]), float(coords[1])] if len(coords) >= 2 else None
        coords = coords[0]
    return None


def _anchor(feature: Any) -> list[float] | None:
    geom = feature.get("geometry") if isinstance(feature, dict) else None
    return _first_position(geom.get("coordinates")) if isinstance(geom, dict) else None


def _ident(feature: Any) -> tuple[Any, Any]:
    """(id, name) of a feature as the user gave them (None when absent)."""
    props = (feature.get("properties") or {}) if isinstance(feature, dict) else {}
    props = props if isinstance(props, dict) else {}
    fid = feature.get("id") if isinstance(feature, dict) else None
    if fid is None:
        fid = props.get("@id", props.get("osm_id", props.get("id")))
    return fid, props.get("name") or None


def _fmt_lonlat(p: list[float]) -> str:
    return f"[{p[0]:.6f}, {p[1]:.6f}]"


def feature_label(index: int, feature: Any) -> str:
    """'feature 3 (id way/42, name 'Kirjasto') at [24.949120, 60.165510]' – how errors name a
    feature (the position is its first one, as given)."""
    fid, name = _ident(feature)
    parts = [f"id {fid}"] if fid is not None else []
    if name:
        parts.append(f"name {name!r}")
    at = _anchor(feature)
    return (
        f"feature {index}"
        + (f" ({', '.join(parts)})" if parts else "")
        + (f" at {_fmt_lonlat(at)}" if at is not None else "")
    )


def feature_entry(index: int, feature: Any, **extra: Any) -> dict[str, Any]:
    """A summary entry naming a feature: index, id, name, lon/lat of its first position."""
    fid, name = _ident(feature)
    at = _anchor(feature)
    entry: dict[str, Any] = {"feature": index}
    if fid is not None:
        entry["id"] = fid if isinstance(fid, int | str) else str(fid)
    if name:
        entry["name"] = str(name)
    if at is not None:
        entry["lonlat"] = [round(at[0], 7), round(at[1], 7)]
    return {**entry, **extra}


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


def parse_tag_length(value: Any, positive: bool = False) -> tuple[float | None, str | None]:
    """(metres, note) of an OSM length tag: a number with an optional unit
    (:func:`parse_length`), ≥ 0 (> 0 when ``positive``); a ``;``-separated list of such
    values gives the largest with a note; anything else gives (None, why)."""
    v = parse_length(value)
    ok = v is not None and (v > 0 if positive else v >= 0)
    if ok:
        return v, None
    if isinstance(value, str) and ";" in value:
        vals = [parse_length(s) for s in value.split(";")]
        good = [x for x in vals if x is not None and (x > 0 if positive else x >= 0)]
        if good and len(good) == len(vals):
            return max(good), f"several values {value!r}: the largest, {max(good):g}, used"
    if v is not None:
        return None, f"{value!r} is not {'> 0' if positive else '≥ 0'}"
    return None, f"{value!r} is not a number with an optional unit (m, ft)"


def _lonlat(pos: Any, label: str) -> list[float]:
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


def _ring(coords: Any, label: str, notes: list[str]) -> list[list[float]]:
    """A GeoJSON linear ring → its open vertex list (consecutive repeats removed). An unclosed
    ring is closed with a note in ``notes``; fewer than 3 distinct positions is an
    :class:`_OutlineError`."""
    if not isinstance(coords, list) or len(coords) == 0:
        raise _OutlineError(f"{label}: empty ring")
    pts = [_lonlat(p, label)[:2] for p in coords]
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
            f"{label}: position {_fmt_lonlat(pts[k])} lies {d[k] / 1000:.0f} km from the origin"
            f" {_fmt_lonlat(list(frame.origin))} (limit {MAX_FRAME_RADIUS_M / 1000:g} km): {hint}"
        )
    assert xy is not None
    return xy


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
    return reason[: m.start()] + f" at {_fmt_lonlat(ll.tolist())}" + reason[m.end() :]


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


def _crs_error(member: Any, why: str) -> DocumentFieldError:
    """The error on a collection's ``crs`` member: that it was seen, its value, why it cannot be
    used and how to convert the file (:data:`CRS_CONVERT_HINT`)."""
    try:
        given = json.dumps(member, ensure_ascii=False)
    except (TypeError, ValueError):
        given = repr(member)
    if len(given) > 200:
        given = given[:200] + "…"
    return DocumentFieldError(
        "crs", f"the collection has a crs member, {given}: {why}; {CRS_CONVERT_HINT}"
    )


def crs_name(member: Any) -> str:
    """The CRS name of a GeoJSON collection's ``crs`` member (the 2008 GeoJSON specification's
    named CRS ``{"type": "name", "properties": {"name": "urn:ogc:def:crs:EPSG::3067"}}``, the
    older ``{"type": "EPSG", "properties": {"code": 3067}}``, or a bare name such as
    ``"EPSG:3067"``); a :class:`DocumentFieldError` on ``crs`` for anything else (a linked
    CRS, no name)."""
    if isinstance(member, str) and member.strip():
        return member.strip()
    if isinstance(member, dict):
        props = member.get("properties")
        props = props if isinstance(props, dict) else {}
        kind = str(member.get("type", "")).lower()
        name = props.get("name")
        if kind == "name" and isinstance(name, str) and name.strip():
            return name.strip()
        code = props.get("code")
        if kind == "epsg" and isinstance(code, int | str) and not isinstance(code, bool):
            return f"EPSG:{code}"
        if kind == "link":
            raise _crs_error(member, "a linked CRS (a file or URL) is not read")
    raise _crs_error(
        member,
        'expected a named CRS, {"type": "name", "properties": {"name": "EPSG:…"}}',
    )


def _is_position(c: Any) -> bool:
    return (
        isinstance(c, list)
        and len(c) >= 2
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in c)
        and all(math.isfinite(v) for v in c[:2])
    )


def _positions(coords: Any, out: list[list[float]]) -> None:
    """Append every position of nested GeoJSON coordinates to ``out`` (anything else is left
    for the importer to name)."""
    if _is_position(coords):
        out.append(coords)
    elif isinstance(coords, list):
        for c in coords:
            _positions(c, out)


def _replaced(coords: Any, new: Iterator[list[float]]) -> Any:
    """The coordinates with each position (:func:`_is_position`) the next of ``new``."""
    if _is_position(coords):
        return next(new)
    if isinstance(coords, list):
        return [_replaced(c, new) for c in coords]
    return coords


def _geometry_positions(geom: Any, out: list[list[float]]) -> None:
    if not isinstance(geom, dict):
        return
    if geom.get("type") == "GeometryCollection":
        for g in geom.get("geometries") or []:
            _geometry_positions(g, out)
    else:
        _positions(geom.get("coordinates"), out)


def _geometry_replaced(geom: Any, new: Iterator[list[float]]) -> Any:
    if not isinstance(geom, dict):
        return geom
    out = {k: v for k, v in geom.items() if k != "bbox"}
    if geom.get("type") == "GeometryCollection":
        parts = geom.get("geometries")
        if isinstance(parts, list):
            out["geometries"] = [_geometry_replaced(g, new) for g in parts]
    elif "coordinates" in geom:
        out["coordinates"] = _replaced(geom["coordinates"], new)
    return out


def wgs84_collection(collection: Any) -> tuple[Any, dict[str, Any] | None]:
    """(the collection in WGS84 [lon, lat], what its ``crs`` member made of it): a collection
    without a ``crs`` member (or ``"crs": null``) as it is; with one (:func:`crs_name`), a copy
    without it whose positions are converted from that CRS with pyproj (x first: easting,
    northing of a projected CRS; heights kept) – a WGS84 one (``OGC:CRS84``, ``EPSG:4326``) is
    taken as [lon, lat] unchanged – and ``{"given", "crs", "name", "converted_to",
    "positions"}`` (``crs``: the name read from the member, ``name``: PROJ's name of it).
    Errors name the ``crs`` member (unknown or not horizontal: its value and how to convert
    the file) or the feature with a position the CRS cannot convert."""
    if not isinstance(collection, dict) or "crs" not in collection:
        return collection, None
    member = collection["crs"]
    out = {k: v for k, v in collection.items() if k not in ("crs", "bbox")}
    if member is None:
        return out, None
    name = crs_name(member)
    try:
        crs = resolve_crs(name)
    except MissingExtraError:
        raise MissingExtraError(
            f"the collection's crs member names {name!r}: converting its coordinates needs"
            " pyproj, which is not installed (pip install 'ris_planner[gis]')"
        ) from None
    except ValueError as exc:
        raise _crs_error(member, f"PROJ knows no CRS {name!r} ({exc})") from None
    if not (crs.is_projected or crs.is_geographic):
        raise _crs_error(
            member, f"{name!r} ({crs.name}) is not a horizontal CRS (projected or geographic)"
        )
    info: dict[str, Any] = {"given": member, "crs": name, "name": crs.name}
    feats = collection.get("features")
    if is_wgs84_lonlat(crs) or not isinstance(feats, list):
        return out, {**info, "converted_to": None, "positions": 0}
    per_feature: list[list[list[float]]] = []
    for f in feats:
        pos: list[list[float]] = []
        _geometry_positions(f.get("geometry") if isinstance(f, dict) else None, pos)
        per_feature.append(pos)
    flat = [p for pos in per_feature for p in pos]
    xy = np.array([p[:2] for p in flat], dtype=float).reshape(-1, 2)
    ll = lonlat_of(xy, crs)
    bad = ~np.all(np.isfinite(ll), axis=1)
    if np.any(bad):
        k = int(np.argmax(bad))
        i = int(np.searchsorted(np.cumsum([len(p) for p in per_feature]), k, side="right"))
        raise FeatureError(
            i,
            f"{feature_label(i, feats[i])}: position {flat[k][:2]} is not a position of"
            f" {name!r} ({crs.name}), the collection's crs: a stray position or the wrong crs?",
        )
    converted = iter(
        [
            [float(a), float(b), *(float(v) for v in p[2:3])]
            for (a, b), p in zip(ll, flat, strict=True)
        ]
    )
    features = []
    for f in feats:
        if isinstance(f, dict) and isinstance(f.get("geometry"), dict):
            f = {k: v for k, v in f.items() if k != "bbox"}
            f["geometry"] = _geometry_replaced(f["geometry"], converted)
        features.append(f)
    out["features"] = features
    return out, {**info, "converted_to": "WGS84 [lon, lat] (OGC:CRS84)", "positions": len(flat)}


def crs_note(info: dict[str, Any]) -> str:
    """The summary note of :func:`wgs84_collection`'s answer about a ``crs`` member."""
    if info["converted_to"] is None:
        return f"crs member {info['crs']} ({info['name']}): WGS84 [lon, lat], read as it is"
    return (
        f"coordinates converted from the crs member's {info['crs']} ({info['name']}) to"
        f" WGS84 [lon, lat] with pyproj ({info['positions']} positions; heights kept)"
    )


def _record_crs(summary: ImportSummary, info: dict[str, Any] | None) -> None:
    """The summary's ``crs`` entry and note of :func:`wgs84_collection`'s conversion."""
    if info is not None:
        summary.crs = info
        summary.notes.append(crs_note(info))


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
        a = _anchor(f)
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
                where = _fmt_lonlat(list(np.median(pts, axis=0)))
                swapped_o = great_circle_m(pts, (centre[1], centre[0], 0.0))
                near = int(np.argmin(d))
                example = feature_label(anchors[near][0], feats[anchors[near][0]])
                if abs(centre[0]) <= 90 and np.median(swapped_o) <= MAX_FRAME_RADIUS_M:
                    raise DocumentFieldError(
                        "origin",
                        f"{_fmt_lonlat(list(centre))} lies {np.min(d) / 1000:.0f} km from the"
                        f" nearest feature, {example} (the features lie around {where}); read"
                        " as [lat, lon] the origin lies among them: lat/lon swapped? (in the"
                        " origin – give LON,LAT – or in every feature)",
                    )
                swapped_f = great_circle_m(pts[:, ::-1], centre)
                if np.median(swapped_f) > MAX_FRAME_RADIUS_M or np.any(np.abs(pts[:, 0]) > 90):
                    raise DocumentFieldError(
                        "origin",
                        f"{_fmt_lonlat(list(centre))} lies {np.min(d) / 1000:.0f} km from the"
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
                f" {_fmt_lonlat(list(centre))} (limit {MAX_FRAME_RADIUS_M / 1000:g} km): {hint}",
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


def _frame_of(
    features: list[Any], origin: tuple[float, ...] | None, options: ImportOptions
) -> Frame:
    check_positions(features, origin, options)
    if origin is None:
        return Frame(default_origin(features))
    o = tuple(float(v) for v in origin)
    return Frame((o[0], o[1], o[2] if len(o) > 2 else 0.0))


def license_of(collection: Any) -> tuple[str | None, str | None, str | None]:
    """(license, attribution, note) of a FeatureCollection: its top-level ``license`` and
    ``attribution``; without either, :data:`OSM_LICENSE` when its features carry OSM ids
    (``way/42``, ``@id``, ``osm_id``), with a note saying so."""
    if not isinstance(collection, dict):
        return None, None, None
    lic, attr = collection.get("license"), collection.get("attribution")
    lic = str(lic) if lic not in (None, "") else None
    attr = str(attr) if attr not in (None, "") else None
    if lic is None and attr is None:
        feats = collection.get("features") or []
        osm = any(
            isinstance(f, dict)
            and (_OSM_ID.match(str(_ident(f)[0] or "")) or "osm_id" in (f.get("properties") or {}))
            for f in feats[:1000]
        )
        if osm:
            return OSM_LICENSE, None, f"license: {OSM_LICENSE!r} (features carry OpenStreetMap ids)"
    return lic, attr, None


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
    local = [_local(frame, r, where) for r in rings]
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
    feats = _features(collection)
    frame = _frame_of(feats, origin, opts)
    h0 = frame.origin[2]
    summary = ImportSummary()
    _record_crs(summary, crs)
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
            entry = feature_entry(i, feat)
            kind = geom.get("type")
            fid = _ident(feat)[0]
            name = props.get("name") or (str(fid) if fid is not None else None)
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
    if summary.courtyards:
        summary.notes.append(
            f"{summary.courtyards} inner ring(s) (courtyards) kept open: their buildings cut"
            " into simple prisms"
        )
    fragment: dict[str, Any] = {"frame": frame.to_json()}
    _add_license(fragment, collection, summary)
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


def _add_license(fragment: dict[str, Any], collection: Any, summary: ImportSummary) -> None:
    lic, attr, note = license_of(collection)
    if lic is not None:
        fragment["license"] = lic
        summary.license = lic
    if attr is not None:
        fragment["attribution"] = attr
    if note is not None:
        summary.notes.append(note)


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
    feats = _features(collection)
    frame = _frame_of(feats, origin, opts)
    h0 = frame.origin[2]
    summary = ImportSummary()
    _record_crs(summary, crs)
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
    _add_license(fragment, collection, summary)
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
        members = [
            (m.attrib.get("role") or "outer", ways[m.attrib["ref"]][0])
            for m in rel.iter("member")
            if m.attrib.get("type") == "way" and m.attrib.get("ref") in ways
        ]
        outers = [p for role, p in members if role == "outer"]
        inners = [p for role, p in members if role == "inner"]
        rings = outers + inners
        if not outers or not all(len(p) >= 4 and p[0] == p[-1] for p in rings):
            summary.notes.append(
                f"relation/{rel.attrib.get('id')}: a ring split over several ways: skipped"
            )
            continue
        features.append(
            {
                "type": "Feature",
                "id": f"relation/{rel.attrib.get('id')}",
                "properties": tags,
                "geometry": {"type": "MultiPolygon", "coordinates": _nest(outers, inners)},
            }
        )
    collection = {"type": "FeatureCollection", "license": OSM_LICENSE, "features": features}
    if root.attrib.get("attribution"):
        collection["attribution"] = root.attrib["attribution"]
    return collection, summary


def _nest(outers: list[list[list[float]]], inners: list[list[list[float]]]) -> list[Any]:
    """MultiPolygon coordinates of closed outer and inner rings: each inner ring goes to the
    first outer ring that contains its first vertex (an inner ring inside none is dropped by
    the importer's validity rules as a hole outside its shell)."""
    shapely = require("shapely")
    polys: list[list[Any]] = [[o] for o in outers]
    shells = [shapely.Polygon(o) for o in outers]
    for ring in inners:
        p = shapely.Point(ring[0]) if len(ring) > 1 else None
        k = next((j for j, sh in enumerate(shells) if p is not None and sh.covers(p)), 0)
        polys[k].append(ring)
    return polys
