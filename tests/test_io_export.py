"""Export: plan.geojson (RFC 7946 checks, read back with pyogrio), heatmap.tif (pixels at their
coordinates, nodata inside buildings), points.csv; ``plan --out`` and the Helsinki example."""

from __future__ import annotations

import csv
import importlib.util
import io
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pyproj = pytest.importorskip("pyproj")
rasterio = pytest.importorskip("rasterio")
pyogrio = pytest.importorskip("pyogrio")
shapely = pytest.importorskip("shapely")

from ris_planner.cli import main  # noqa: E402
from ris_planner.environment.kinds.prism import closed_ccw_ring  # noqa: E402
from ris_planner.io.frames import Frame, to_local  # noqa: E402
from ris_planner.io.geojson_write import plan_geojson  # noqa: E402
from ris_planner.io.geotiff import NODATA, write_geotiff  # noqa: E402
from ris_planner.io.import_options import OSM_LICENSE as LICENSE  # noqa: E402
from ris_planner.io.points_csv import points_csv  # noqa: E402
from ris_planner.model.scenario import SystemParams  # noqa: E402
from ris_planner.planning import PlanDocument, SerialExecutor, run_plan  # noqa: E402

ORIGIN = (24.949, 60.1655, 0.0)
FRAME = Frame(ORIGIN)
GEOD = pyproj.Geod(ellps="WGS84")
ROOT = Path(__file__).parent.parent

LONLAT_TOLERANCE_DEG = 1e-8
"""Exported degrees are rounded to 1e-9° (0.1 mm); 1e-8° ≈ 1 mm."""

BUILDING = [[5.0, 5.0], [5.0, 11.0], [11.0, 11.0], [11.0, 5.0]]  # clockwise on purpose


def _ll(xy: Any) -> list:
    return FRAME.to_geographic(np.asarray(xy, dtype=float)).tolist()


def geo_plan_document() -> dict[str, Any]:
    """A small plan in WGS84: three candidates, UE points on a 2 m grid, a building and a wall
    (passed to the planner only where it takes an environment)."""
    grid = [[x, y, 1.5] for x in range(0, 14, 2) for y in range(0, 6, 2)]
    doc: dict[str, Any] = {
        "frame": {"origin": list(ORIGIN)},
        "candidates": [
            {"position": _ll([[-5.0, 2.0, 3.0]])[0], "orientation": [0.0, 0.2, 0.0], "name": "W"},
            {"position": _ll([[7.0, -5.0, 3.0]])[0], "orientation": [math.pi / 2, 0.2, 0.0]},
            {"position": _ll([[18.0, 2.0, 3.0]])[0], "orientation": [math.pi, 0.2, 0.0]},
        ],
        "tx_map": {"points": _ll(grid)},
        "rx_map": {"points": _ll(grid)},
        "pairs": "unordered",
        "objective": {"kind": "coverage", "metric": "rx", "threshold_m": 0.5},
        "ris_count": [1, 2],
        "search": {"top_k": 2},
    }
    env = {
        "obstacles": [
            {"kind": "prism", "name": "block", "footprint": _ll(BUILDING), "height_m": 10},
            {
                "kind": "wall",
                "start": _ll([[-3.0, 8.0]])[0],
                "end": _ll([[3.0, 8.0]])[0],
                "height_m": 2,
            },
        ]
    }
    if "environment" in PlanDocument.model_fields:
        doc["environment"] = env
    return {**doc, "_environment": env}


def _run(doc: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any], Any]:
    """(plan.json, export document, result) of a document from :func:`geo_plan_document`."""
    env = doc.pop("_environment")
    local, _ = to_local(doc)
    with SerialExecutor() as ex:
        result = run_plan(local, executor=ex)
    return result.to_json(), {**doc, "environment": env}, result


@pytest.fixture(scope="module")
def planned() -> tuple[dict[str, Any], dict[str, Any], Any]:
    return _run(geo_plan_document())


def _signed_area(ring: list[list[float]]) -> float:
    r = np.asarray(ring[:-1])
    return 0.5 * float(
        np.dot(r[:, 0], np.roll(r[:, 1], -1)) - np.dot(r[:, 1], np.roll(r[:, 0], -1))
    )


def rfc7946_problems(fc: dict[str, Any]) -> list[str]:
    """RFC 7946 checks: a FeatureCollection of Features; positions [lon, lat] within range
    (§3.1.1, §4); LineStrings ≥ 2 positions; Polygon rings closed, ≥ 4 positions, exterior
    counter-clockwise and holes clockwise (§3.1.6 right-hand rule); no ``crs`` member."""
    out = []
    if fc.get("type") != "FeatureCollection" or "crs" in fc:
        out.append("not a FeatureCollection without crs")

    def pos(p: Any, where: str) -> None:
        if not (isinstance(p, list) and 2 <= len(p) <= 3):
            out.append(f"{where}: position {p}")
        elif not (-180 <= p[0] <= 180 and -90 <= p[1] <= 90):
            out.append(f"{where}: {p} outside lon/lat ranges")

    for i, f in enumerate(fc.get("features", [])):
        g = f.get("geometry") or {}
        if f.get("type") != "Feature" or not isinstance(f.get("properties"), dict):
            out.append(f"feature {i}: not a Feature with properties")
        c = g.get("coordinates")
        if g.get("type") == "Point":
            pos(c, f"feature {i}")
        elif g.get("type") == "LineString":
            if len(c) < 2:
                out.append(f"feature {i}: LineString with < 2 positions")
            for p in c:
                pos(p, f"feature {i}")
        elif g.get("type") == "Polygon":
            for k, ring in enumerate(c):
                for p in ring:
                    pos(p, f"feature {i} ring {k}")
                if len(ring) < 4 or ring[0] != ring[-1]:
                    out.append(f"feature {i} ring {k}: not closed")
                elif (_signed_area(ring) > 0) != (k == 0):
                    out.append(f"feature {i} ring {k}: wrong winding")
        else:
            out.append(f"feature {i}: geometry {g.get('type')}")
    return out


def test_rfc7946_checker_catches_violations() -> None:
    cw = [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.0, 0.0]]

    def feature(geometry: dict[str, Any]) -> dict[str, Any]:
        return {"type": "Feature", "properties": {}, "geometry": geometry}

    bad = {
        "type": "FeatureCollection",
        "features": [
            feature({"type": "Point", "coordinates": [60.0, 100.0]}),  # lat > 90
            feature({"type": "Polygon", "coordinates": [cw]}),  # clockwise exterior
            feature({"type": "Polygon", "coordinates": [cw[:-1]]}),  # not closed
        ],
    }
    assert len(rfc7946_problems(bad)) == 3
    fixed = closed_ccw_ring(np.array(cw[:-1]))
    assert fixed[0] == fixed[-1] and _signed_area(fixed) > 0  # closed, reversed to CCW


def test_plan_geojson_is_rfc7946_and_reads_in_a_gis(planned: Any, tmp_path: Path) -> None:
    plan, doc, result = planned
    points = [
        {"index": i, "position": p, "weight": 1.0, "bound_m": {"2": 0.1 * i}}
        for i, p in enumerate(result.rx_map.points.tolist())
    ]
    fc = plan_geojson(plan, doc, points)
    assert rfc7946_problems(fc) == []
    roles = [f["properties"]["role"] for f in fc["features"]]
    n_sites = sum(len(lay["sites"]) for b in plan["by_count"] for lay in b["top_layouts"])
    assert roles.count("site") == n_sites and roles.count("candidate") == 3
    assert roles.count("ue") == len(points) and roles.count("obstacle") == 2
    # candidates at the geographic positions they were given
    given = [c["position"] for c in doc["candidates"]]
    got = [f for f in fc["features"] if f["properties"]["role"] == "candidate"]
    for g, f in zip(given, got, strict=True):
        assert np.allclose(f["geometry"]["coordinates"], g[:2], atol=LONLAT_TOLERANCE_DEG)
        assert f["properties"]["height_m"] == pytest.approx(g[2])
    best = next(f["properties"] for f in fc["features"] if f["properties"]["role"] == "site")
    half_wavelength = SystemParams().wavelength / 2  # the default element spacing
    assert best["rank"] == 1 and best["rows"] == 10
    assert best["size_m"] == pytest.approx([10 * half_wavelength, 10 * half_wavelength])
    # the building: a counter-clockwise 6 m × 6 m polygon (geodesic area: an independent route)
    block = next(f for f in fc["features"] if f["properties"].get("name") == "block")
    ring = np.array(block["geometry"]["coordinates"][0])
    area, _ = GEOD.polygon_area_perimeter(ring[:, 0], ring[:, 1])
    assert area == pytest.approx(36.0, rel=1e-5)
    # read back with a GIS reader (GDAL's GeoJSON driver)
    path = tmp_path / "plan.geojson"
    path.write_text(json.dumps(fc))
    meta, _, wkb, columns = pyogrio.raw.read(path)  # no geopandas needed
    assert meta["crs"] == "EPSG:4326" and len(wkb) == len(fc["features"])
    roles = columns[list(meta["fields"]).index("role")]
    assert sorted(set(roles)) == ["candidate", "obstacle", "site", "ue"]
    assert set(shapely.get_type_id(shapely.from_wkb(wkb))) == {0, 1, 3}  # Point, Line, Polygon
    # without per-point results: sites, candidates and obstacles only
    no_points = {k: v for k, v in plan.items() if k != "points"}
    roles = [f["properties"]["role"] for f in plan_geojson(no_points, doc)["features"]]
    assert "ue" not in roles and roles.count("candidate") == 3


def test_local_documents_export_local_metres(planned: Any) -> None:
    plan, doc, _ = planned
    local, _ = to_local(doc)
    fc = plan_geojson(plan, local)
    assert fc["ris_planner_frame"].startswith("local metres")
    cand = next(f for f in fc["features"] if f["properties"]["role"] == "candidate")
    assert np.allclose(cand["geometry"]["coordinates"], [-5, 2], atol=1e-6)


def pixel_of(ds: Any, x: float, y: float) -> tuple[int, int]:
    """(row, col) of the pixel containing (x, y), from the north-up transform coefficients
    (x = c + col·a, y = f + row·e at pixel corners)."""
    t = ds.transform
    assert t.b == 0 and t.d == 0  # north up
    return int(np.floor((y - t.f) / t.e)), int(np.floor((x - t.c) / t.a))


def centre_of(ds: Any, row: int, col: int) -> tuple[float, float]:
    t = ds.transform
    return t.c + (col + 0.5) * t.a, t.f + (row + 0.5) * t.e


def _grid_points() -> list[dict[str, Any]]:
    pts = []
    for i, (x, y) in enumerate((x, y) for x in range(0, 16, 2) for y in range(0, 16, 2)):
        pts.append(
            {"index": i, "position": [x, y, 1.5], "weight": 1.0, "bound_m": {"3": 0.01 * (i + 1)}}
        )
    pts[5]["bound_m"]["3"] = None  # a blind spot
    return pts


@pytest.mark.parametrize("geographic", [True, False])
def test_geotiff_pixels_sit_at_their_points(tmp_path: Path, geographic: bool) -> None:
    points = _grid_points()
    env = {"obstacles": [{"kind": "prism", "footprint": BUILDING, "height_m": 10}]}
    doc: dict[str, Any] = {"environment": env}
    if geographic:
        env = {"obstacles": [{"kind": "prism", "footprint": _ll(BUILDING), "height_m": 10}]}
        doc = {"frame": {"origin": list(ORIGIN)}, "environment": env}
    path = write_geotiff(tmp_path / "heatmap.tif", points, doc)
    with rasterio.open(path) as ds:
        band = ds.read(1)
        assert ds.res == (2.0, 2.0) and band.shape == (8, 8) and ds.nodata == NODATA
        if geographic:
            to_wgs84 = pyproj.Transformer.from_crs(ds.crs.to_wkt(), "EPSG:4326", always_xy=True)
        for p in points:
            x, y = p["position"][:2]
            row, col = pixel_of(ds, x, y)
            assert centre_of(ds, row, col) == pytest.approx((x, y), abs=1e-9)
            inside = 5 < x < 11 and 5 < y < 11
            b = p["bound_m"]["3"]
            if inside:
                assert band[row, col] == NODATA
            elif b is None:
                assert np.isposinf(band[row, col])
            else:
                assert band[row, col] == pytest.approx(b, rel=1e-7)  # float32
            if geographic:  # the raster's own CRS puts the pixel at the point's lon/lat
                lon, lat = to_wgs84.transform(*centre_of(ds, row, col))
                assert np.allclose([lon, lat], _ll([[x, y]])[0], atol=1e-10)
        assert (band == NODATA).sum() == 9  # the pixel centres at 6, 8, 10 inside the block
        assert ("ENGCRS" in ds.crs.to_wkt() or "LOCAL_CS" in ds.crs.to_wkt()) != geographic


def test_geotiff_keeps_the_smallest_bound_per_pixel(tmp_path: Path) -> None:
    points = [
        {"position": [0.0, 0.0, 1.5], "bound_m": {"2": 3.0}},
        {"position": [0.0, 0.0, 10.0], "bound_m": {"2": 1.0}},
        {"position": [4.0, 0.0, 1.5], "bound_m": {"2": None}},
        {"position": [4.0, 0.0, 8.0], "bound_m": {"2": 2.0}},
    ]
    path = write_geotiff(tmp_path / "h.tif", points, {}, pixel_m=4.0)
    with rasterio.open(path) as ds:
        assert ds.read(1).tolist() == [[1.0, 2.0]]


def test_points_csv(planned: Any) -> None:
    _, doc, _ = planned
    pts = [
        {"index": 0, "position": [1.0, 2.0, 1.5], "weight": 2.0, "bound_m": {"2": 0.5, "3": None},
         "serving": {"2": [0, 4], "3": []}, "reason": {"2": None, "3": "underdetermined: ris1"}},
    ]  # fmt: skip
    rows = list(csv.DictReader(io.StringIO(points_csv(pts, doc))))
    (row,) = rows
    assert row["bound_m_2"] == "0.5" and row["bound_m_3"] == "" and row["serving_2"] == "0 4"
    assert row["reason_3"] == "underdetermined: ris1"
    assert [float(row["lon"]), float(row["lat"])] == pytest.approx(_ll([[1.0, 2.0]])[0], abs=1e-9)


def test_plan_cli_writes_gis_files(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    doc = geo_plan_document()
    doc.pop("_environment")
    doc |= {"license": LICENSE, "attribution": "Imported with ris-planner"}
    src = tmp_path / "plan.json"
    src.write_text(json.dumps(doc))
    out = tmp_path / "out"
    assert main(["plan", str(src), "--out", str(out), "--workers", "1"]) == 0
    plan = json.loads((out / "plan.json").read_text())
    assert plan["frame"]["origin"] == list(ORIGIN)
    # the licence in every file
    assert plan["license"] == LICENSE
    fc = json.loads((out / "plan.geojson").read_text())
    assert (fc["license"], fc["attribution"]) == (LICENSE, "Imported with ris-planner")
    with rasterio.open(out / "heatmap.tif") as ds:
        tags = ds.tags()
        assert tags["TIFFTAG_COPYRIGHT"] == f"{LICENSE}; Imported with ris-planner"
        assert tags["license"] == LICENSE
    lines = (out / "points.csv").read_text().splitlines()
    assert lines[:2] == [f"# license: {LICENSE}", "# attribution: Imported with ris-planner"]
    assert lines[2].startswith("index,x_m,")
    sites = [f["properties"] for f in fc["features"] if f["properties"]["role"] == "site"]
    assert sites and all(
        {"azimuth_deg", "tilt_deg", "roll_deg"} <= set(p) and not any(k.endswith("_rad") for k in p)
        for p in sites
    )
    for name in ("plan.geojson", "heatmap.tif", "points.csv", "heatmap.png"):
        assert (out / name).is_file()
    fc = json.loads((out / "plan.geojson").read_text())
    assert rfc7946_problems(fc) == []
    ue = [f for f in fc["features"] if f["properties"]["role"] == "ue"]
    assert len(ue) == len(doc["rx_map"]["points"])
    with rasterio.open(out / "heatmap.tif") as ds:
        band = ds.read(1)
        local, _ = to_local(doc)
        for f in ue[:5]:
            x, y = local["rx_map"]["points"][f["properties"]["index"]][:2]
            b = f["properties"]["bound_m"]["2"]
            v = band[pixel_of(ds, x, y)]
            assert np.isposinf(v) if b is None else v == pytest.approx(b, rel=1e-6)
    # a geographic document with swapped coordinates: exit 2, one line naming the field
    capsys.readouterr()
    doc["rx_map"]["points"][3] = [*doc["rx_map"]["points"][3][1::-1], 1.5]
    src.write_text(json.dumps(doc))
    assert main(["plan", str(src), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: rx_map.points.3: ") and "swapped" in err and err.count("\n") == 1


def test_helsinki_example_small(tmp_path: Path) -> None:
    spec = importlib.util.spec_from_file_location(
        "plan_helsinki", ROOT / "examples/plan_helsinki.py"
    )
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    doc, environment = mod.helsinki_document(pairs=150)
    doc["ris_count"] = [2]
    doc["ris"] = {"rows": 16, "cols": 16}
    local, _frame = to_local(doc)
    with SerialExecutor() as ex:
        result = run_plan(local, executor=ex)
    from ris_planner.io.gis_outputs import plan_outputs

    files = plan_outputs(result, result.to_json(), {**doc, "environment": environment}, tmp_path)
    fc = json.loads(files["geojson"].read_text())
    assert rfc7946_problems(fc) == []
    roles = [f["properties"]["role"] for f in fc["features"]]
    assert roles.count("obstacle") == 29 and roles.count("candidate") == len(doc["candidates"])
    lons = [
        f["geometry"]["coordinates"][0] for f in fc["features"] if f["geometry"]["type"] == "Point"
    ]
    assert min(lons) > 24.94 and max(lons) < 24.96  # central Helsinki
    with rasterio.open(files["geotiff"]) as ds:
        assert ds.crs.is_projected and (ds.read(1) == NODATA).any()


def test_heights_go_back_to_the_documents_datum() -> None:
    """With an origin at h = 20 m, local z = h − 20; the export adds the 20 m back."""
    frame = Frame((24.949, 60.1655, 20.0))
    pos = frame.to_geographic(np.array([[3.0, 4.0, 5.0]]))[0].tolist()  # h = 25
    doc = {
        "frame": {"origin": list(frame.origin)},
        "candidates": [{"position": pos}],
        "environment": {
            "obstacles": [
                {"kind": "prism", "footprint": _ll(BUILDING), "base_m": 21.0, "height_m": 4}
            ]
        },
    }
    plan = {
        "candidates": [{"index": 0, "position": [3.0, 4.0, 5.0], "orientation": [0.0, 0.0, 0.0]}],
        "by_count": [{"ris_count": 1, "top_layouts": [{"sites": [0], "objective": 0.5}]}],
    }
    fc = plan_geojson(plan, doc)
    site, cand, block = (f["properties"] for f in fc["features"])
    assert site["height_m"] == cand["height_m"] == pytest.approx(25.0)
    assert site["azimuth_deg"] == pytest.approx(90.0)  # yaw 0 faces east
    # degrees, as the import's input: no radians in a GIS file
    plan["candidates"][0]["orientation"] = [math.pi, math.radians(15), 0.0]
    site, cand, _ = (f["properties"] for f in plan_geojson(plan, doc)["features"])
    assert site["azimuth_deg"] == pytest.approx(270.0) and site["tilt_deg"] == pytest.approx(15)
    assert cand["tilt_deg"] == pytest.approx(15) and cand["roll_deg"] == 0
    assert not [k for k in (*site, *cand) if k.endswith("_rad")]
    assert "license" not in plan_geojson(plan, doc)  # none given, none written
    assert block["base_m"] == pytest.approx(21.0) and block["height_m"] == 4
