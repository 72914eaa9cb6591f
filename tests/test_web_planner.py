"""The planner page doing the whole job in headless Chromium against a real uvicorn on
127.0.0.1 (the fixtures and helpers of ``test_web``): import the Helsinki blocks with import
options, place, move, turn and remove candidates on the map, set the parameters, plan, read the
counts table, colour bar and legend, render a diagnosis and a sizing answer, export plan.json,
plan.geojson and the candidates; the API-key banner; candidate generation (POST /v1/sites).

Screenshots go to the tests' temporary folder (and ``out/web/`` with
``RIS_PLANNER_SCREENSHOTS``); docs/guides/web-page.md shows two of them.
"""

# ruff: noqa: F811  (the fixtures of test_web, imported by name, are the tests' parameters)
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import httpx
import pytest
from test_api_candidates import same_candidates_file
from test_web import (  # noqa: F401  (fixtures: browser, page, server, shots)
    WAIT_MS,
    Browser,
    Console,
    Page,
    Shots,
    browser,
    drawn_ue_points,
    expect,
    low_contrast_text,
    no_horizontal_scroll,
    page,
    screen_of,
    server,
    set_box,
    settle,
    shots,
    undeclared_percentages,
    unlabelled_controls,
)
from waits import HANG_S

from api.launch import served
from ris_planner.io.candidates import CandidateOptions, candidates_geojson
from ris_planner.io.frames import Frame

HELSINKI = Path(__file__).resolve().parent.parent / "examples" / "helsinki"

JOB_WAIT_MS = WAIT_MS
"""The wait for a small plan (3 sites, 4 × 4 elements, 200 pairs, 1–2 RISs) to finish: a few
seconds on an idle machine; the wait ends a hang only (tests/waits.py)."""

PX_TOL = 1.5
"""A dragged candidate lands within 1.5 screen pixels of the pointer (the map's rounding of
the pointer position to its viewBox)."""


def open_planner(pg: Page, url: str) -> None:
    pg.goto(url + "/")
    expect(pg.locator("#server-status")).to_contain_text("Server ok")
    expect(pg.locator("#geojson-box")).to_be_visible()


def drawn_ues_of(pg: Page, preview: str) -> int:
    """UE points the map draws once ``state.<preview>`` is there."""
    pg.wait_for_function(f"() => Boolean(window.risPlanner.state.{preview})", timeout=WAIT_MS)
    return drawn_ue_points(pg)


EXPORT_ROUNDING_M = 1e-4
"""plan.geojson rounds lon/lat to 1e-9° (ris_planner.io.geojson_write.LONLAT_DIGITS): ≤ 0.5e-9° ×
111.3 km/° = 56 µm per axis, under 0.1 mm together."""

SPOT_SPACING_M = 25.0
"""Candidates go on street points this far apart around the middle of the site: close enough
for two RISs to serve the streets between them, so the heatmap has finite cells."""


def spread_near_centre(points: list[list[float]], n: int, spacing: float) -> list[list[float]]:
    """``n`` of ``points`` nearest the median point, each ≥ ``spacing`` from the ones before."""
    xs, ys = sorted(p[0] for p in points), sorted(p[1] for p in points)
    cx, cy = xs[len(xs) // 2], ys[len(ys) // 2]
    chosen: list[list[float]] = []
    for p in sorted(points, key=lambda p: math.hypot(p[0] - cx, p[1] - cy)):
        if all(math.hypot(p[0] - q[0], p[1] - q[1]) >= spacing for q in chosen):
            chosen.append(p)
        if len(chosen) == n:
            return chosen
    raise AssertionError(f"fewer than {n} street points {spacing} m apart")


def import_helsinki(pg: Page) -> None:
    pg.set_input_files("#upload-geojson", str(HELSINKI / "helsinki.geojson"))
    expect(pg.locator("#import-summary")).to_be_visible(timeout=WAIT_MS)


SUBMIT_TOP_PX = 1600
"""At a 1280 × 800 window with a site loaded, Submit and the first parameter (the RIS counts)
start at most this far down the page: reachable without scrolling past the map or the lists."""


def in_reach(pg: Page, selector: str) -> float:
    """The top of an element in page coordinates (its box plus the scroll)."""
    box = pg.locator(selector).bounding_box()
    assert box is not None, selector
    top: float = box["y"] + pg.evaluate("window.scrollY")
    return top


def test_plan_a_real_site_end_to_end(page: tuple[Page, Console], server: str, shots: Shots) -> None:
    pg, console = page
    console.allow(r"status of 422")  # validation before the candidates are placed
    open_planner(pg, server)
    # the import options show the import's documented defaults
    assert pg.input_value("#imp-default_height") == "10"
    assert pg.input_value("#imp-ue_height") == "1.5"
    import_helsinki(pg)
    report = pg.locator("#import-report")
    expect(report.locator("tr", has_text="Buildings").first).to_contain_text("29")
    expect(report.locator("tr", has_text="Road pieces (UE positions)")).to_contain_text("120")
    expect(report.locator("tr", has_text="Default pairs")).to_contain_text(
        '{"sample":1000,"seed":1'  # and the pair model where the import writes one
    )
    assert "{'" not in report.inner_text()  # JSON text, never Python's dict repr
    # the file's road classes, all chosen; the site drawn without candidates yet
    classes = pg.locator("#road-classes input.road-class")
    assert sorted(classes.evaluate_all("els => els.map(e => e.value)")) == [
        "footway",
        "residential",
        "service",
    ]
    expect(pg.locator("path.prism")).to_have_count(29)
    expect(pg.locator("#import-summary")).to_contain_text("29 buildings, 120 road pieces")
    expect(pg.locator("#import-details")).not_to_have_attribute("open", "")  # on request
    expect(pg.locator("#validation-status")).to_contain_text("No candidate sites yet")
    # no red refusal for the candidates nobody could have placed yet
    expect(pg.locator("#other-errors")).to_be_empty()
    # Submit and the parameters within reach at 1280 × 800, the site loaded
    pg.set_viewport_size({"width": 1280, "height": 800})
    assert in_reach(pg, "#submit") <= SUBMIT_TOP_PX
    assert in_reach(pg, "#f-ris_count") <= SUBMIT_TOP_PX
    pg.set_viewport_size({"width": 1280, "height": 900})
    all_points = pg.evaluate("window.risPlanner.state.sitePreview.rx_map.total")
    first = pg.evaluate("window.risPlanner.state.doc")
    # import again: residential streets only, UEs at 2 m, the default building height 12 m (the
    # options fold away once a file is imported: opened on request)
    pg.click("#import-options summary")
    set_box(pg, "#road-footway", False)
    set_box(pg, "#road-service", False)
    pg.fill("#imp-ue_height", "2")
    pg.fill("#imp-default_height", "12")
    pg.fill("#imp-origin", "24.949, 60.1655")
    pg.click("#reimport")
    expect(report.locator("tr", has_text="Road pieces skipped")).to_contain_text(
        "footway (not chosen): 47", timeout=WAIT_MS
    )
    # asked to plan without candidates, the page says why in red (the server's refusal)
    pg.click("#submit")
    expect(pg.locator("#other-errors")).to_contain_text("no candidate sites", timeout=WAIT_MS)
    expect(pg.locator("#validation-status")).to_contain_text("Not submitted")
    doc = pg.evaluate("window.risPlanner.state.doc")
    assert doc["frame"]["origin"][:2] == [24.949, 60.1655]
    assert {r["height_m"] for r in doc["tx_map"]["roads"]} == {2.0}
    heights = [
        (a["height_m"], b["height_m"])
        for a, b in zip(
            first["environment"]["obstacles"], doc["environment"]["obstacles"], strict=True
        )
        if a != b
    ]
    assert heights == [(10, 12)] * 16  # the 16 buildings without height or levels
    assert drawn_ues_of(pg, "sitePreview") > 0
    points = pg.evaluate("window.risPlanner.state.sitePreview.rx_map.points")
    assert 0 < len(points) < all_points
    shots.take(pg, "planner-01-imported")

    # place three candidates on street points, drag one, turn one, add and remove a fourth
    spots = spread_near_centre(points, 4, SPOT_SPACING_M)
    set_box(pg, "#mode-add")
    for k, (x, y, _) in enumerate(spots[:3]):
        pg.mouse.click(*screen_of(pg, x, y))
        expect(pg.locator("#cand-summary")).to_contain_text(f"Added candidate {k}")
    cands = pg.evaluate("window.risPlanner.state.cands")
    k_px = pg.evaluate("window.risPlanner.pxPerMetre()")
    for c, (x, y, _) in zip(cands, spots[:3], strict=True):
        assert math.hypot(c["position"][0] - x, c["position"][1] - y) <= PX_TOL / k_px
        assert c["position"][2] == CandidateOptions().heights_m[0]  # the first generation height
    expect(pg.locator("#validation-status")).to_contain_text(
        "Valid: 3 candidate sites", timeout=WAIT_MS
    )
    # a drag moves a site in "read a point" mode; unsnapped it lands where it is dropped (the
    # snapping to facades: tests/test_web_map.py), renamed: its old name no longer says where
    set_box(pg, "#mode-inspect")
    set_box(pg, "#snap-facades", False)
    target = spots[3]
    start = screen_of(pg, *cands[0]["position"][:2])
    end = screen_of(pg, *target[:2])
    pg.mouse.move(*start)
    pg.mouse.down()
    pg.mouse.move(*end, steps=8)
    pg.mouse.up()
    expect(pg.locator("#cand-summary")).to_contain_text("Moved candidate 0")
    moved = pg.evaluate("window.risPlanner.state.cands[0]")
    assert math.hypot(moved["position"][0] - target[0], moved["position"][1] - target[1]) <= (
        PX_TOL / k_px
    )
    assert moved["name"] == "added 1 (moved)"
    assert pg.evaluate("window.risPlanner.state.cands.length") == 3  # a drag adds nothing
    set_box(pg, "#snap-facades")
    # select candidate 1 and turn it 15° clockwise (azimuth +15°, yaw −15°)
    pg.mouse.click(*screen_of(pg, *cands[1]["position"][:2]))
    expect(pg.locator("#cand-editor-title")).to_contain_text("Candidate 1")
    before = float(pg.input_value("#ce-azimuth"))
    pg.click("#ce-right")
    yaw = pg.evaluate("window.risPlanner.state.cands[1].orientation[0]")
    turned = (yaw - cands[1]["orientation"][0] + math.pi) % (2 * math.pi) - math.pi
    assert turned == pytest.approx(-math.radians(15), abs=1e-12)
    shown = float(pg.input_value("#ce-azimuth"))  # 0.1° steps: two roundings of ≤ 0.05°
    assert (shown - before - 15 + 180) % 360 - 180 == pytest.approx(0, abs=0.1 + 1e-9)
    pg.fill("#ce-tilt", "20")
    pg.press("#ce-tilt", "Enter")
    pitch = pg.evaluate("window.risPlanner.state.cands[1].orientation[1]")
    assert pitch == pytest.approx(math.radians(20), rel=1e-12)
    set_box(pg, "#mode-add")
    x4, y4 = screen_of(pg, *points[len(points) // 2][:2])
    pg.mouse.click(x4 + 30, y4)
    expect(pg.locator("#cand-summary")).to_contain_text("Added candidate 3")
    pg.click("#ce-remove")
    expect(pg.locator("#cand-summary")).to_contain_text("Removed added 4")
    assert pg.evaluate("window.risPlanner.state.cands.length") == 3
    expect(pg.locator("#candidates .site.editable")).to_have_count(3)
    # without a mouse: the sites table's Edit buttons select a candidate for the editor
    pg.click("#sites-details summary")
    pg.get_by_role("button", name="Edit candidate 2").click()
    expect(pg.locator("#cand-editor-title")).to_contain_text("Candidate 2")
    expect(pg.locator("#ce-azimuth")).to_be_focused()
    set_box(pg, "#mode-inspect")
    # the removal's automatic validation ends (status text, redraw) before the form is used: a
    # layout change under a click made the clock checkbox miss it on a busy machine
    settle(pg)

    # parameters: a small, fast plan
    pg.fill("#f-ris_count", "1, 2")
    pg.fill("#f-ris-rows", "4")
    pg.fill("#f-ris-cols", "4")
    pg.fill("#f-objective-level", "5")
    pg.select_option("#f-pairs-mode", "sample")
    pg.fill("#f-pairs-sample", "200")
    set_box(pg, "#f-known-clock")
    expect(pg.locator("#f-known-height")).to_be_checked()  # the import's default
    pg.click("#validate")
    expect(pg.locator("#validation-status")).to_contain_text(
        "3 candidate sites, 200 TX–RX pairs", timeout=WAIT_MS
    )
    shots.take(pg, "planner-02-candidates-edited")
    pg.click("#submit")
    expect(pg.locator("#progress-text")).to_have_text("100 %", timeout=JOB_WAIT_MS)
    expect(pg.locator("#heatmap-image")).to_be_attached(timeout=WAIT_MS)
    job_id = pg.evaluate("window.risPlanner.state.job.id")
    view = httpx.get(f"{server}/v1/jobs/{job_id}", timeout=HANG_S).json()
    request = view["request"]
    assert request["known"] == ["clock", "height"]
    # the sample size from the form, the rest of the pairs (seed, pair model) the import's
    assert request["pairs"]["sample"] == 200
    assert {k: request["pairs"][k] for k in doc["pairs"] if k != "sample"} == {
        k: v for k, v in doc["pairs"].items() if k != "sample"
    }
    assert (request["ris"]["rows"], request["ris"]["cols"]) == (4, 4)
    assert request["ris_count"] == [1, 2]
    assert request["objective"]["threshold_m"] == 5
    # the edited candidates, in the document's frame: back to local metres they are the list
    edited = pg.evaluate("window.risPlanner.state.cands")
    back = httpx.post(
        f"{server}/v1/candidates/convert",
        json={"frame": request["frame"], "document": request["candidates"]},
        timeout=HANG_S,
    ).json()["local"]
    for got, want in zip(back, edited, strict=True):
        assert math.dist(got["position"], want["position"]) <= 1e-6  # PROJ round trip
        assert got["orientation"] == want["orientation"]
    plan = view["result"]
    assert len(plan["candidates"]) == 3
    # counts table, colour bar with units and the threshold, legend; UE dots off over the heatmap
    expect(pg.locator("#count-table tbody tr")).to_have_count(2)
    assert plan["by_count"][1]["blind_fraction"] < 1  # finite bounds: a colour bar to show
    bar = pg.locator("#colourbar")
    expect(bar).to_contain_text("[m]")
    expect(bar).to_contain_text("threshold")
    legend = pg.locator("#legend")
    for text in ("building", "candidate site", "RIS site of the layout shown", "contour at"):
        expect(legend).to_contain_text(text)
    expect(pg.locator("#layer-ues")).not_to_be_checked()
    assert drawn_ue_points(pg) == 0
    set_box(pg, "#layer-ues")  # on request: small, translucent, above the heatmap
    assert drawn_ue_points(pg) > 0
    expect(legend).to_contain_text("UE points")
    set_box(pg, "#layer-buildings", False)
    expect(pg.locator("path.prism")).to_have_count(0)
    set_box(pg, "#layer-buildings")
    set_box(pg, "#layer-ues", False)
    shots.take(pg, "planner-03-results")

    # exports: plan.json, plan.geojson (the job's file) and the candidates as a sites file
    links = pg.locator("#downloads a")
    with pg.expect_download() as dl:
        links.first.click()
    assert json.loads(Path(dl.value.path()).read_text())["by_count"] == plan["by_count"]
    gj = pg.locator(f"#downloads a[href='{view['figures']['geojson']}']")
    assert gj.get_attribute("download") == f"plan-{job_id[:8]}.geojson"
    # its name and what it holds are the writers' registry's (GET /v1/plan-files)
    registry = httpx.get(f"{server}/v1/plan-files", timeout=HANG_S).json()["files"]
    geo = next(f for f in registry if f["name"] == "geojson")
    geo_link = pg.locator(f"a[href='{view['figures']['geojson']}']")
    expect(pg.locator("#downloads li", has=geo_link)).to_contain_text(
        f"{geo['filename']} – {geo['description']}"
    )
    assert (
        httpx.get(server + view["figures"]["geojson"], timeout=HANG_S).json()["type"]
        == "FeatureCollection"
    )
    cand_link = pg.locator("#dl-candidates")
    expect(cand_link).to_be_visible(timeout=WAIT_MS)
    with pg.expect_download() as dl:
        cand_link.click()
    sites = json.loads(Path(dl.value.path()).read_text())
    assert len(sites["features"]) == 3
    assert all("role" not in f["properties"] for f in sites["features"])
    # the file ris-planner sites writes (one function): frame and licence at the top, so its
    # import centres where the plan's frame is
    assert "ris_planner_frame" not in sites and sites["frame"]["origin"] == plan["frame"]["origin"]
    assert sites["license"] == request["license"]
    want = candidates_geojson(
        Frame(tuple(plan["frame"]["origin"])), plan["candidates"], {"license": request["license"]}
    )
    same_candidates_file(sites, json.loads(json.dumps(want)), "the page's candidates.geojson")
    # a sites file the import reads back as the same candidates
    again = httpx.post(
        f"{server}/v1/candidates/convert",
        json={"frame": {"origin": plan["frame"]["origin"]}, "sites": sites},
        timeout=HANG_S,
    ).json()["local"]
    for got, want in zip(again, edited, strict=True):
        assert math.dist(got["position"], want["position"]) <= EXPORT_ROUNDING_M
        yaw = (got["orientation"][0] - want["orientation"][0] + math.pi) % (2 * math.pi)
        assert yaw - math.pi == pytest.approx(0, abs=1e-9)

    # a diagnosis and a sizing answer (plan.json keys), rendered from the job's view
    diagnosis = {
        "verdict": "weak",
        "causes": [
            {
                "kind": "link_budget",
                "message": "the RIS is too small for these distances",
                "suggested_ris_size": [16, 16],
            },
            {"kind": "geometry", "message": "the sites see the street from one side"},
            {  # hundreds of candidates: counted in the message, listed on request
                "kind": "blocked",
                "message": "143 of 146 candidates serve no pair, so they cannot help this plan:"
                " 143 see no UE point (e.g. 0 (B0-f0-0-h4), 1 (B1-f0-0-h4), 2 (B2-f0-0-h4), …)",
                "no_visible_point": 143,
                "candidates": [
                    {"index": i, "name": f"B{i}-f0-0-h4", "reason": "no_visible_point"}
                    for i in range(143)
                ],
            },
        ],
        "floor": 0.2,
        "best": 0.4,
        "worst": 0.1,
    }
    servable = plan["pairs_summary"]["servable_weight"]
    sizing = {  # plan.json sizing (one shape for every search: search.sizing.SizeRow)
        "target": {"min": 0.9},
        "of": "servable pairs",
        "goal": {"min": 0.9 * servable},
        "servable_weight": servable,
        "sizes": [
            {
                "ris_size": [4, 4],
                "count": None,
                "lower_bound": None,
                "objective": None,
                "sites": None,
                "note": "no searched count reaches it",
                "counts": [
                    {"count": 2, "objective": 0.5, "reaches": False, "objective_bound": 0.5}
                ],
            },
            {
                "ris_size": [8, 8],
                "count": 2,
                "lower_bound": 1,
                "objective": 0.9,
                "sites": [0, 2],
                "note": None,
                "counts": [{"count": 2, "objective": 0.9, "reaches": True, "objective_bound": 0.9}],
            },
        ],
        "search_method": {
            "requested": "auto",
            "used": "district",
            "why": "the enumerating search does not fit at 8×8 (a rendering test's answer)",
        },
        "answer": {
            "ris_size": [8, 8],
            "count": 2,
            "lower_bound": 1,
            "gap": 1,
            "gap_share": 0.5,
            "elements": 128,
            "objective": 0.9,
            "sites": [0, 2],
        },
        "message": "between 1 and 2 RISs of 8×8 reach 90 % of the servable pairs",
    }
    search = {  # the plan's search as auto resolved it (plan.json search_method)
        "requested": "auto",
        "used": "district",
        "why": "the layouts of 2 RISs do not fit (a rendering test's answer)",
    }

    validation = {  # plan.json validation (ris_planner.planning.outputs.estimator_check)
        "pairs": 10,
        "draws": 5,
        "threshold_m": 0.5,
        "multipath": False,
        "reflections": False,
        "codebook": {"kind": "designed", "names": ["dir_der_sdp"]},
        "layouts": [
            {
                "ris_count": 2,
                "sites": [0, 3],
                "estimator_coverage": 0.4,
                "bound_coverage": 0.8,
                "shortfall": {"count": 3, "covered_pairs": 8, "by_cause": {"ghost": 3}},
                "outliers": {"ghost": 7, "threshold_snr": 0},
            }
        ],
    }

    def with_keys(route: Any) -> None:
        answer = route.fetch()
        body = answer.json()
        body["result"] |= {
            "diagnosis": diagnosis,
            "sizing": sizing,
            "validation": validation,
            "search_method": search,
        }
        route.fulfill(response=answer, json=body)

    pg.route(f"**/v1/jobs/{job_id}", with_keys)
    pg.locator(f"#jobs-body tr[data-job='{job_id}'] button").click()
    box = pg.locator("#diagnosis")
    expect(box).to_be_visible(timeout=WAIT_MS)
    expect(box).to_have_attribute("data-verdict", "weak")
    expect(box).to_have_attribute("role", "alert")
    expect(box).to_contain_text("Warning: the plan is weak")
    expect(box).to_contain_text("link_budget: the RIS is too small")
    blocked = box.locator("li[data-kind='blocked']")
    expect(blocked).to_contain_text("143 of 146 candidates serve no pair")
    expect(blocked.locator("details summary")).to_have_text("The 143 candidates (list)")
    # the names once, in the message's examples; the list collapsed until asked for
    assert blocked.inner_text().count("B2-f0-0-h4") == 1
    assert "B142-f0-0-h4" not in blocked.inner_text()
    with pg.expect_download() as dl:
        blocked.locator("summary").click()
        blocked.locator("a.cause-download").click()
    rows = Path(dl.value.path()).read_text().splitlines()
    assert rows[0] == "index,name,reason" and len(rows) == 144
    assert rows[-1] == "142,B142-f0-0-h4,no_visible_point"
    expect(blocked.locator("ul.cause-list li")).to_have_count(143)
    # the sizing in plain words (the server's message), its certified interval, the sizes
    # tried, the search that answered it and why
    expect(pg.locator("#sizing-answer")).to_contain_text(sizing["message"])
    expect(pg.locator("#sizing-interval")).to_have_text(
        "Certified interval: 1 to 2 RISs of 8 × 8 elements – no layout of fewer than 1 RIS"
        " reaches the target (certified), the search found one of 2 (gap 1 RIS)."
    )
    expect(pg.locator("#sizing-target")).to_contain_text("at least 90.0 % of the servable pairs")
    expect(pg.locator("#sizing-table tbody tr")).to_have_count(2)
    expect(pg.locator("#sizing-table tr.answer td").first).to_have_text("8 × 8")
    expect(pg.locator("#sizing-table tr.answer td.lower")).to_have_text("1")
    methods = httpx.get(f"{server}/v1/search-methods", timeout=HANG_S).json()
    label = next(m["label"] for m in methods["methods"] if m["name"] == "district")
    expect(pg.locator("#sizing-search")).to_contain_text(f"the {label} search")
    # the plan's own search, auto resolved: one line with the reason
    expect(pg.locator("#search-why")).to_have_text(
        f"auto chose the {label} search: {search['why']}."
    )
    row = pg.locator("#estimator-check-table tbody tr")
    expect(row).to_have_count(1)
    expect(row).to_contain_text("40 %")
    expect(row).to_contain_text("80 %")
    expect(row).to_contain_text("3 of 8 (ghost 3)")
    expect(row).to_contain_text(f"{plan['candidates'][0]['name']} [0]")  # by name and index
    expect(pg.locator("#estimator-check")).to_contain_text("designed beams (dir der sdp)")
    assert undeclared_percentages(pg) == []  # every share with its denominator
    shots.take(pg, "planner-04-diagnosis-sizing")
    box.get_by_role("button", name="Use 16 × 16 elements").click()
    assert (pg.input_value("#f-ris-rows"), pg.input_value("#f-ris-cols")) == ("16", "16")
    pg.unroute(f"**/v1/jobs/{job_id}")
    # the sizing control: the plan document with "sizing": {} where the server knows it
    spec = httpx.get(f"{server}/openapi.json", timeout=HANG_S).json()
    if "sizing" in spec["components"]["schemas"]["PlanDocument"]["properties"]:
        expect(pg.locator("#find-size")).to_be_enabled()
        pg.click("#find-size")
        pg.wait_for_function(
            "(id) => window.risPlanner.state.job && window.risPlanner.state.job.id !== id",
            arg=job_id,
            timeout=WAIT_MS,
        )
        sized = pg.evaluate("window.risPlanner.state.job.id")
        expect(pg.locator("#job-status")).to_contain_text("succeeded", timeout=JOB_WAIT_MS)
        assert (
            httpx.get(f"{server}/v1/jobs/{sized}", timeout=HANG_S).json()["request"]["sizing"] == {}
        )
        expect(pg.locator("#sizing")).to_be_visible(timeout=WAIT_MS)
    else:
        expect(pg.locator("#find-size")).to_be_disabled()
        expect(pg.locator("#hint-find-size")).to_contain_text("cannot size the RIS yet")
    no_horizontal_scroll(pg)
    assert unlabelled_controls(pg) == []
    assert low_contrast_text(pg) == []


def test_api_key_banner_follows_the_server(browser: Browser, tmp_path: Path, shots: Shots) -> None:
    """Without a key the banner asks for one; a wrong key keeps it; the right key hides it
    (and loads what the 401s refused); a later 401 (a wrong key again) shows it again."""
    context = browser.new_context(viewport={"width": 1280, "height": 900})
    context.set_default_timeout(WAIT_MS)
    pg = context.new_page()
    console = Console(pg)
    console.allow(r"status of 401")
    env = {"RIS_PLANNER_API_KEY": "zebra-secret"}
    try:
        with served(tmp_path / "jobs.db", workers=1, env=env) as srv:
            pg.goto(srv.url + "/")
            banner = pg.locator("#banner")
            expect(banner).to_be_visible(timeout=WAIT_MS)
            expect(pg.locator("#banner-text")).to_contain_text("needs an API key")
            pg.click("summary:has-text('Server API key')")
            pg.fill("#api-key", "wrong")
            pg.click("#api-key-form button[type='submit']")
            expect(pg.locator("#api-key-status")).to_contain_text("refused", timeout=WAIT_MS)
            expect(banner).to_be_visible()
            shots.take(pg, "planner-05-key-needed", full_page=False)
            pg.fill("#api-key", "zebra-secret")
            pg.click("#api-key-form button[type='submit']")
            expect(pg.locator("#api-key-status")).to_have_text(
                "Key accepted by the server.", timeout=WAIT_MS
            )
            expect(banner).to_be_hidden()
            expect(pg.locator("#preset option[value='fig10-anchors']")).to_be_attached()
            pg.fill("#api-key", "stale")
            pg.click("#api-key-form button[type='submit']")
            expect(banner).to_be_visible(timeout=WAIT_MS)
            expect(pg.locator("#banner-text")).to_contain_text("needs an API key")
        assert console.unexpected() == []
    finally:
        context.close()


def test_generate_candidates_from_the_site(
    page: tuple[Page, Console], server: str, shots: Shots
) -> None:
    """POST /v1/sites (facades and poles of the imported site) → candidates on the map: the form
    starts from the defaults of ``ris-planner sites``, the list downloads as the file the
    command line writes; a site dragged into a building turns red, is named, and Submit says
    why it refuses."""
    probe = httpx.post(f"{server}/v1/sites", json={}, timeout=HANG_S)
    if probe.status_code == 404:
        pytest.skip("this server has no POST /v1/sites yet (candidate generation is being added)")
    pg, console = page
    console.allow(r"status of 422")
    open_planner(pg, server)
    # the generation form: the defaults of ris-planner sites (one model holds them)
    d = CandidateOptions()
    expect(pg.locator("#gen-spacing")).to_have_value(f"{d.spacing_m:g}")
    expect(pg.locator("#gen-heights")).to_have_value(", ".join(f"{h:g}" for h in d.heights_m))
    for kind in ("facade", "pole"):
        assert pg.is_checked(f"#gen-kind-{kind}") == (kind in d.kinds)
    import_helsinki(pg)
    expect(pg.locator("#generate")).to_be_enabled()
    pg.fill("#gen-spacing", "30")
    pg.fill("#gen-heights", "6")
    pg.click("#generate")
    expect(pg.locator("#cand-summary")).to_contain_text("Generated", timeout=WAIT_MS)
    n = pg.evaluate("window.risPlanner.state.cands.length")
    assert n > 0
    expect(pg.locator("#candidates .site.editable")).to_have_count(n)
    expect(pg.locator("#validation-status")).to_contain_text(
        f"Valid: {n} candidate sites", timeout=WAIT_MS
    )
    shots.take(pg, "planner-06-generated")
    # the list as a file: what POST /v1/sites (ris-planner sites) answers for these options
    options = {"spacing_m": 30, "heights_m": [6], "kinds": ["facade", "pole"]}
    site = json.loads((HELSINKI / "helsinki.geojson").read_text())
    want = httpx.post(
        f"{server}/v1/sites", json={"site": site, "options": options}, timeout=HANG_S
    ).json()
    summary = want.pop("summary")
    # what the generation did, readable: the sites kept per kind, those dropped and why, the
    # UE points in the kept sites' field of view, the warnings as a list
    kinds = ", ".join(f"{n} {k}" for k, n in summary["by_kind"].items())
    expect(pg.locator("#gen-kept")).to_have_text(f"{summary['candidates']} sites kept: {kinds}.")
    expect(pg.locator("#gen-dropped")).to_contain_text(
        f"{summary['dropped_unseen']} seeing no UE point in their field of view"
    )
    sees = sorted(f["properties"]["sees_points"] for f in want["features"])
    expect(pg.locator("#gen-view")).to_contain_text(
        f"each kept site sees {sees[0]} to {sees[-1]} of the site's"
        f" {summary['ue_points']} UE points"
    )
    warnings = len(summary["buildings_without_candidates"]) + len(summary["notes"])
    expect(pg.locator("#gen-warnings li")).to_have_count(warnings)
    assert "{" not in pg.locator("#gen-summary").inner_text()  # no raw dump
    with pg.expect_download() as dl:
        pg.click("#download-candidates")
    assert dl.value.suggested_filename == "candidates.geojson"
    got = json.loads(Path(dl.value.path()).read_text())
    same_candidates_file(got, want, "the page's candidates.geojson")

    # drag a candidate into a tall building: red on the map, named, and Submit refuses it
    shapely_geometry = pytest.importorskip("shapely.geometry")
    obstacles = pg.evaluate("window.risPlanner.state.preview.obstacles")
    k = next(i for i, ob in enumerate(obstacles) if ob["height_m"] > 7)
    inner = shapely_geometry.Polygon(obstacles[k]["footprint"]).representative_point()
    pg.locator("#map").scroll_into_view_if_needed()
    set_box(pg, "#snap-facades", False)  # placed where dropped, not snapped out to a facade
    first = pg.evaluate("window.risPlanner.state.cands[0]")
    pg.mouse.move(*screen_of(pg, *first["position"][:2]))
    pg.mouse.down()
    pg.mouse.move(*screen_of(pg, inner.x, inner.y), steps=8)
    pg.mouse.up()
    expect(pg.locator("#cand-summary")).to_contain_text("Moved candidate")
    cands = pg.evaluate("window.risPlanner.state.cands")
    moved = min(
        range(len(cands)),
        key=lambda i: math.hypot(
            cands[i]["position"][0] - inner.x, cands[i]["position"][1] - inner.y
        ),
    )
    expect(pg.locator("#candidates .site.inside")).to_have_count(1)
    inside = pg.locator(f"#candidates .site.inside[data-site='{moved}']")
    assert inside.locator("rect").get_attribute("fill") == "#c62828"
    note = pg.locator("#cand-inside")
    expect(note).to_be_visible()
    name = cands[moved]["name"]
    assert name.endswith(" (moved)")  # a generated facade's name would lie
    building = obstacles[k]["name"] or f"obstacle {k}"
    expect(note).to_contain_text(
        f"1 candidate lies inside a building (red on the map): {name} [{moved}] in {building}"
    )
    expect(pg.locator("#legend")).to_contain_text("candidate inside a building")
    jobs_before = httpx.get(f"{server}/v1/jobs", timeout=HANG_S).json()
    pg.click("#submit")
    status = pg.locator("#validation-status")
    expect(status).to_contain_text(
        "Not submitted: 1 candidate site lies inside a building", timeout=WAIT_MS
    )
    problems = pg.locator("#other-errors")  # the whole message: each site where the document has it
    expect(problems).to_contain_text(f"candidate {moved} ({name}) at [lon, lat, h] = [")
    expect(problems).to_contain_text(f"inside environment obstacle {k} (")
    assert httpx.get(f"{server}/v1/jobs", timeout=HANG_S).json() == jobs_before  # nothing queued
    shots.take(pg, "planner-08-inside-a-building")
    # the moved site is no longer the generated one: the file keeps its pose, not what the
    # generator said of it
    with pg.expect_download() as dl:
        pg.click("#download-candidates")
    props = json.loads(Path(dl.value.path()).read_text())["features"][moved]["properties"]
    assert props["name"] == name and "sees_points" not in props and "kind" not in props
    # removed, the list is plannable again and nothing is red
    pg.mouse.click(*screen_of(pg, *cands[moved]["position"][:2]))
    expect(pg.locator("#cand-editor-title")).to_contain_text(f"Candidate {moved}")
    pg.click("#ce-remove")
    expect(note).to_be_hidden()
    expect(pg.locator("#candidates .site.inside")).to_have_count(0)
    expect(pg.locator("#validation-status")).to_contain_text(
        f"Valid: {n - 1} candidate sites", timeout=WAIT_MS
    )


def test_a_swapped_file_and_the_swap_check(
    page: tuple[Page, Console], server: str, tmp_path: Path
) -> None:
    """A file whose positions are [lat, lon]: the import refuses it saying to turn the swap
    check off, the page points at its control for that, and with it off the import and the
    generation go through."""
    from test_api_sites import swapped

    pg, console = page
    console.allow(r"status of 422")
    open_planner(pg, server)
    path = tmp_path / "swapped.geojson"
    path.write_text(json.dumps(swapped(json.loads((HELSINKI / "helsinki.geojson").read_text()))))
    expect(pg.locator("#imp-swap_check")).to_be_checked()
    pg.set_input_files("#upload-geojson", str(path))
    err = pg.locator("#err-upload-geojson")
    expect(err).to_contain_text("turn the swap check off", timeout=WAIT_MS)
    expect(err).to_contain_text("untick “Lat/lon swap check” under Import options")
    set_box(pg, "#imp-swap_check", False)  # (a refused file leaves the options open)
    pg.click("#reimport")
    expect(pg.locator("#import-summary")).to_be_visible(timeout=WAIT_MS)
    expect(err).to_be_empty()
    pg.fill("#gen-spacing", "30")
    pg.click("#generate")
    expect(pg.locator("#cand-summary")).to_contain_text("Generated", timeout=WAIT_MS)
    expect(pg.locator("#err-gen")).to_be_empty()


def test_real_osm_cut_through_the_page(
    page: tuple[Page, Console], server: str, shots: Shots
) -> None:
    """The real-site chain of tests/test_real_site_e2e.py through the page: upload the OSM cut,
    generate candidates with the page's defaults, plan with the import's defaults (a 200-pair
    sample and 60 candidates for the test's time), read the diagnosis; no candidate and no
    scored UE point inside a building, the licence in the export."""
    from test_real_site_e2e import LICENSE, MAX_CANDIDATES, PAIRS, SITE, check_plan

    pg, console = page
    console.allow(r"status of 422")  # validation before the candidates are placed
    open_planner(pg, server)
    pg.set_input_files("#upload-geojson", str(SITE))
    expect(pg.locator("#import-summary")).to_be_visible(timeout=WAIT_MS)
    report = pg.locator("#import-report")
    expect(report.locator("tr", has_text="Buildings").first).to_contain_text("45")
    pg.click("#generate")
    expect(pg.locator("#cand-summary")).to_contain_text("Generated", timeout=WAIT_MS)
    n = pg.evaluate("window.risPlanner.state.cands.length")
    assert n > 0
    # keep the first MAX_CANDIDATES (the test's time), as a planner prunes a long list
    pg.evaluate(f"window.risPlanner.state.cands.splice({MAX_CANDIDATES})")
    pg.select_option("#f-pairs-mode", "sample")
    pg.fill("#f-pairs-sample", str(PAIRS))
    pg.click("#validate")
    expect(pg.locator("#validation-status")).to_contain_text(
        f"{min(n, MAX_CANDIDATES)} candidate sites, {PAIRS} TX–RX pairs", timeout=WAIT_MS
    )
    pg.click("#submit")
    expect(pg.locator("#progress-text")).to_have_text("100 %", timeout=JOB_WAIT_MS)
    expect(pg.locator("#diagnosis")).to_be_visible(timeout=WAIT_MS)
    shots.take(pg, "planner-07-real-osm-cut")
    job_id = pg.evaluate("window.risPlanner.state.job.id")
    view = httpx.get(f"{server}/v1/jobs/{job_id}", timeout=HANG_S).json()
    assert view["status"] == "succeeded", view["error"]
    check_plan(view["request"], view["result"])
    geo = httpx.get(server + view["figures"]["geojson"], timeout=HANG_S).json()
    assert geo["license"] == LICENSE
    assert console.unexpected() == []
