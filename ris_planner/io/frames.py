"""Geographic frames: a document's ``frame`` ↔ the local metres the engine works in.

A scenario or plan document may carry

* ``"frame": {"origin": [lon, lat, h]}`` – its coordinates are WGS84 longitude, latitude in
  degrees (RFC 7946 order) and heights in metres; or
* ``"frame": {"crs": "EPSG:32635", "origin": [E, N, h]}`` – its coordinates are metres of that
  projected CRS; ``origin`` (in the same CRS) is optional: default the centre of the bounding
  box of the document's points, rounded to the metre.

:func:`to_local` converts every coordinate once, at the boundary, into the local frame and
drops ``frame``; results go back with :meth:`Frame.to_geographic`. Documents without a
``frame`` pass through unchanged (identical dict content).

The local frame is a transverse Mercator projection on the WGS84 ellipsoid centred at the
origin (``+proj=tmerc +lat_0 +lon_0 +k=1``): x east, y north at the origin, in metres. It is
conformal with scale 1 at the origin's meridian; its point scale is k ≈ 1 + x²/(2R²), so a
distance from the origin of d is off by about d³/(6R²): 0.4 mm at 5 km, 4 mm at 10 km,
0.5 m at the :data:`MAX_FRAME_RADIUS_M` limit (tested against geodesic distances). Unlike a
tangent plane (geodetic → ECEF → ENU), the ground stays flat: vertical values are kept as
heights, local z = h − h_origin for every vertical value of the document (the h of 3-D points,
``heights_m`` of walls, ``height_m`` of roads, ``base_m`` of obstacles; extents such as an
obstacle's ``height_m`` are unchanged), whereas the tangent plane would sink a building 1 km
away by 8 cm (d²/2R) and tilt it. Both projections invert to well below 1 mm.
"""

from __future__ import annotations

import copy
import functools
import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.errors import DocumentFieldError
from ris_planner.environment.kinds import point_paths
from ris_planner.io import MissingExtraError, require

FloatArray = NDArray[np.float64]

MAX_FRAME_RADIUS_M = 50_000.0
"""Points farther than this (50 km) from the origin are rejected: lat/lon swapped, a wrong
CRS or a stray feature (the tmerc distance error reaches 0.5 m there)."""

WGS84 = "EPSG:4326"

# Where documents hold coordinates: (path, kind). ``*`` = every list entry. Kinds: ``p3`` a
# point [x, y, z], ``p3s`` a point or a list of points, ``p2`` an [x, y] point, ``z`` a
# vertical value. Paths that do not exist (or have another type) are skipped. The obstacles'
# [x, y] points are each registered kind's ``point_fields`` (:func:`_obstacle_fields`).
_POINT_FIELDS: tuple[tuple[tuple[str, ...], str], ...] = (
    (("candidates", "*", "position"), "p3"),
    (("heatmap_tx",), "p3"),
    (("pairs", "tx", "*"), "p3"),
    (("pairs", "rx", "*"), "p3"),
    (("ris", "*", "position"), "p3"),
    (("tx",), "p3s"),
    (("rx",), "p3s"),
    (("walls", "*", "start"), "p2"),
    (("walls", "*", "end"), "p2"),
    (("walls", "*", "heights_m", "*"), "z"),
    (("environment", "obstacles", "*", "base_m"), "z"),
    *(
        item
        for m in ("tx_map", "rx_map")
        for item in (
            ((m, "points", "*"), "p3"),
            ((m, "roads", "*", "points", "*"), "p2"),
            ((m, "roads", "*", "height_m"), "z"),
        )
    ),
)


def _obstacle_fields() -> tuple[tuple[tuple[str, ...], str], ...]:
    """The [x, y] points of obstacles: the registered kinds' ``point_fields``, read when a
    document is converted (a kind registered at run time included)."""
    return tuple((("environment", "obstacles", "*", *p), "p2") for p in point_paths())


def _iter_fields(doc: dict[str, Any]) -> Iterator[tuple[str, Any, Any, str]]:
    """(dotted path, container, key, kind) of every coordinate value of a document."""

    def rec(
        node: Any, path: tuple[str, ...], at: tuple[str | int, ...]
    ) -> Iterator[tuple[tuple[str | int, ...], Any, Any]]:
        head, rest = path[0], path[1:]
        keys: list[Any]
        if head == "*":
            keys = list(range(len(node))) if isinstance(node, list) else []
        else:
            keys = [head] if isinstance(node, dict) and head in node else []
        for k in keys:
            if rest:
                yield from rec(node[k], rest, (*at, k))
            else:
                yield (*at, k), node, k

    for path, kind in (*_POINT_FIELDS, *_obstacle_fields()):
        for where, holder, key in rec(doc, path, ()):
            if kind == "p3s" and _is_point_list(holder[key]):
                for i in range(len(holder[key])):
                    yield ".".join(map(str, (*where, i))), holder[key], i, "p3"
            else:
                yield ".".join(map(str, where)), holder, key, "p3" if kind == "p3s" else kind


def _is_point_list(value: Any) -> bool:
    return isinstance(value, list) and bool(value) and isinstance(value[0], list)


def _numbers(value: Any, n: tuple[int, ...], where: str) -> list[float]:
    if (
        not isinstance(value, list)
        or len(value) not in n
        or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
    ):
        want = " or ".join(str(k) for k in n)
        raise DocumentFieldError(where, f"expected {want} numbers, got {value!r}")
    try:
        out = [float(v) for v in value]
    except OverflowError:
        out = [math.inf]
    if not all(math.isfinite(v) for v in out):
        raise DocumentFieldError(where, f"coordinates must be finite, got {value!r}")
    return out


@functools.lru_cache(maxsize=32)
def _transformer(src: str, dst: str) -> Any:
    """A cached ``pyproj.Transformer`` (x = east / lon first)."""
    pyproj = require("pyproj")
    return pyproj.Transformer.from_crs(src, dst, always_xy=True)


@dataclass(frozen=True)
class Frame:
    """A local transverse Mercator frame centred at ``origin`` = (lon, lat, h) (WGS84 degrees,
    metres). ``source_crs`` is the CRS of the document's horizontal coordinates (WGS84 lon/lat
    or a projected CRS)."""

    origin: tuple[float, float, float]
    source_crs: str = WGS84

    def __post_init__(self) -> None:
        # plain floats (a numpy scalar's repr would end up in the PROJ string)
        object.__setattr__(self, "origin", tuple(float(v) for v in self.origin))

    @property
    def proj4(self) -> str:
        lon, lat, _ = self.origin
        return (
            f"+proj=tmerc +lat_0={lat!r} +lon_0={lon!r} +k=1 +x_0=0 +y_0=0 +datum=WGS84"
            " +units=m +no_defs +type=crs"
        )

    def local_crs(self) -> Any:
        """The local frame as a ``pyproj.CRS`` (a projected CRS a GIS can reproject)."""
        pyproj = require("pyproj")
        return pyproj.CRS.from_proj4(self.proj4)

    def _transformer(self, src: str, dst: str) -> Any:
        return _transformer(src, dst)

    def from_source(self, xy: FloatArray) -> FloatArray:
        """Source-CRS x, y [N, 2] → local x, y [N, 2] (metres)."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        t = self._transformer(self.source_crs, self.proj4)
        x, y = t.transform(xy[:, 0], xy[:, 1], errcheck=True)
        return np.column_stack([x, y])

    def to_geographic(self, points: FloatArray) -> FloatArray:
        """Local points [N, 2] or [N, 3] → WGS84 [lon, lat(, h)] (degrees, metres)."""
        pts = np.asarray(points, dtype=float)
        flat = pts.reshape(-1, pts.shape[-1])
        t = self._transformer(self.proj4, WGS84)
        lon, lat = t.transform(flat[:, 0], flat[:, 1], errcheck=True)
        cols = [lon, lat] + ([flat[:, 2] + self.origin[2]] if flat.shape[1] == 3 else [])
        return np.column_stack(cols).reshape(pts.shape)

    def from_geographic(self, points: FloatArray) -> FloatArray:
        """WGS84 [lon, lat(, h)] [N, 2|3] → local points of the same shape."""
        pts = np.asarray(points, dtype=float)
        flat = pts.reshape(-1, pts.shape[-1])
        t = self._transformer(WGS84, self.proj4)
        x, y = t.transform(flat[:, 0], flat[:, 1], errcheck=True)
        cols = [x, y] + ([flat[:, 2] - self.origin[2]] if flat.shape[1] == 3 else [])
        return np.column_stack(cols).reshape(pts.shape)

    def to_json(self) -> dict[str, Any]:
        """The ``frame`` of a WGS84 document with this origin."""
        return {"origin": list(self.origin)}

    def describe(self) -> dict[str, Any]:
        """The frame of a result: ``{"origin": [lon, lat, h], "local_crs": proj4}`` (the
        ``frame`` of ``plan.json`` and ``ris_planner_frame`` of ``plan.geojson``)."""
        return {"origin": list(self.origin), "local_crs": self.proj4}


def parse_frame(spec: Any, doc: dict[str, Any] | None = None) -> Frame:
    """The :class:`Frame` of a document's ``frame`` value (``doc`` supplies the points whose
    bounding box centres a projected-CRS frame without ``origin``)."""
    if not isinstance(spec, dict) or not set(spec) <= {"origin", "crs"} or not spec:
        raise DocumentFieldError(
            "frame",
            'expected {"origin": [lon, lat, h]} or {"crs": "EPSG:…"[, "origin": [x, y, h]]},'
            f" got {spec!r}",
        )
    crs = spec.get("crs")
    if crs is None:
        if "origin" not in spec:
            raise DocumentFieldError("frame", "give origin [lon, lat, h] (WGS84) or a crs")
        lon, lat, *h = _numbers(spec["origin"], (2, 3), "frame.origin")
        if not (-180 <= lon <= 180 and -90 <= lat <= 90):
            raise DocumentFieldError(
                "frame.origin",
                f"[lon, lat] = [{lon}, {lat}] is not a WGS84 position (lon within ±180°, lat"
                " within ±90°; GeoJSON order is lon, lat)"
                + (" – lat/lon swapped?" if abs(lon) <= 90 and abs(lat) <= 180 else ""),
            )
        if abs(lat) > 84:
            raise DocumentFieldError("frame.origin", f"latitude {lat} is beyond ±84° (polar sites)")
        return Frame((lon, lat, h[0] if h else 0.0))
    pyproj = require("pyproj")
    if not isinstance(crs, str) or not crs.strip() or len(crs) > MAX_CRS_CHARS:
        raise DocumentFieldError(
            "frame.crs", f'expected a CRS name such as "EPSG:32635", got {crs!r}'
        )
    try:
        src = pyproj.CRS.from_user_input(crs)
    except pyproj.exceptions.CRSError as exc:
        raise DocumentFieldError("frame.crs", f"unknown CRS {crs!r} ({exc})") from None
    if not src.is_projected:
        raise DocumentFieldError(
            "frame.crs",
            f"{crs!r} is not a projected CRS in metres; for lon/lat give"
            ' {"origin": [lon, lat, h]}',
        )
    if "origin" in spec:
        x0, y0, *h = _numbers(spec["origin"], (2, 3), "frame.origin")
    else:
        pts = np.array(
            [
                holder[key][:2]
                for _, holder, key, kind in _iter_fields(doc or {})
                if kind in ("p2", "p3") and isinstance(holder[key], list) and len(holder[key]) >= 2
            ],
            dtype=float,
        ).reshape(-1, 2)
        if len(pts) == 0:
            raise DocumentFieldError("frame", "no coordinates to centre the frame on; give origin")
        x0, y0 = (np.round((pts.min(axis=0) + pts.max(axis=0)) / 2)).tolist()
        h = []
    t = pyproj.Transformer.from_crs(src, WGS84, always_xy=True)
    try:
        lon, lat = t.transform(x0, y0, errcheck=True)
    except pyproj.exceptions.ProjError as exc:
        raise DocumentFieldError(
            "frame.origin", f"[{x0}, {y0}] is not a position of {crs!r} ({exc})"
        ) from None
    return Frame((float(lon), float(lat), h[0] if h else 0.0), src.to_string())


def resolve_crs(name: str) -> Any:
    """The ``pyproj.CRS`` of a CRS name (``EPSG:3067``, ``urn:ogc:def:crs:EPSG::3067``,
    ``OGC:CRS84``, a PROJ string or WKT); ``ValueError`` with PROJ's reason when it knows no
    such CRS, :class:`~ris_planner.io.MissingExtraError` without pyproj."""
    pyproj = require("pyproj")
    try:
        return pyproj.CRS.from_user_input(name)
    except pyproj.exceptions.CRSError as exc:
        raise ValueError(str(exc)) from None


def is_wgs84_lonlat(crs: Any) -> bool:
    """Whether a ``pyproj.CRS`` is WGS84 longitude/latitude (``OGC:CRS84``, ``EPSG:4326``
    whatever its axis order: GeoJSON positions are [lon, lat] in either)."""
    pyproj = require("pyproj")
    return bool(crs.is_geographic and crs.equals(pyproj.CRS(CRS84), ignore_axis_order=True))


def lonlat_of(xy: FloatArray, crs: Any) -> FloatArray:
    """x, y [N, 2] in a horizontal ``pyproj.CRS`` (easting, northing of a projected one; lon,
    lat of a geographic one: x first, whatever the CRS's axis order) → WGS84 lon, lat [N, 2]
    in degrees; a position the CRS cannot convert gives ``inf`` (the caller names it)."""
    pyproj = require("pyproj")
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    t = pyproj.Transformer.from_crs(crs, WGS84, always_xy=True)
    lon, lat = t.transform(xy[:, 0], xy[:, 1])
    return np.column_stack([lon, lat])


CRS84 = "OGC:CRS84"
"""WGS84 longitude, latitude: the CRS of GeoJSON (RFC 7946)."""


EARTH_RADIUS_M = 6_371_008.8
"""Mean Earth radius (IUGG) of the great-circle pre-check of :func:`to_local`."""

MAX_CRS_CHARS = 2000
"""Longest ``frame.crs`` text accepted (an EPSG code, a PROJ string or WKT)."""


def great_circle_m(lonlat: FloatArray, origin: tuple[float, float, float]) -> FloatArray:
    """Haversine distances [N] of WGS84 [lon, lat] [N, 2] from the origin (sphere of
    :data:`EARTH_RADIUS_M`; 0.5 % from the ellipsoid, enough to refuse far points before the
    projection, which is undefined 90° from its meridian)."""
    lon, lat = np.radians(lonlat[:, 0]), np.radians(lonlat[:, 1])
    lon0, lat0 = math.radians(origin[0]), math.radians(origin[1])
    a = np.sin((lat - lat0) / 2) ** 2 + math.cos(lat0) * np.cos(lat) * np.sin((lon - lon0) / 2) ** 2
    return 2 * EARTH_RADIUS_M * np.arcsin(np.sqrt(np.clip(a, 0.0, 1.0)))


def _far_error(where: str, v: list[float], dist_m: float, frame: Frame) -> DocumentFieldError:
    hint = "lat/lon swapped (GeoJSON order is [lon, lat]) or the wrong CRS?"
    if frame.source_crs != WGS84:
        hint = f"easting/northing swapped or not in {frame.source_crs}?"
    elif abs(v[0]) <= 90:
        swapped = float(great_circle_m(np.array([[v[1], v[0]]]), frame.origin)[0])
        if swapped <= MAX_FRAME_RADIUS_M:
            hint = (
                f"lat/lon swapped? (read as [lat, lon] it lies {swapped / 1000:.1f} km from the"
                " origin; GeoJSON order is [lon, lat])"
            )
    return DocumentFieldError(
        where,
        f"{v[:2]} lies {dist_m / 1000:.0f} km from the frame origin {list(frame.origin[:2])}"
        f" (limit {MAX_FRAME_RADIUS_M / 1000:g} km): {hint}",
    )


def _origin_error(frame: Frame, src: FloatArray, dist_m: FloatArray) -> DocumentFieldError:
    """The error on ``frame.origin`` when no point of the document lies near it (checked
    before any single point is blamed: one wrong origin is not every point's fault)."""
    lo, hi = src.min(axis=0), src.max(axis=0)
    centre = ((lo + hi) / 2).tolist()
    o = list(frame.origin[:2])
    what = (
        f"no point of the document lies within {MAX_FRAME_RADIUS_M / 1000:g} km of it (the"
        f" nearest {float(np.min(dist_m)) / 1000:.0f} km; the points lie around"
        f" [{centre[0]:.6f}, {centre[1]:.6f}])"
    )
    if frame.source_crs == WGS84 and abs(o[0]) <= 90:
        swapped = great_circle_m(src, (o[1], o[0], 0.0))
        if float(np.median(swapped)) <= MAX_FRAME_RADIUS_M:
            return DocumentFieldError(
                "frame.origin",
                f"[lon, lat] = {o}: {what}; read as [lat, lon] the origin lies"
                " among them: lat/lon swapped? (GeoJSON order is [lon, lat])",
            )
    if frame.source_crs != WGS84:
        return DocumentFieldError(
            "frame.origin",
            f"(at lon/lat {o}) {what}: the wrong origin, easting/northing swapped or the wrong"
            " CRS?",
        )
    return DocumentFieldError(
        "frame.origin", f"{o}: {what}: the wrong origin, lat/lon swapped or the wrong CRS?"
    )


def check_lonlat(where: str, lon: float, lat: float) -> None:
    """Raise :class:`DocumentFieldError` at ``where`` unless [lon, lat] are degrees within
    range, with ``swapped?`` when the pair is one read as [lat, lon]."""
    if -180 <= lon <= 180 and -90 <= lat <= 90:
        return
    swapped = abs(lon) <= 90 and abs(lat) <= 180  # in range as [lat, lon]
    hint = " – lat/lon swapped? (GeoJSON order is [lon, lat])" if swapped else ""
    raise DocumentFieldError(
        where,
        f"[{lon}, {lat}] is not [lon, lat] in degrees (lon within ±180, lat within ±90){hint}",
    )


def _convert(frame: Frame, items: list[tuple[str, list[float]]]) -> FloatArray:
    """Source x, y of each (field, point) → local x, y [N, 2]. Checks in this order, so the
    error names the field at fault: a point that is no [lon, lat] position (``swapped?`` when
    it is one read as [lat, lon]); ``frame.origin`` when no point lies within
    :data:`MAX_FRAME_RADIUS_M` of it; then the first point beyond that distance."""
    src = np.array([v[:2] for _, v in items], dtype=float)
    if frame.source_crs == WGS84:
        for where, v in items:
            check_lonlat(where, v[0], v[1])
        arc = great_circle_m(src, frame.origin)
        if not np.any(arc <= MAX_FRAME_RADIUS_M):
            raise _origin_error(frame, src, arc)
        far = arc > 2 * MAX_FRAME_RADIUS_M  # certainly too far: refused before projecting
        if np.any(far):
            k = int(np.argmax(far))
            raise _far_error(items[k][0], items[k][1], float(arc[k]), frame)
    try:
        xy = frame.from_source(src)
    except MissingExtraError:
        raise
    except Exception as exc:  # pyproj.exceptions.ProjError: a point the CRS cannot convert
        raise DocumentFieldError(
            "frame.crs", f"coordinates outside the area of {frame.source_crs} ({exc})"
        ) from None
    dist = np.hypot(xy[:, 0], xy[:, 1])
    if not np.any(dist <= MAX_FRAME_RADIUS_M):
        raise _origin_error(frame, src, np.where(np.isfinite(dist), dist, np.inf))
    return xy


LICENSE_FIELDS = ("license", "attribution")
"""Top-level fields of a document that name its data's licence and attribution (an import
copies them from its input; the exports carry them); :func:`to_local` takes them off."""

MAX_LICENSE_CHARS = 2000
"""Longest ``license`` / ``attribution`` text."""


def license_of_document(document: Any) -> dict[str, str]:
    """The ``license`` / ``attribution`` of a document (only those present), or a
    :class:`~ris_planner.core.errors.DocumentFieldError` naming the field when one is not a text."""
    out: dict[str, str] = {}
    if not isinstance(document, dict):
        return out
    for key in LICENSE_FIELDS:
        value = document.get(key)
        if value is None:
            continue
        if not isinstance(value, str) or len(value) > MAX_LICENSE_CHARS:
            raise DocumentFieldError(
                key, f"expected a text of at most {MAX_LICENSE_CHARS} characters, got {value!r:.80}"
            )
        out[key] = value
    return out


Converted = tuple[dict[str, Any], "Frame | None"]
"""A document in local metres and its frame (:func:`to_local`'s answer)."""


def to_local(document: Any) -> tuple[Any, Frame | None]:
    """(the document in local metres without ``frame``, its :class:`Frame`), or the document
    unchanged and ``None`` when it has no ``frame`` (or is no JSON object: the document model
    then says what is wrong). The top-level ``license`` and ``attribution``
    (:data:`LICENSE_FIELDS`) are taken off too: they travel with the document as given to the
    exports, not into the engine.

    The one boundary of geographic documents: ``ris-planner bounds/plan``, the service's
    routes that take a document (``POST /v1/bounds``, ``/v1/plans``, ``/v1/plans/validate``,
    ``/v1/power-allocations``) and its plan jobs all convert here, before validation and the
    size limits (which therefore apply to the converted document).

    Raises :class:`~ris_planner.core.errors.DocumentFieldError` naming the field (its dotted path)
    of
    a bad ``frame``, of a point that is not a coordinate pair, lies outside ±180°/±90° or
    farther than :data:`MAX_FRAME_RADIUS_M` from the origin (lat/lon swapped, a wrong CRS), and
    of a UE ``grid`` or ``csv_text`` (not regular in metres in a geographic frame: give points
    or roads); :class:`~ris_planner.io.MissingExtraError` without pyproj. A ``rectangle`` wall
    becomes its four segment walls (outward facing), since its sides are no longer axis-aligned.
    """
    if not isinstance(document, dict) or not (set(document) & {"frame", *LICENSE_FIELDS}):
        return document, None
    license_of_document(document)
    if "frame" not in document:
        return {k: v for k, v in document.items() if k not in LICENSE_FIELDS}, None
    frame = parse_frame(document["frame"], document)
    doc = copy.deepcopy(
        {k: v for k, v in document.items() if k != "frame" and k not in LICENSE_FIELDS}
    )
    for m in ("tx_map", "rx_map"):
        spec = doc.get(m)
        if isinstance(spec, dict):
            for bad in ("grid", "csv_text", "csv"):
                if spec.get(bad) is not None:
                    raise DocumentFieldError(
                        f"{m}.{bad}",
                        "not supported in a document with a frame (a grid in geographic"
                        " coordinates is not regular in metres); give points, roads or an"
                        " imported area (ris-planner import)",
                    )
    if isinstance(doc.get("walls"), list):
        doc["walls"] = [
            w for i, wall in enumerate(doc["walls"]) for w in _split_rectangle(wall, f"walls.{i}")
        ]
    _search_region_to_local(doc, frame)
    horizontal: list[tuple[str, Any, Any, list[float]]] = []
    for where, holder, key, kind in _iter_fields(doc):
        value = holder[key]
        if kind == "z":
            if isinstance(value, int | float) and not isinstance(value, bool):
                holder[key] = _numbers([value], (1,), where)[0] - frame.origin[2]
            continue
        v = _numbers(value, (3,) if kind == "p3" else (2,), where)
        horizontal.append((where, holder, key, v))
    if horizontal:
        xy = _convert(frame, [(w, v) for w, _, _, v in horizontal])
        dist = np.hypot(xy[:, 0], xy[:, 1])
        far = ~(dist <= MAX_FRAME_RADIUS_M)  # NaN too
        if np.any(far):
            k = int(np.argmax(far))
            where, _, _, v = horizontal[k]
            raise _far_error(where, v, float(dist[k]), frame)
        for (_, holder, key, v), (x, y) in zip(horizontal, xy, strict=True):
            holder[key] = [float(x), float(y)] + ([v[2] - frame.origin[2]] if len(v) == 3 else [])
    return doc, frame


SEARCH_REGION = "validation.search_region"


def _search_region_to_local(doc: dict[str, Any], frame: Frame) -> None:
    """``validation.search_region``'s ``min_lonlat``/``max_lonlat`` ([lon, lat, h], WGS84 in
    GeoJSON order, whatever the frame's CRS) → ``min_m``/``max_m`` in place: the local
    axis-aligned box holding the four corners of the lon/lat box (the lon/lat box's edges are
    not quite local x, y lines: meridians converge), z = h − h_origin. Refused, naming the
    field: both forms, one corner missing, a corner that is no [lon, lat] position or lies
    beyond :data:`MAX_FRAME_RADIUS_M` ("swapped?" when it would be one read as [lat, lon]),
    and an empty box (``min`` above ``max`` on an axis: the corners swapped)."""
    val = doc.get("validation")
    if not isinstance(val, dict):
        return
    region = val.get("search_region")
    if not isinstance(region, dict) or not {"min_lonlat", "max_lonlat"} & set(region):
        return
    if {"min_m", "max_m"} & set(region):
        raise DocumentFieldError(
            SEARCH_REGION,
            "give min_m/max_m (local metres) or min_lonlat/max_lonlat ([lon, lat, h]), not both",
        )
    if "min_lonlat" not in region or "max_lonlat" not in region:
        raise DocumentFieldError(SEARCH_REGION, "give both min_lonlat and max_lonlat")
    lo = _numbers(region["min_lonlat"], (3,), f"{SEARCH_REGION}.min_lonlat")
    hi = _numbers(region["max_lonlat"], (3,), f"{SEARCH_REGION}.max_lonlat")
    for where, v in ((f"{SEARCH_REGION}.min_lonlat", lo), (f"{SEARCH_REGION}.max_lonlat", hi)):
        check_lonlat(where, v[0], v[1])
        arc = float(great_circle_m(np.array([v[:2]]), frame.origin)[0])
        if arc > MAX_FRAME_RADIUS_M:
            raise _far_error(where, v, arc, frame)
    names = ("lon", "lat", "h")
    for axis in range(3):
        if hi[axis] < lo[axis]:
            raise DocumentFieldError(
                SEARCH_REGION,
                f"the box is empty: max_lonlat {names[axis]} {hi[axis]} < min_lonlat"
                f" {names[axis]} {lo[axis]} (corners swapped? min_lonlat is the south-west"
                " bottom corner, max_lonlat the north-east top one)",
            )
    corners = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
    xy = frame.from_geographic(corners)
    low = [*(float(v) for v in xy.min(axis=0)), lo[2] - frame.origin[2]]
    high = [*(float(v) for v in xy.max(axis=0)), hi[2] - frame.origin[2]]
    rest = {k: v for k, v in region.items() if k not in ("min_lonlat", "max_lonlat")}
    val["search_region"] = {**rest, "min_m": low, "max_m": high}


def search_region_lonlat(frame: Frame, region: dict[str, Any], given: Any = None) -> dict[str, Any]:
    """plan.json ``validation.search_region`` with the box also in WGS84: ``min_lonlat`` /
    ``max_lonlat`` [lon, lat, h] of its local min and max corners, and ``given`` the document's
    own ``min_lonlat``/``max_lonlat`` when it gave the region so."""
    lo = frame.to_geographic(np.array([region["min_m"]], dtype=float))[0]
    hi = frame.to_geographic(np.array([region["max_m"]], dtype=float))[0]
    out = {
        **region,
        "min_lonlat": [float(v) for v in lo],
        "max_lonlat": [float(v) for v in hi],
    }
    if isinstance(given, dict) and "min_lonlat" in given and "max_lonlat" in given:
        out["given"] = {"min_lonlat": given["min_lonlat"], "max_lonlat": given["max_lonlat"]}
    return out


def _split_rectangle(wall: Any, where: str) -> list[Any]:
    """A ``rectangle`` wall [x_min, y_min, x_max, y_max] → four segment walls whose ``right``
    normal faces outward (counter-clockwise corners, as :func:`planning.sites.wall_poses`)."""
    if not isinstance(wall, dict) or wall.get("rectangle") is None:
        return [wall]
    x0, y0, x1, y1 = _numbers(wall["rectangle"], (4,), f"{where}.rectangle")
    corners = [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]
    rest = {k: v for k, v in wall.items() if k != "rectangle"}
    return [
        {**rest, "start": corners[i], "end": corners[(i + 1) % 4], "side": "right"}
        for i in range(4)
    ]
