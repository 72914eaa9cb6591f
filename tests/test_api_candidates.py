"""``POST /v1/candidates/convert`` and ``POST /v1/site/preview`` (the planner page's helpers):
checked against independent routes – geodesic distances (pyproj.Geod), the import of the same
sites file through ``POST /v1/import``, and the preview of ``POST /v1/plans/validate``."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest
from api_helpers import api_client
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
        doc = client.post("/v1/import?format=geojson", content=body).json()["document"]
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
