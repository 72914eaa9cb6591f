"""The ``crs`` member of a GeoJSON collection → WGS84 [lon, lat] (guide:
``docs/guides/import.md``).

Input coordinates are WGS84 [lon, lat] (RFC 7946), or those of the CRS the collection names in
a ``crs`` member (the 2008 GeoJSON specification's ``{"type": "name", "properties": {"name":
"urn:ogc:def:crs:EPSG::3067"}}``, or ``"EPSG:3067"``), which are converted to WGS84 with pyproj
first and the conversion listed in the summary (:func:`wgs84_collection`; a CRS that PROJ does
not know is an error on ``crs`` saying how to convert the file).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from typing import Any

import numpy as np

from ris_planner.core.errors import DocumentFieldError
from ris_planner.io import MissingExtraError
from ris_planner.io.frames import is_wgs84_lonlat, lonlat_of, resolve_crs
from ris_planner.io.import_options import FeatureError, ImportSummary, feature_label

CRS_CONVERT_HINT = (
    "GeoJSON is WGS84 [lon, lat] (RFC 7946): convert the file, e.g. with"
    " ogr2ogr -f GeoJSON -t_srs EPSG:4326 out.geojson in.geojson, or name a CRS that PROJ"
    ' knows in the crs member ({"type": "name", "properties": {"name": "EPSG:3067"}})'
)
"""How to get a file the importer reads, in the errors about a ``crs`` member."""


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


def record_crs(summary: ImportSummary, info: dict[str, Any] | None) -> None:
    """The summary's ``crs`` entry and note of :func:`wgs84_collection`'s conversion."""
    if info is not None:
        summary.crs = info
        summary.notes.append(crs_note(info))
