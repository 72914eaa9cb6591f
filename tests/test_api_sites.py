"""``POST /v1/sites`` against a real uvicorn on 127.0.0.1: the Helsinki site (raw GeoJSON and the
document ``POST /v1/import`` makes of it) gives what ``ris-planner sites`` writes plus its
summary, bad options are a 422 naming ``options.…``, a body over the limit and a layout over
the generator's site and leg limits a 413 before any work, a missing API key a 401."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest
from api_helpers import api_client
from waits import HANG_S

from api.launch import served
from ris_planner.io.candidates import (
    MAX_VISIBILITY_LEGS,
    CandidateOptions,
    candidate_sites,
    generate_candidates,
)

HELSINKI = Path(__file__).resolve().parent.parent / "examples" / "helsinki"
BODY_LIMIT = 200_000


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    tmp = tmp_path_factory.mktemp("sites-server")
    env = {"RIS_PLANNER_MAX_BODY_BYTES": str(BODY_LIMIT)}
    with served(tmp / "jobs.db", workers=1, env=env, log=tmp / "server.log") as srv:
        yield srv.url


def helsinki() -> dict:
    return json.loads((HELSINKI / "helsinki.geojson").read_text())


def test_sites_of_the_helsinki_site(server: str) -> None:
    options = {"kinds": ["facade", "pole"], "heights_m": [4, 8], "max_candidates": 200}
    r = httpx.post(
        f"{server}/v1/sites", json={"site": helsinki(), "options": options}, timeout=HANG_S
    )
    assert r.status_code == 200, r.text
    answer = r.json()
    want, summary = candidate_sites(helsinki(), CandidateOptions.model_validate(options))
    assert answer["summary"] == summary.to_json()
    assert {k: v for k, v in answer.items() if k != "summary"} == want
    assert answer["type"] == "FeatureCollection" and answer["license"].startswith("©")
    assert summary.candidates == 200 and set(summary.by_kind) == {"facade", "pole"}
    # the answer as it is is a sites file: POST /v1/import takes it, in the site's frame
    r = httpx.post(f"{server}/v1/import?format=sites", json=answer, timeout=HANG_S)
    assert r.status_code == 200, r.text
    fragment = r.json()["fragment"]
    assert fragment["frame"] == answer["frame"] and len(fragment["candidates"]) == 200
    names = [c["name"] for c in fragment["candidates"]]
    assert names == [f["properties"]["name"] for f in answer["features"]]
    # the document POST /v1/import makes of the site: the same frame, prisms, streets
    imported = httpx.post(f"{server}/v1/import", json=helsinki(), timeout=HANG_S)
    assert imported.status_code == 200, imported.text
    doc = imported.json()["document"]
    facades = {"kinds": ["facade"]}
    r = httpx.post(f"{server}/v1/sites", json={"site": doc, "options": facades}, timeout=HANG_S)
    assert r.status_code == 200, r.text
    assert r.json()["frame"] == doc["frame"] == answer["frame"]
    want = generate_candidates(helsinki(), CandidateOptions(kinds=["facade"]))
    assert r.json()["features"] == want["features"]


def test_sites_errors(server: str) -> None:
    url = f"{server}/v1/sites"
    r = httpx.post(
        url, json={"site": helsinki(), "options": {"spacing_m": 0, "kinds": []}}, timeout=HANG_S
    )
    assert r.status_code == 422
    fields = {f["field"] for f in r.json()["fields"]}
    assert fields == {"options.spacing_m", "options.kinds"}, r.json()
    r = httpx.post(url, json={"site": helsinki(), "options": {"tilts": [10]}}, timeout=HANG_S)
    assert r.status_code == 422 and r.json()["fields"][0]["field"] == "options.tilts"
    r = httpx.post(url, json={"options": {}}, timeout=HANG_S)
    assert r.status_code == 422 and r.json()["fields"][0]["field"] == "site"
    ring = [[24.94, 160.17], [24.941, 160.17], [24.941, 160.171], [24.94, 160.17]]  # lat > 90
    feature = {"type": "Feature", "properties": {"building": "yes"}}
    feature["geometry"] = {"type": "Polygon", "coordinates": [ring]}
    r = httpx.post(
        url, json={"site": {"type": "FeatureCollection", "features": [feature]}}, timeout=HANG_S
    )
    assert r.status_code == 422 and r.json()["fields"][0]["field"] == "site.features.0"
    assert "swapped?" in r.json()["message"]
    no_ue = {"frame": {"origin": [24.94, 60.17]}, "environment": {"obstacles": []}}
    r = httpx.post(url, json={"site": no_ue}, timeout=HANG_S)
    assert r.status_code == 422 and "no UE positions" in r.json()["message"]
    # too large: the body (before it is read), the layout (before any visibility test)
    r = httpx.post(url, content=b"{" + b" " * BODY_LIMIT + b"}", timeout=HANG_S)
    assert r.status_code == 413 and r.json()["limit"] == BODY_LIMIT
    r = httpx.post(url, json={"site": helsinki(), "options": {"spacing_m": 0.001}}, timeout=HANG_S)
    assert r.status_code == 413 and "sites before the visibility filter" in r.json()["message"]
    # 48 627 sites × 692 UE points = 33.6 M legs fit; 97 195 × 692 = 67.3 M do not
    r = httpx.post(url, json={"site": helsinki(), "options": {"spacing_m": 0.05}}, timeout=HANG_S)
    assert r.status_code == 413 and "visibility legs" in r.json()["message"]
    assert r.json()["limit"] == MAX_VISIBILITY_LEGS


def test_sites_needs_the_api_key(tmp_path: Path) -> None:
    with api_client(tmp_path, api_key="k3y") as client:
        body = {"site": helsinki(), "options": {"kinds": ["pole"]}}
        assert client.post("/v1/sites", json=body).status_code == 401
        r = client.post("/v1/sites", json=body, headers={"X-API-Key": "k3y"})
        assert r.status_code == 200 and r.json()["summary"]["by_kind"] == {"pole": 29}


def test_one_set_of_generation_defaults(server: str) -> None:
    """The defaults of POST /v1/sites – every one stated in the OpenAPI schema, which the
    planner page fills its generation form from – are those of ``ris-planner sites`` without
    flags: one model (:class:`CandidateOptions`) holds them all."""
    from ris_planner.cli.app import build_parser
    from ris_planner.cli.geo import candidate_options_of

    spec = httpx.get(f"{server}/openapi.json", timeout=HANG_S).json()
    props = spec["components"]["schemas"]["CandidateOptions"]["properties"]
    defaults = CandidateOptions().model_dump(mode="json")
    assert {k: p.get("default") for k, p in props.items()} == defaults
    cli = candidate_options_of(build_parser("sites").parse_args(["sites", "site.geojson"]))
    assert cli == CandidateOptions()
    off = build_parser("sites").parse_args(["sites", "site.geojson", "--no-swap-check"])
    assert candidate_options_of(off) == CandidateOptions(swap_check=False)
    assert (defaults["spacing_m"], defaults["heights_m"]) == (10.0, [4.0, 8.0])


def swapped(site: dict) -> dict:
    """The site with every position written [lat, lon] (what the swap check refuses)."""

    def turn(c: list) -> list:
        return [c[1], c[0], *c[2:]] if isinstance(c[0], int | float) else [turn(x) for x in c]

    feats = [
        {**f, "geometry": {**f["geometry"], "coordinates": turn(f["geometry"]["coordinates"])}}
        for f in site["features"]
    ]
    return {**site, "features": feats}


def test_the_swap_check_can_be_turned_off(server: str) -> None:
    """A file that fails the import's file-wide swap check says to turn the check off; the
    generation has the same option (swap_check, --no-swap-check), so the page's one control
    serves both."""
    site = swapped(helsinki())
    options = {"max_candidates": 5, "kinds": ["facade"]}
    r = httpx.post(f"{server}/v1/sites", json={"site": site, "options": options}, timeout=HANG_S)
    assert r.status_code == 422 and "turn the swap check off" in r.json()["message"]
    off = {**options, "swap_check": False}
    r = httpx.post(f"{server}/v1/sites", json={"site": site, "options": off}, timeout=HANG_S)
    assert r.status_code == 200, r.text
    assert r.json()["summary"]["candidates"] == 5
