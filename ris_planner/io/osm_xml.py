"""``.osm`` XML (JOSM, Overpass, openstreetmap.org exports) → a GeoJSON FeatureCollection
(:func:`osm_xml_features`; guide: ``docs/guides/import.md``), read by
:func:`~ris_planner.io.geojson_read.import_features`.

The file is read with the standard library's :mod:`xml.etree.ElementTree`: the format is flat
(nodes, ways with node references, tags), so no binary dependency is needed; for ``.pbf`` files
convert with ``osmium export`` or read them with the ``osmium`` package as
``examples/helsinki/extract.py`` does.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from typing import IO, Any

from ris_planner.core.errors import RisPlannerError
from ris_planner.io import require
from ris_planner.io.import_options import OSM_LICENSE, ImportSummary


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
