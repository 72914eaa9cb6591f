"""Geographic documents and site imports over REST, against a real uvicorn on 127.0.0.1: a
lon/lat plan document planned as a job gives the files ``ris-planner plan`` writes for it
(plan.geojson in WGS84 near the origin), bounds and validation take frames, bad frames are a 422
naming the field, a server without pyproj a 501; ``POST /v1/import`` of GeoJSON (the Helsinki
example), OSM XML and a DXF drawn by ezdxf, a body over the limit (413) and a bad feature
(422 naming it)."""

from __future__ import annotations

import csv
import io
import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from api_helpers import GEOJSON, OCTETS
from test_api_e2e import poll
from test_api_plans import small_plan_doc, without_timing
from test_io_import import _floor_plan
from tolerance import BOUND_ACCURACY, assert_close
from waits import HANG_S

from api.launch import served
from api.models import SITE_OSM_XML
from ris_planner.io.frames import Frame

ORIGIN = (24.9384, 60.1699, 10.0)
"""Helsinki city centre, 10 m above the ellipsoid (the heights are relative to it)."""

NEAR_ORIGIN_DEG = 1e-3
"""Every exported position of the small plan lies within ~60 m (1e-3° of latitude is 111 m)."""

HELSINKI = Path(__file__).resolve().parent.parent / "examples" / "helsinki"


def geo_plan_doc() -> dict[str, Any]:
    """``small_plan_doc`` in WGS84 around :data:`ORIGIN`: candidates and the 7×7×2 grid of UE
    points as lon/lat/h (a grid itself is refused in a geographic frame)."""
    doc = small_plan_doc()
    frame = Frame(ORIGIN)
    xs = np.arange(-3.0, 3.5, 1.0)
    grid = np.array([[x, y, z] for x in xs for y in xs for z in (0.0, 0.5)])
    points = np.round(frame.to_geographic(grid), 10).tolist()
    for c in doc["candidates"]:
        c["position"] = np.round(frame.to_geographic(np.array([c["position"]])), 10)[0].tolist()
    return doc | {
        "frame": {"origin": list(ORIGIN)},
        "tx_map": {"points": points},
        "rx_map": {"points": points},
    }


def geo_scenario(scenario: dict[str, Any]) -> dict[str, Any]:
    """A local scenario's RIS, TX and RX positions as WGS84 lon/lat/h around :data:`ORIGIN`."""
    frame = Frame(ORIGIN)
    geo = json.loads(json.dumps(scenario))
    for r in geo["ris"]:
        r["position"] = frame.to_geographic(np.array([r["position"]]))[0].tolist()
    for key in ("tx", "rx"):
        geo[key] = frame.to_geographic(np.array([geo[key]], dtype=float))[0].tolist()
    return geo | {"frame": {"origin": list(ORIGIN)}}


POWER_RTOL = 1e-6
"""The lon/lat → metres round trip moves positions by < 1 µm (test_io_frames): the power
objectives of a metre-scale scenario agree far inside this."""


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    tmp = tmp_path_factory.mktemp("geo-server")
    env = {"RIS_PLANNER_MAX_BODY_BYTES": "200000"}
    with served(tmp / "jobs.db", workers=1, env=env, log=tmp / "server.log") as srv:
        yield srv.url


def test_geographic_plan_job_writes_the_cli_files(server: str, tmp_path: Path) -> None:
    from ris_planner.cli import main

    doc = geo_plan_doc()
    r = httpx.post(f"{server}/v1/plans", json=doc, timeout=HANG_S)
    assert r.status_code == 202, r.text
    view = poll(server, r.json()["id"])
    assert view["status"] == "succeeded", view["error"]
    assert view["request"] == doc  # the job keeps the document as sent
    plan = view["result"]
    assert plan["frame"]["origin"] == list(ORIGIN)
    assert plan["frame"]["local_crs"] == Frame(ORIGIN).proj4
    files = {k: httpx.get(server + u, timeout=HANG_S) for k, u in view["figures"].items()}
    geo = files["geojson"].json()
    coords = np.array(
        [f["geometry"]["coordinates"] for f in geo["features"] if f["properties"]["role"] == "ue"]
    )
    assert len(coords) == 98 and np.all(np.abs(coords - ORIGIN[:2]) < NEAR_ORIGIN_DEG)
    # the same document through the command line: the same plan and the same files
    src = tmp_path / "geo.json"
    src.write_text(json.dumps(doc))
    assert main(["plan", str(src), "--out", str(tmp_path / "cli"), "--workers", "1"]) == 0
    # the job ran in another process: figures to the bounds' accuracy, decisions exactly
    cli_plan = json.loads((tmp_path / "cli" / "plan.json").read_text())
    assert_close(without_timing(cli_plan), without_timing(plan), accuracy=BOUND_ACCURACY)
    cli_geo = json.loads((tmp_path / "cli" / "plan.geojson").read_text())
    assert_close(cli_geo, geo, accuracy=BOUND_ACCURACY)
    assert_close(
        csv_rows((tmp_path / "cli" / "points.csv").read_text()),
        csv_rows(files["points_csv"].text),
        accuracy=BOUND_ACCURACY,
    )
    assert_close(
        geotiff_contents((tmp_path / "cli" / "heatmap.tif").read_bytes()),
        geotiff_contents(files["geotiff"].content),
        accuracy=BOUND_ACCURACY,
    )


def csv_rows(text: str) -> list[list[Any]]:
    """A CSV's cells, numbers as floats (so they compare by the tolerance rule)."""

    def cell(v: str) -> Any:
        try:
            return float(v)
        except ValueError:
            return v

    return [[cell(v) for v in row] for row in csv.reader(io.StringIO(text))]


def geotiff_contents(data: bytes) -> dict[str, Any]:
    """A GeoTIFF's georeferencing, tags and pixels (its bytes hold floats from another
    process, so the pixels compare by the tolerance rule)."""
    import rasterio

    with rasterio.MemoryFile(data) as mem, mem.open() as ds:
        return {
            "crs": ds.crs.to_wkt(),
            "transform": list(ds.transform),
            "nodata": ds.nodata,
            "tags": ds.tags(),
            "pixels": ds.read(),
        }


def test_validate_and_bounds_take_frames(server: str) -> None:
    doc = geo_plan_doc()
    preview = httpx.post(f"{server}/v1/plans/validate", json=doc, timeout=HANG_S).json()
    assert preview["frame"]["origin"] == list(ORIGIN) and preview["sites"] == 5
    local = small_plan_doc()  # the same site in local metres: the same expanded positions
    local_preview = httpx.post(f"{server}/v1/plans/validate", json=local, timeout=HANG_S).json()
    got = np.array([c["position"] for c in preview["candidates"]])
    want = np.array([c["position"] for c in local_preview["candidates"]])
    assert np.allclose(got, want, atol=1e-6)  # 1e-10° rounding ≈ 10 µm
    # a scenario in WGS84: the bounds of the same scenario in metres
    scenario = {
        "ris": [{"position": [-4, 0, 2]}, {"position": [4, 0, 2], "orientation": [np.pi, 0, 0]}],
        "tx": [-2, -4, 0],
        "rx": [2, 3, 0],
    }
    geo = geo_scenario(scenario)
    a = httpx.post(f"{server}/v1/bounds", json=geo, timeout=HANG_S)
    b = httpx.post(f"{server}/v1/bounds", json=scenario, timeout=HANG_S)
    assert a.status_code == 200, a.text
    assert a.json()["peb_rx_m"] == pytest.approx(b.json()["peb_rx_m"], rel=1e-6)


def test_geographic_power_allocation(server: str) -> None:
    from test_api_power import small_power_doc

    local = small_power_doc()
    geo = geo_scenario(local)
    r = httpx.post(f"{server}/v1/power-allocations?objective=sum", json=geo, timeout=HANG_S)
    assert r.status_code == 202, r.text
    assert r.json()["request"]["scenario"] == geo  # kept as sent
    ref = httpx.post(f"{server}/v1/power-allocations?objective=sum", json=local, timeout=HANG_S)
    a, b = poll(server, r.json()["id"]), poll(server, ref.json()["id"])
    assert a["status"] == b["status"] == "succeeded", (a["error"], b["error"])
    for part in ("uniform", "sdp"):
        assert a["result"][part]["objective"] == pytest.approx(
            b["result"][part]["objective"], rel=POWER_RTOL
        )
    bad = geo | {"rx": [60.1699, 24.9384, 0.0]}  # [lat, lon]
    r = httpx.post(f"{server}/v1/power-allocations", json=bad, timeout=HANG_S)
    assert r.status_code == 422 and r.json()["fields"][0]["field"] == "rx"


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"frame": {"origin": [60.1699, 24.9384]}}, "frame.origin"),  # lat/lon swapped
        ({"frame": {"origin": ["east", 60.1]}}, "frame.origin"),
        ({"frame": {"crs": 5}}, "frame.crs"),
        ({"frame": {}}, "frame"),
        ({"rx_map": {"grid": {"x": [0, 1, 1], "y": [0, 1, 1], "z": [0, 0, 1]}}}, "rx_map.grid"),
    ],
)
def test_bad_frames_name_the_field(server: str, change: dict[str, Any], field: str) -> None:
    for path in ("/v1/plans", "/v1/plans/validate"):
        r = httpx.post(f"{server}{path}", json=geo_plan_doc() | change, timeout=HANG_S)
        assert r.status_code == 422, r.text
        assert r.json()["fields"][0]["field"] == field, r.json()


def test_a_point_swapped_far_away_names_the_field(server: str) -> None:
    doc = geo_plan_doc()
    p = doc["candidates"][2]["position"]
    doc["candidates"][2]["position"] = [p[1], p[0], p[2]]  # [lat, lon]: 2000 km off
    r = httpx.post(f"{server}/v1/plans", json=doc, timeout=HANG_S)
    assert r.status_code == 422 and r.json()["fields"][0]["field"] == "candidates.2.position"
    assert "swapped" in r.json()["message"]
    assert httpx.get(f"{server}/v1/jobs?kind=plan", timeout=HANG_S).json()["total"] <= 1


def test_without_pyproj_a_frame_is_a_501(tmp_path: Path) -> None:
    """A server whose processes cannot import pyproj (a module of that name first on the path
    that raises ImportError, as a missing package does; the documents are converted in the
    parse processes, api.offload, so the server runs in its own process here)."""
    fake = tmp_path / "nogis"
    (fake / "pyproj").mkdir(parents=True)
    (fake / "pyproj" / "__init__.py").write_text("raise ImportError('No module named pyproj')\n")
    root = Path(__file__).resolve().parent.parent
    path = os.pathsep.join(p for p in (str(fake), str(root), os.environ.get("PYTHONPATH")) if p)
    doc = geo_plan_doc() | {"frame": {"origin": [24.93851, 60.16991, 0.0]}}
    with served(tmp_path / "jobs.db", env={"PYTHONPATH": path}) as server:
        for route in ("/v1/plans", "/v1/plans/validate"):
            r = httpx.post(f"{server.url}{route}", json=doc, timeout=HANG_S)
            assert r.status_code == 501, r.text
            assert "pip install 'ris_planner[gis]'" in r.json()["message"]
        ok = httpx.post(f"{server.url}/v1/plans/validate", json=small_plan_doc(), timeout=HANG_S)
        assert ok.status_code == 200


# --- POST /v1/import -------------------------------------------------------------------------


def helsinki_site(sites: int = 6) -> dict[str, Any]:
    """The Helsinki buildings and streets with the first ``sites`` mounting points."""
    site = json.loads((HELSINKI / "helsinki.geojson").read_text())
    points = json.loads((HELSINKI / "sites.geojson").read_text())["features"][:sites]
    return {"type": "FeatureCollection", "features": site["features"] + points}


def test_import_geojson_gives_a_plan_document(
    server: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from ris_planner.cli import main

    body = json.dumps(helsinki_site()).encode()
    r = httpx.post(
        f"{server}/v1/import?highways=residential",
        content=body,
        headers={"Content-Type": "application/geo+json"},
        timeout=HANG_S,
    )
    assert r.status_code == 200, r.text
    answer = r.json()
    report, doc = answer["report"], answer["document"]
    assert report["format"] == "geojson" and report["buildings"] == 29
    assert report["candidates"] == 6 and len(report["default_height"]) == 29 - 13
    assert len(doc["environment"]["obstacles"]) == 29 and doc["tx_map"] == doc["rx_map"]
    assert doc["frame"] == answer["fragment"]["frame"]
    assert doc["license"] == report["license"] == "© OpenStreetMap contributors, ODbL 1.0"
    preview = httpx.post(f"{server}/v1/plans/validate", json=doc, timeout=HANG_S)
    assert preview.status_code == 200, preview.text
    assert preview.json()["sites"] == 6 and len(preview.json()["obstacles"]) == 29
    assert preview.json()["tx_points"] == 278  # plan_helsinki.py's street points
    # the command line with the same options writes the same document
    src = tmp_path / "site.geojson"
    src.write_bytes(body)
    assert main(["import", "geojson", str(src), "--plan", "--highways", "residential"]) == 0
    assert json.loads(capsys.readouterr().out) == doc


def test_import_osm_xml(server: str) -> None:
    """The OpenAPI document's OSM XML example: a four-storey building and a street."""
    r = httpx.post(
        f"{server}/v1/import",
        content=SITE_OSM_XML.encode(),
        headers={"Content-Type": "application/xml"},
        timeout=HANG_S,
    )
    assert r.status_code == 200, r.text
    doc, report = r.json()["document"], r.json()["report"]
    assert report["format"] == "osm" and report["heights_from_levels"] == 1
    (prism,) = doc["environment"]["obstacles"]
    assert prism["height_m"] == 12.0 and prism["name"] == "way/10"
    assert len(doc["tx_map"]["roads"]) == 1
    assert any("candidate" in n for n in report["notes"])  # no mounting points in the file


def test_import_dxf(server: str, tmp_path: Path) -> None:
    path = tmp_path / "floor.dxf"
    _floor_plan(path, insunits=4)  # millimetres
    body = path.read_bytes()
    url = f"{server}/v1/import?format=dxf&layer=WALLS=wall:2.7&layer=COLUMNS=prism:3:0.1"
    r = httpx.post(url, content=body, headers=OCTETS, timeout=HANG_S)
    assert r.status_code == 200, r.text
    doc, report = r.json()["document"], r.json()["report"]
    walls = [(o["start"], o["end"]) for o in doc["environment"]["obstacles"] if o["kind"] == "wall"]
    assert walls == [([0.0, 0.0], [10.0, 0.0]), ([0.0, 5.0], [4.0, 5.0]), ([4.0, 5.0], [4.0, 8.0])]
    assert report["units_to_m"] == 0.001 and report["prisms"] == 1
    assert doc["tx_map"]["grid"]["x"] == [0.0, 10.0, 5.0]  # a grid over the plan
    # layers that the drawing does not have: a 422 naming them
    doors = f"{server}/v1/import?format=dxf&layer=DOORS=wall:2"
    r = httpx.post(doors, content=body, headers=OCTETS, timeout=HANG_S)
    assert r.status_code == 422 and "'DOORS' not in the drawing" in r.json()["message"]
    r = httpx.post(f"{server}/v1/import?format=dxf", content=body, headers=OCTETS, timeout=HANG_S)
    assert r.status_code == 422 and "no layers chosen" in r.json()["message"]
    nonsense = b"0\nSECTION\nnonsense"
    r = httpx.post(
        f"{server}/v1/import?format=dxf", content=nonsense, headers=OCTETS, timeout=HANG_S
    )
    assert r.status_code == 422 and "request body" in r.json()["message"]


def test_import_errors(server: str) -> None:
    site = helsinki_site(sites=0)
    i = next(k for k, f in enumerate(site["features"]) if f["geometry"]["type"] == "Polygon")
    ring = site["features"][i]["geometry"]["coordinates"][0]
    ring[1] = ring[1][::-1]  # one vertex of a building as [lat, lon]
    name = site["features"][i]["properties"].get("name")
    r = httpx.post(f"{server}/v1/import?origin=24.949,60.1655", json=site, timeout=HANG_S)
    assert r.status_code == 422 and r.json()["message"].startswith(f"feature {i} (id ")
    assert "swapped" in r.json()["message"] and (name is None or name in r.json()["message"])
    assert r.json()["fields"][0]["field"] == f"features.{i}"  # the feature's path in the body
    bowtie = [[24.94, 60.16], [24.941, 60.161], [24.941, 60.16], [24.94, 60.161], [24.94, 60.16]]
    bad = {
        "type": "FeatureCollection",
        "features": [
            {
                "type": "Feature",
                "id": "b7",
                "properties": {"building": "yes"},
                "geometry": {"type": "Polygon", "coordinates": [bowtie]},
            }
        ],
    }
    r = httpx.post(f"{server}/v1/import?invalid=error", json=bad, timeout=HANG_S)
    assert r.status_code == 422, r.text
    assert "feature 0 (id b7) at [24.940000, 60.160000]: invalid outline" in r.json()["message"]
    assert r.json()["fields"][0]["field"] == "features.0"
    # by default repaired, and listed by id and lon/lat; or skipped
    r = httpx.post(f"{server}/v1/import", json=bad, timeout=HANG_S)
    assert r.status_code == 200, r.text
    (entry,) = r.json()["report"]["repaired"]
    assert (entry["id"], entry["lonlat"], entry["parts"]) == ("b7", [24.94, 60.16], 2)
    assert len(r.json()["document"]["environment"]["obstacles"]) == 2
    r = httpx.post(f"{server}/v1/import?invalid=skip", json=bad, timeout=HANG_S)
    assert r.status_code == 200 and r.json()["report"]["skipped_invalid"][0]["id"] == "b7"
    r = httpx.post(f"{server}/v1/import?invalid=mend", json=bad, timeout=HANG_S)
    assert r.status_code == 422 and r.json()["fields"][0]["field"] == "invalid"
    # an origin given as LAT,LON: the origin is named, not a feature
    r = httpx.post(f"{server}/v1/import?origin=60.1655,24.949", json=site, timeout=HANG_S)
    assert r.status_code == 422 and r.json()["fields"][0]["field"] == "origin"
    assert "swapped?" in r.json()["message"]
    for body, status in [
        (b"{not json", 400),  # malformed JSON: 400 on every route
        (b'{"type": "FeatureCollection", "features": []}', 422),
        (b"\x00\x01", 422),
    ]:
        r = httpx.post(f"{server}/v1/import", content=body, headers=OCTETS, timeout=HANG_S)
        assert r.status_code == status and r.json()["message"], (body, r.text)
    big = json.dumps(helsinki_site()).encode() * 6  # > RIS_PLANNER_MAX_BODY_BYTES = 200 000
    r = httpx.post(f"{server}/v1/import", content=big, headers=GEOJSON, timeout=HANG_S)
    assert r.status_code == 413 and r.json()["limit"] == 200_000
    spec = httpx.get(f"{server}/openapi.json", timeout=HANG_S).json()
    body_types = spec["paths"]["/v1/import"]["post"]["requestBody"]["content"]
    assert {"application/geo+json", "application/xml", "application/octet-stream"} <= set(
        body_types
    )


def test_import_converts_a_named_projected_crs(tmp_path: Path) -> None:
    """``POST /v1/import`` of a GeoJSON in ETRS-TM35FIN (EPSG:3067) named by its crs member: the
    same site as the WGS84 file within a centimetre (``_assert_same_site``), the conversion in
    the report; an unknown
    CRS is a 422 on ``crs`` saying what was seen and how to convert; a site without buildings
    is imported with a warning."""
    from api_helpers import api_client
    from test_io_import import TM35FIN_URN, _assert_same_site, _projected, _site_wgs84

    from ris_planner.io.geojson_read import NO_BUILDINGS_WARNING

    crs = {"type": "name", "properties": {"name": TM35FIN_URN}}
    origin = "24.949,60.1655"
    with api_client(tmp_path) as client:
        want = client.post(f"/v1/import?origin={origin}", json=_site_wgs84())
        assert want.status_code == 200, want.text
        r = client.post(f"/v1/import?origin={origin}", json=_projected(_site_wgs84(), crs))
        assert r.status_code == 200, r.text
        answer = r.json()
        _assert_same_site(answer["fragment"], want.json()["fragment"])
        assert answer["report"]["crs"]["name"] == "ETRS89 / TM35FIN(E,N)"
        assert answer["report"]["crs"]["given"] == crs
        assert any("converted from the crs member" in n for n in answer["report"]["notes"])
        doc = answer["document"]
        assert doc["tx_map"] == answer["fragment"]["ue_map"] and "crs" not in doc
        # an unknown CRS: a 422 on crs naming the member and the way out
        bad = {"type": "name", "properties": {"name": "EPSG:99999"}}
        r = client.post("/v1/import", json=_projected(_site_wgs84(), bad))
        assert r.status_code == 422, r.text
        assert r.json()["fields"][0]["field"] == "crs"
        message = r.json()["message"]
        assert "crs member" in message and "EPSG:99999" in message and "ogr2ogr" in message
        # no buildings: imported, with a warning in the report
        roads = {
            "type": "FeatureCollection",
            "features": [f for f in _site_wgs84()["features"] if "highway" in f["properties"]],
        }
        r = client.post("/v1/import", json=roads)
        assert r.status_code == 200, r.text
        assert r.json()["report"]["warnings"] == [NO_BUILDINGS_WARNING]
