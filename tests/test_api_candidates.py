"""``POST /v1/candidates/convert`` and ``POST /v1/site/preview`` (the planner page's helpers):
checked against independent routes – geodesic distances (pyproj.Geod), the import of the same
sites file through ``POST /v1/import``, and the preview of ``POST /v1/plans/validate``."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest
from api_helpers import GEOJSON, api_client
from tolerance import assert_close

pyproj = pytest.importorskip("pyproj")

HELSINKI = Path(__file__).resolve().parent.parent / "examples" / "helsinki"
ORIGIN = [24.949, 60.1655, 2.0]

PROJ_INVERSE_ATOL_M = 1e-6
"""A local → WGS84 → local round trip through PROJ's transverse Mercator (forward and inverse
series, accurate to well below a micrometre within 50 km of the origin) agrees to 1 µm."""

GEODESIC_ATOL_M = 1e-6
"""tmerc with k = 1 is true to scale on its central meridian and off by x²/(2R²) ≈ 1.2e-10
(relative) 100 m away: 1e-8 m over 100 m, far below 1 µm; Geod's inverse is exact to nm."""


def _candidates() -> list[dict[str, Any]]:
    return [
        {"position": [100.0, 0.0, 6.0], "orientation": [0.3, 0.1, 0.0], "name": "east"},
        {"position": [0.0, -100.0, 4.0], "orientation": [-2.0, 0.2, 0.0]},
        {"position": [-35.5, 72.25, 8.5], "orientation": [3.0, 0.0, 0.0], "cost": 2.0},
    ]


def test_local_to_document_and_back(tmp_path: Path) -> None:
    with api_client(tmp_path) as client:
        frame = {"origin": ORIGIN}
        answer = client.post(
            "/v1/candidates/convert", json={"frame": frame, "local": _candidates()}
        )
        assert answer.status_code == 200, answer.text
        doc = answer.json()["document"]
        geod = pyproj.Geod(ellps="WGS84")
        for c, d in zip(_candidates(), doc, strict=True):
            x, y, z = c["position"]
            lon, lat, h = d["position"]
            _, _, dist = geod.inv(ORIGIN[0], ORIGIN[1], lon, lat)
            assert abs(dist - math.hypot(x, y)) <= GEODESIC_ATOL_M
            assert h == pytest.approx(z + ORIGIN[2], abs=1e-12)  # one addition
            assert d["orientation"] == c["orientation"]  # positions only are converted
        # 100 m east of the origin: on the origin's parallel to first order, east of it
        assert doc[0]["position"][0] > ORIGIN[0]
        assert doc[1]["position"][1] < ORIGIN[1]
        back = client.post("/v1/candidates/convert", json={"frame": frame, "document": doc}).json()
        for c, got in zip(_candidates(), back["local"], strict=True):
            assert_close(got["position"], c["position"], atol=PROJ_INVERSE_ATOL_M)
            assert got["orientation"] == c["orientation"]
        assert back["document"] == doc
        # without a frame the local metres are the document's
        plain = client.post("/v1/candidates/convert", json={"local": _candidates()}).json()
        assert plain["local"] == plain["document"]
        assert [c["position"] for c in plain["local"]] == [c["position"] for c in _candidates()]


def test_sites_are_the_imports_candidates(tmp_path: Path) -> None:
    """GeoJSON mounting points → the candidates POST /v1/import makes of the same file at the
    same origin, in local metres as POST /v1/plans/validate previews them."""
    sites = json.loads((HELSINKI / "sites.geojson").read_text())
    origin = [*ORIGIN[:2], 0.0]
    with api_client(tmp_path) as client:
        conv = client.post(
            "/v1/candidates/convert", json={"frame": {"origin": origin}, "sites": sites}
        )
        assert conv.status_code == 200, conv.text
        local = conv.json()["local"]
        assert len(local) == len(sites["features"]) == 26
        imported = client.post(
            "/v1/import?format=sites&origin=" + ",".join(map(str, origin)),
            content=json.dumps(sites).encode(),
            headers={"content-type": "application/geo+json"},
        )
        assert imported.status_code == 200, imported.text
        doc = imported.json()["document"]
        ues = [[ORIGIN[0], ORIGIN[1], 1.5], [ORIGIN[0] + 1e-4, ORIGIN[1], 1.5]]
        doc["tx_map"] = doc["rx_map"] = {"points": ues}
        doc["ris_count"] = [1]
        preview = client.post("/v1/plans/validate", json=doc)
        assert preview.status_code == 200, preview.text
        want = preview.json()["candidates"]
        for got, w in zip(local, want, strict=True):
            assert_close(got["position"], w["position"], atol=PROJ_INVERSE_ATOL_M)
            assert_close(got["orientation"], w["orientation"])
            assert got["name"] == w["name"]
        # the azimuth convention: compass 266.71° (facing west) → yaw = 90° − 266.71° ≈ −π
        az = sites["features"][0]["properties"]["azimuth_deg"]
        assert_close(local[0]["orientation"][0], math.radians(90 - az))


def test_convert_errors_name_the_field(tmp_path: Path) -> None:
    with api_client(tmp_path) as client:
        bad = client.post("/v1/candidates/convert", json={"local": [{"position": [0, 0, "x"]}]})
        assert bad.status_code == 422
        assert bad.json()["fields"][0]["field"] == "local.0.position.2"
        both = client.post("/v1/candidates/convert", json={"local": [], "document": []})
        assert both.status_code == 422 and "exactly one" in both.json()["message"]
        point = {"type": "Point", "coordinates": [24.9, 60.1]}
        no_height = {
            "type": "FeatureCollection",
            "features": [{"type": "Feature", "properties": {}, "geometry": point}],
        }
        got = client.post(
            "/v1/candidates/convert",
            json={"frame": {"origin": [24.9, 60.1]}, "sites": no_height},
        )
        assert got.status_code == 422
        assert got.json()["fields"][0]["field"] == "sites.features.0"
        assert "height" in got.json()["message"]
        unframed = client.post("/v1/candidates/convert", json={"sites": no_height})
        assert unframed.status_code == 422 and "frame" in unframed.json()["message"]
        swapped = client.post(
            "/v1/candidates/convert",
            json={"frame": {"origin": [60.1, 24.9]}, "document": [{"position": [24.9, 60.1, 0]}]},
        )
        assert swapped.status_code == 422
        # the origin is the swapped one (the candidate lies where [lat, lon] of it would)
        assert swapped.json()["fields"][0]["field"] == "frame.origin"
        assert "swapped?" in swapped.json()["message"]


def test_site_preview_of_an_import_without_candidates(tmp_path: Path) -> None:
    """The imported Helsinki blocks (no candidates: validate refuses them) preview their
    buildings and road points as validate does once a candidate is added."""
    body = (HELSINKI / "helsinki.geojson").read_bytes()
    with api_client(tmp_path) as client:
        doc = client.post("/v1/import?format=geojson", content=body, headers=GEOJSON).json()[
            "document"
        ]
        assert client.post("/v1/plans/validate", json=doc).status_code == 422
        site = client.post("/v1/site/preview", json=doc)
        assert site.status_code == 200, site.text
        got = site.json()
        assert (
            len(got["obstacles"]) == 29 and got["frame"]["origin"][:2] == doc["frame"]["origin"][:2]
        )
        street = got["rx_map"]["points"][0]
        with_site = doc | {
            "candidates": [
                {
                    "position": [
                        *client.post(
                            "/v1/candidates/convert",
                            json={
                                "frame": doc["frame"],
                                "local": [{"position": [*street[:2], 6.0]}],
                            },
                        ).json()["document"][0]["position"]
                    ],
                    "orientation": [0, 0, 0],
                }
            ],
            "ris_count": [1],
        }
        want = client.post("/v1/plans/validate", json=with_site)
        assert want.status_code == 200, want.text
        w = want.json()
        assert got["obstacles"] == w["obstacles"]
        # validate drops UE points inside buildings; the site preview draws every road point
        kept = {tuple(p) for p in w["rx_map"]["points"]}
        assert kept <= {tuple(p) for p in got["rx_map"]["points"]}
        assert got["rx_map"]["total"] >= w["rx_map"]["total"] > 0
        bad = client.post("/v1/site/preview", json={"tx_map": {"points": []}})
        assert bad.status_code == 422 and bad.json()["fields"][0]["field"].startswith("tx_map")


CANDIDATES_FILE_ATOL = 1e-9
"""Two routes to a candidates file differ by a local → WGS84 → local → WGS84 round trip
through PROJ's transverse Mercator (≤ 1 µm, about 1e-11° at 60° N: PROJ_INVERSE_ATOL_M) and by
azimuth → yaw → azimuth (a few ulps of 360°): absolute 1e-9 (degrees, metres) bounds both."""


def same_candidates_file(got: dict[str, Any], want: dict[str, Any], where: str = "file") -> None:
    """Equal candidates files under the tolerance rule: the same members, frame, names and
    properties; positions, heights and angles to :data:`CANDIDATES_FILE_ATOL` (azimuths on the
    circle: 359.999… and 0 are the same facing)."""
    assert {k: v for k, v in got.items() if k != "features"} == {
        k: v for k, v in want.items() if k != "features"
    }, where
    assert len(got["features"]) == len(want["features"]), where
    for i, (g, w) in enumerate(zip(got["features"], want["features"], strict=True)):
        gp, wp = dict(g["properties"]), dict(w["properties"])
        turn = (gp.pop("azimuth_deg") - wp.pop("azimuth_deg") + 180.0) % 360.0 - 180.0
        assert abs(turn) <= CANDIDATES_FILE_ATOL, f"{where}.features[{i}]: azimuth {turn}"
        assert_close(gp, wp, atol=CANDIDATES_FILE_ATOL, where=f"{where}.features[{i}]")
        assert_close(
            g["geometry"], w["geometry"], atol=CANDIDATES_FILE_ATOL, where=f"{where}.features[{i}]"
        )


def test_the_candidates_file_is_one_document_on_every_route(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The same site through ``ris-planner sites``, ``POST /v1/sites`` and the page's download
    (the generated list in local metres → ``POST /v1/candidates/geojson``) gives the same file:
    the licence and ``frame`` at the top (no ``ris_planner_frame``), the same sites. Imported
    again – command line or service – it centres on the frame it was generated in, so the
    candidates land where they were (an import without ``frame`` centres on the candidates'
    own bounding box, tens of metres away)."""
    from ris_planner.cli import main
    from ris_planner.io.candidates import SITE_PROPERTIES
    from ris_planner.io.frames import to_local
    from ris_planner.io.site_import import import_data

    site_path = HELSINKI / "helsinki.geojson"
    site = json.loads(site_path.read_text())
    cli_path = tmp_path / "candidates.geojson"
    assert main(["sites", str(site_path), "--out", str(cli_path), "--max-candidates", "40"]) == 0
    capsys.readouterr()
    cli = json.loads(cli_path.read_text())
    assert cli["license"] == site["license"] and "ris_planner_frame" not in cli
    with api_client(tmp_path) as client:
        rest = client.post("/v1/sites", json={"site": site, "options": {"max_candidates": 40}})
        assert rest.status_code == 200, rest.text
        answer = rest.json()
        answer.pop("summary")
        same_candidates_file(answer, cli, "POST /v1/sites")
        # the page: the import's document, the answer converted into its frame, then written
        doc = client.post("/v1/import", json=site).json()["document"]
        local = client.post(
            "/v1/candidates/convert", json={"frame": doc["frame"], "sites": answer}
        ).json()["local"]
        members = {k: answer[k] for k in ("license", "source") if k in answer}
        props = [{k: f["properties"][k] for k in SITE_PROPERTIES} for f in answer["features"]]
        body = {"frame": doc["frame"], "local": local, "properties": props, **members}
        page = client.post("/v1/candidates/geojson", json=body)
        assert page.status_code == 200, page.text
        same_candidates_file(page.json(), cli, "the page's download")
        # imported again: the file's frame is the import's (command line and service)
        page_path = tmp_path / "page-candidates.geojson"
        page_path.write_text(page.text)
        fragment, _ = import_data(page_path.read_bytes(), "sites")
        assert fragment["frame"] == cli["frame"]
        plan_path = tmp_path / "plan.json"
        argv = ["import", "geojson", str(site_path), "--plan", "--candidates", str(page_path)]
        assert main([*argv, "--out", str(plan_path)]) == 0
        capsys.readouterr()
        again = json.loads(plan_path.read_text())
        assert again["frame"]["origin"] == cli["frame"]["origin"]
        # a plan's candidates (plan.json: local metres, with its frame and licence) → the same
        # file without what the generator said of each site
        plan_cands = to_local(again)[0]["candidates"]
        origin = again["frame"]["origin"]
        result = client.post(
            "/v1/candidates/geojson",
            json={"frame": {"origin": origin}, "local": plan_cands, "license": again["license"]},
        )
        assert result.status_code == 200, result.text
        bare = {k: v for k, v in cli.items() if k != "source"}
        bare["features"] = [
            {**f, "properties": {k: v for k, v in f["properties"].items() if k not in props[0]}}
            for f in cli["features"]
        ]
        same_candidates_file(result.json(), bare, "a plan's candidates")


def test_the_candidates_file_route(tmp_path: Path) -> None:
    """POST /v1/candidates/geojson: roll and cost written where not 0, the licence members
    kept, a 422 naming the field for a bad candidate or properties that do not fit."""
    with api_client(tmp_path) as client:
        cands = [
            {"position": [10.0, 0.0, 5.0], "orientation": [math.pi / 2, 0.2, 0.1], "cost": 3.0},
            {"position": [0.0, 0.0, 0.0], "name": "origin"},
        ]
        body = {"frame": {"origin": ORIGIN}, "local": cands, "attribution": "© someone"}
        got = client.post("/v1/candidates/geojson", json=body)
        assert got.status_code == 200, got.text
        fc = got.json()
        assert fc["attribution"] == "© someone" and fc["frame"] == {"origin": ORIGIN}
        first, second = (f["properties"] for f in fc["features"])
        assert_close(first["azimuth_deg"], 0.0, atol=1e-12)  # yaw π/2: facing north
        assert_close(first["tilt_deg"], math.degrees(0.2))
        assert_close(first["roll_deg"], math.degrees(0.1))
        assert (first["cost"], first["height_m"]) == (3.0, 5.0) and "name" not in first
        assert second == {"name": "origin", "azimuth_deg": 90.0, "tilt_deg": 0.0, "height_m": 0.0}
        assert fc["features"][1]["geometry"]["coordinates"] == ORIGIN  # the origin itself
        bad = client.post(
            "/v1/candidates/geojson", json={**body, "local": [{"position": [0, 0, "x"]}]}
        )
        assert bad.status_code == 422 and bad.json()["fields"][0]["field"] == "local.0.position.2"
        short = client.post("/v1/candidates/geojson", json={**body, "properties": [None]})
        assert short.status_code == 422 and "2 candidates" in short.json()["message"]
        pose = client.post(
            "/v1/candidates/geojson", json={**body, "properties": [{"azimuth_deg": 3}, None]}
        )
        assert pose.status_code == 422 and "azimuth_deg" in pose.json()["message"]
        local = client.post("/v1/candidates/geojson", json={"local": cands})
        assert local.status_code == 422 and local.json()["fields"][0]["field"] == "frame"


def test_every_candidate_inside_a_building_is_named_where_the_document_has_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Five candidates inside five buildings of an imported site: the refusal counts them and
    names every one with its position in the document's coordinates – WGS84 [lon, lat, h] for
    the geographic document (``ris-planner plan`` and ``POST /v1/plans/validate`` alike), local
    metres for the same document in local metres – and its building."""
    shapely_geometry = pytest.importorskip("shapely.geometry")
    from ris_planner.cli import main
    from ris_planner.io.candidates import document_positions
    from ris_planner.io.frames import parse_frame, to_local
    from ris_planner.planning.prepare import prepare_plan
    from ris_planner.planning.scoring.visibility import SitesInsideError

    body = (HELSINKI / "helsinki.geojson").read_bytes()
    with api_client(tmp_path) as client:
        doc = client.post("/v1/import?format=geojson", content=body, headers=GEOJSON).json()[
            "document"
        ]
        local_doc, _ = to_local(doc)
        obstacles = local_doc["environment"]["obstacles"]
        tall = [k for k, ob in enumerate(obstacles) if ob["height_m"] > 4][:5]
        inner = [
            shapely_geometry.Polygon(obstacles[k]["footprint"]).representative_point() for k in tall
        ]
        local = [[p.x, p.y, 3.0] for p in inner]
        frame = parse_frame(doc["frame"])
        geo = document_positions(frame, local).tolist()
        names = [f"inside {k}" for k in tall]
        doc["candidates"] = [
            {"position": g, "orientation": [0.0, 0.0, 0.0], "name": n}
            for g, n in zip(geo, names, strict=True)
        ]
        doc["ris_count"] = [1]
        answer = client.post("/v1/plans/validate", json=doc)
        assert answer.status_code == 422, answer.text
        message = answer.json()["message"]
    assert message.startswith("5 candidate sites lie inside a building")
    for i, (k, n, g) in enumerate(zip(tall, names, geo, strict=True)):
        where = f"[lon, lat, h] = [{g[0]:.7f}, {g[1]:.7f}, {g[2]:.2f}]"
        assert f"candidate {i} ({n}) at {where} inside environment obstacle {k} (" in message
    assert "[x, y, z]" not in message
    # the command line: the same words on stderr, exit status 2
    path = tmp_path / "inside.json"
    path.write_text(json.dumps(doc))
    assert main(["plan", str(path), "--out", str(tmp_path / "out")]) == 2
    assert message in capsys.readouterr().err
    # the document in local metres: named in local metres
    local_doc["candidates"] = to_local(doc)[0]["candidates"]
    local_doc["ris_count"] = [1]
    with pytest.raises(SitesInsideError) as exc:
        prepare_plan(local_doc)
    assert len(exc.value.sites) == 5 and [s.name for s in exc.value.sites] == names
    for p in local:
        assert f"[x, y, z] = [{p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}] m" in str(exc.value)
    # a process boundary (a job, the parse pool) keeps the sites and their positions' text
    import pickle

    again = pickle.loads(pickle.dumps(exc.value))
    assert str(again) == str(exc.value) and again.sites == exc.value.sites
