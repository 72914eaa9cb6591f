"""A real site end to end, as a planner meets it: a small OpenStreetMap cut that the examples do
not use (``tests/data/osm/bulevardi.geojson``, © OpenStreetMap contributors, ODbL 1.0: 45
buildings, courtyards among them, 139 streets) → candidate sites → a starting plan → the plan →
its exports, with the documented defaults (only the pair sample and the candidate count made
small for the test's time), through the command line and through REST on a real uvicorn.

Checked independently of the planner (shapely on the imported footprints): no candidate RIS
and no scored UE point lies inside a building; every export carries the data's licence; the
plan states its physics, its diagnosis and its provenance. The page's run of the same chain is
in ``tests/test_web.py``."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from waits import HANG_S

from api.launch import served
from ris_planner.cli import main
from ris_planner.io.frames import to_local
from ris_planner.model.plan_physics import PLAN_MAX_ANGLE_DEG, PLAN_PATTERN_EXPONENT

shapely = pytest.importorskip("shapely")

SITE = Path(__file__).parent / "data" / "osm" / "bulevardi.geojson"
LICENSE = "© OpenStreetMap contributors, ODbL 1.0"
PAIRS = 200
"""The pair sample of the test's plans (the import's default is 1000; the rest is default)."""
MAX_CANDIDATES = 60
INSIDE_M = 0.01
"""A point deeper than this inside a footprint (between its base and top) is inside the
building (the environment contract's 1 cm)."""


def buildings(local_doc: dict[str, Any]) -> list[tuple[Any, float, float]]:
    """(footprint polygon, base, top) of every prism of a document in local metres."""
    from shapely.geometry import Polygon

    out = []
    for ob in local_doc["environment"]["obstacles"]:
        assert ob["kind"] == "prism"
        base = float(ob.get("base_m", 0.0))
        out.append((Polygon(ob["footprint"]), base, base + float(ob["height_m"])))
    return out


def inside_any(points: np.ndarray, prisms: list[tuple[Any, float, float]]) -> list[int]:
    """Indices of the points [N, 3] more than INSIDE_M inside some prism."""
    from shapely.geometry import Point

    bad = []
    for i, (x, y, z) in enumerate(points):
        for poly, base, top in prisms:
            if base + INSIDE_M < z < top - INSIDE_M and poly.buffer(-INSIDE_M).contains(
                Point(x, y)
            ):
                bad.append(i)
                break
    return bad


def check_plan(plan_doc: dict[str, Any], plan: dict[str, Any]) -> None:
    """The plan of the starting document: candidates and scored UE points outside every
    building, the physics, diagnosis, licence and provenance stated."""
    local, _ = to_local(plan_doc)
    prisms = buildings(local)
    cands = np.array([c["position"] for c in local["candidates"]], dtype=float)
    assert len(cands) > 0 and inside_any(cands, prisms) == []
    ues = np.array([p["position"] for p in plan["points"]], dtype=float)
    assert len(ues) > 0 and inside_any(ues, prisms) == []
    # the import's starting plan writes the documented physical element model out
    assert plan["physics"]["pattern_exponent"] == PLAN_PATTERN_EXPONENT
    assert plan["physics"]["max_angle_deg"] == PLAN_MAX_ANGLE_DEG
    assert plan["diagnosis"]["verdict"] in ("ok", "weak", "useless")
    if plan["diagnosis"]["verdict"] != "ok":
        assert plan["diagnosis"]["causes"], "a weak or useless plan says why"
    assert plan["license"] == LICENSE
    assert len(plan["provenance"]["input_sha256"]) == 64
    assert [b["ris_count"] for b in plan["by_count"]] == [2, 3]


def test_command_line_chain(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cand = tmp_path / "candidates.geojson"
    argv = ["sites", str(SITE), "--out", str(cand), "--max-candidates", str(MAX_CANDIDATES)]
    assert main(argv) == 0
    sites = json.loads(cand.read_text())
    assert sites["license"] == LICENSE and 0 < len(sites["features"]) <= MAX_CANDIDATES
    plan_path = tmp_path / "plan.json"
    argv = ["import", "geojson", str(SITE), "--plan", "--candidates", str(cand)]
    assert main([*argv, "--out", str(plan_path)]) == 0
    doc = json.loads(plan_path.read_text())
    assert len(doc["candidates"]) == len(sites["features"])
    assert doc["frame"]["origin"] == sites["frame"]["origin"]  # the candidates' frame
    doc["pairs"]["sample"] = PAIRS
    plan_path.write_text(json.dumps(doc))
    out = tmp_path / "out"
    assert main(["plan", str(plan_path), "--out", str(out), "--workers", "1"]) == 0
    text = capsys.readouterr().out
    assert "\n2 RIS: " in text and "\n3 RIS: " in text
    plan = json.loads((out / "plan.json").read_text())
    check_plan(doc, plan)
    geo = json.loads((out / "plan.geojson").read_text())
    assert geo["license"] == LICENSE
    assert (out / "points.csv").read_text().startswith("# license: " + LICENSE)
    for png in ("topview.png", "heatmap.png", "cdf.png"):
        assert (out / png).read_bytes()[:4] == b"\x89PNG"
    import rasterio

    with rasterio.open(out / "heatmap.tif") as tif:
        assert LICENSE in tif.tags().values()


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    tmp = tmp_path_factory.mktemp("real-site")
    with served(tmp / "jobs.db", workers=1, log=tmp / "server.log") as srv:
        yield srv.url


def test_rest_chain(server: str) -> None:
    raw = SITE.read_bytes()
    r = httpx.post(
        f"{server}/v1/import",
        content=raw,
        headers={"Content-Type": "application/geo+json"},
        timeout=HANG_S,
    )
    assert r.status_code == 200, r.text
    doc = r.json()["document"]
    options = {"max_candidates": MAX_CANDIDATES}
    r = httpx.post(
        f"{server}/v1/sites", json={"site": json.loads(raw), "options": options}, timeout=HANG_S
    )
    assert r.status_code == 200, r.text
    sites = r.json()
    assert sites["frame"]["origin"] == doc["frame"]["origin"]  # the same default frame
    r = httpx.post(
        f"{server}/v1/import?format=sites",
        content=json.dumps(sites).encode(),
        headers={"Content-Type": "application/geo+json"},
        timeout=HANG_S,
    )
    assert r.status_code == 200, r.text
    doc["candidates"] = r.json()["fragment"]["candidates"]
    doc["pairs"]["sample"] = PAIRS
    r = httpx.post(f"{server}/v1/plans", json=doc, timeout=HANG_S)
    assert r.status_code == 202, r.text
    job = r.json()["id"]
    deadline = HANG_S
    import time

    t0 = time.monotonic()
    while True:
        view = httpx.get(f"{server}/v1/jobs/{job}", timeout=HANG_S).json()
        if view["status"] in ("succeeded", "failed", "cancelled"):
            break
        assert time.monotonic() - t0 < deadline, f"job still {view['status']}"
        time.sleep(0.5)
    assert view["status"] == "succeeded", view["error"]
    check_plan(doc, view["result"])
    geo = httpx.get(server + view["figures"]["geojson"], timeout=HANG_S).json()
    assert geo["license"] == LICENSE
