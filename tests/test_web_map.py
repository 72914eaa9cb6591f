"""The planner page's map (Leaflet, vendored, in local metres) in headless Chromium against a
real uvicorn on 127.0.0.1 (the fixtures and helpers of ``test_web``): zoom and pan change the
view and Fit brings the site back; "add" mode adds exactly one site where clicked, also over a
crowd of sites; a dragged site snaps to the nearest facade, 5 cm in front of it and facing out,
and is renamed; UE points inside buildings are not drawn (the plan drops them) and are counted.
"""

# ruff: noqa: F811  (the fixtures of test_web, imported by name, are the tests' parameters)
from __future__ import annotations

import json
import math
from typing import Any

import httpx
import pytest
from test_web import (  # noqa: F401  (fixtures: browser, page, server, shots)
    WAIT_MS,
    Console,
    Page,
    Shots,
    browser,
    expect,
    map_info,
    open_page,
    page,
    screen_of,
    server,
    set_box,
    settle,
    shots,
)
from waits import HANG_MS, HANG_S

PX_TOL = 1.5
"""A site placed or dropped with the mouse lands within 1.5 screen pixels of the pointer (the
map rounds positions to whole pixels)."""

FACADE_OFFSET_M = 0.05
"""The generator's distance in front of a facade (POST /v1/sites offset_m default)."""

ROW = 40
"""Sites in the crowded row along the street: 0.5 m apart, closer than their glyphs."""


def block_doc(with_candidates: bool = True) -> dict[str, Any]:
    """A street between two 40 m × 16 m buildings (the north one's outline counter-clockwise,
    the south one's clockwise), a 2 m UE grid over everything – :data:`INSIDE` of its 961
    points inside the buildings – and a row of ``ROW`` sites 0.5 m apart along the street's
    middle."""
    prism = {"kind": "prism", "base_m": 0, "height_m": 10}
    north = [[-20, 5], [20, 5], [20, 21], [-20, 21]]
    south = [[-20, -5], [20, -5], [20, -21], [-20, -21]]
    grid = {"grid": {"x": [-30, 30, 2], "y": [-30, 30, 2], "z": [1.5, 1.5, 1]}}
    doc: dict[str, Any] = {
        "description": "two blocks and a crowded row of sites (browser test: the map)",
        "environment": {
            "obstacles": [
                {**prism, "name": "north", "footprint": north},
                {**prism, "name": "south", "footprint": south},
            ]
        },
        "tx_map": grid,
        "rx_map": grid,
        "pairs": {"sample": 200, "seed": 0},
        "objective": {"kind": "coverage", "metric": "rx", "threshold_m": 1.0},
        "ris_count": [1],
    }
    if with_candidates:
        doc["candidates"] = [
            {"position": [-10 + 0.5 * i, 0, 4], "orientation": [0, 0.17, 0], "name": f"C{i}"}
            for i in range(ROW)
        ]
    return doc


GRID = range(-30, 31, 2)
INSIDE = sum(-20 < x < 20 and 5 < abs(y) < 21 for x in GRID for y in GRID)
"""UE grid points more than 1 cm inside a building (those at x = ±20 lie on a wall)."""

ZOOM = 3
"""The map's zoom in the drag test: 2³ = 8 pixels per metre, so the snapping reach (48 px) is
6 m, less than the 8 m depth of the buildings' middles."""


def upload(pg: Page, doc: dict[str, Any], name: str = "blocks.json") -> None:
    buffer = json.dumps(doc).encode()
    files = [{"name": name, "mimeType": "application/json", "buffer": buffer}]
    pg.set_input_files("#upload", files=files)
    expect(pg.locator("#doc-name")).to_contain_text(name)
    pg.locator("#map").scroll_into_view_if_needed()


def zoomed_past(pg: Page, zoom: float) -> None:
    """Wait until the map's zoom is above ``zoom`` and its view has stopped changing (the zoom
    animation over: window.risPlanner.moving())."""
    pg.wait_for_function(
        "(z) => window.risPlanner.map.getZoom() > z && !window.risPlanner.moving()",
        arg=zoom,
        timeout=WAIT_MS,
    )


def view(pg: Page) -> dict[str, float]:
    got: dict[str, float] = pg.evaluate(
        "(() => { const m = window.risPlanner.map, c = m.getCenter();"
        " return {zoom: m.getZoom(), x: c.lng, y: c.lat, k: window.risPlanner.pxPerMetre()}; })()"
    )
    return got


def test_zoom_and_pan_change_the_view(
    page: tuple[Page, Console], server: str, shots: Shots
) -> None:
    pg, _ = page
    open_page(pg, server)
    upload(pg, block_doc())
    expect(pg.locator("#validation-status")).to_contain_text(
        "Valid: 40 candidate sites", timeout=WAIT_MS
    )
    expect(pg.locator("path.prism")).to_have_count(2)
    fitted = view(pg)
    corner = screen_of(pg, -20, 5)
    # the zoom control: one step in, the scale grows by its factor, the corner moves
    pg.click(".leaflet-control-zoom-in")
    zoomed_past(pg, fitted["zoom"])
    zoomed = view(pg)
    assert zoomed["k"] / fitted["k"] == pytest.approx(2 ** (zoomed["zoom"] - fitted["zoom"]))
    assert math.dist(screen_of(pg, -20, 5), corner) > 20
    # the mouse wheel over the map zooms further in
    box = pg.locator("#map").bounding_box()
    assert box is not None
    pg.mouse.move(box["x"] + box["width"] / 2, box["y"] + 60)
    pg.mouse.wheel(0, -240)
    zoomed_past(pg, zoomed["zoom"])
    # dragging the map (on no site) pans it: a fixed point follows the pointer
    before = view(pg)
    start = (box["x"] + 80, box["y"] + box["height"] - 60)
    seen = screen_of(pg, -20, 5)
    pg.mouse.move(*start)
    pg.mouse.down()
    pg.mouse.move(start[0] + 120, start[1] - 70, steps=10)
    pg.mouse.up()
    after = view(pg)
    assert after["zoom"] == before["zoom"]
    assert (after["x"] - before["x"], after["y"] - before["y"]) == (
        pytest.approx(-120 / before["k"], abs=PX_TOL / before["k"]),
        pytest.approx(-70 / before["k"], abs=PX_TOL / before["k"]),
    )
    moved = screen_of(pg, -20, 5)
    assert (moved[0] - seen[0], moved[1] - seen[1]) == (
        pytest.approx(120, abs=PX_TOL),
        pytest.approx(-70, abs=PX_TOL),
    )
    assert pg.evaluate("window.risPlanner.state.cands.length") == ROW  # panning adds nothing
    shots.take(pg, "map-01-zoomed-panned", full_page=False)
    # Fit brings the whole site back as it was first shown
    pg.click("#map-fit")
    back = view(pg)
    assert back["zoom"] == fitted["zoom"]
    assert math.dist(screen_of(pg, -20, 5), corner) < PX_TOL


def test_add_mode_adds_one_site_over_others(
    page: tuple[Page, Console], server: str, shots: Shots
) -> None:
    """The row's glyphs overlap at the fitted zoom: in "read a point" mode a click on one selects
    it; in "add" mode the same click adds exactly one site there, selecting none of the row."""
    pg, _ = page
    open_page(pg, server)
    upload(pg, block_doc())
    expect(pg.locator("#validation-status")).to_contain_text(
        "Valid: 40 candidate sites", timeout=WAIT_MS
    )
    expect(pg.locator("#candidates .site")).to_have_count(ROW)
    k = pg.evaluate("window.risPlanner.pxPerMetre()")
    assert 0.5 * k < 16  # neighbours closer than a glyph's pointer disc
    last = ROW - 1  # drawn on top of its neighbours
    x, y = -10 + 0.5 * last, 0.0
    pg.mouse.click(*screen_of(pg, x, y))
    expect(pg.locator("#cand-editor-title")).to_contain_text(f"Candidate {last} – C{last}")
    # the map names a site with its index, as the command line does
    title = pg.locator(f"#candidates .site[data-site='{last}'] title")
    expect(title).to_contain_text(f"Site C{last} [{last}]: x ")
    assert pg.evaluate("window.risPlanner.state.cands.length") == ROW
    set_box(pg, "#mode-add")
    pg.mouse.click(*screen_of(pg, x, y))
    expect(pg.locator("#cand-summary")).to_contain_text(f"Added candidate {ROW}")
    cands = pg.evaluate("window.risPlanner.state.cands")
    assert len(cands) == ROW + 1
    added = cands[-1]["position"]
    assert math.hypot(added[0] - x, added[1] - y) <= PX_TOL / k
    assert cands[last]["position"] == [x, y, 4]  # the site under the click is untouched
    assert pg.evaluate("window.risPlanner.state.selCand") == ROW
    expect(pg.locator("#candidates .site")).to_have_count(ROW + 1)
    # a click on an empty spot adds one more; a drag in "add" mode pans and adds nothing
    pg.mouse.click(*screen_of(pg, 0, -25))
    expect(pg.locator("#cand-summary")).to_contain_text(f"Added candidate {ROW + 1}")
    sx, sy = screen_of(pg, 0, 25)
    pg.mouse.move(sx, sy)
    pg.mouse.down()
    pg.mouse.move(sx + 60, sy + 30, steps=6)
    pg.mouse.up()
    assert pg.evaluate("window.risPlanner.state.cands.length") == ROW + 2
    expect(pg.locator("#validation-status")).to_contain_text(
        f"Valid: {ROW + 2} candidate sites", timeout=WAIT_MS
    )
    shots.take(pg, "map-02-added-over-sites", full_page=False)


def drag(pg: Page, src: tuple[float, float], dst: tuple[float, float]) -> None:
    settle(pg)
    x, y = screen_of(pg, *src)
    pg.mouse.move(x, y)
    # an editable site's marker is under the pointer (not the map, which would pan)
    pg.wait_for_function(
        "([x, y]) => { const e = document.elementFromPoint(x, y);"
        " return Boolean(e && e.closest('.leaflet-marker-icon.editable')); }",
        arg=[x, y],
        timeout=HANG_MS,
    )
    pg.mouse.down()
    pg.mouse.move(*screen_of(pg, *dst), steps=8)
    pg.mouse.up()


def test_dragged_site_snaps_to_a_facade(
    page: tuple[Page, Console], server: str, shots: Shots
) -> None:
    """Dropped 1 m off the north block's street facade, a site lands 5 cm in front of it facing
    south; dropped deep inside the south block (a clockwise outline) it comes out of the nearest
    facade facing north; each is renamed "<name> (moved)". Unticked, "snap to facades" leaves a
    site where it is dropped. The sites dragged are the row's last ones, drawn on top."""
    pg, _ = page
    open_page(pg, server)
    upload(pg, block_doc())
    expect(pg.locator("#validation-status")).to_contain_text(
        "Valid: 40 candidate sites", timeout=WAIT_MS
    )
    offset = pg.evaluate("window.risPlanner.state.facadeOffset")
    assert offset == FACADE_OFFSET_M  # the generator's, read from the OpenAPI schema
    pg.evaluate(f"window.risPlanner.map.setView([0, 0], {ZOOM}, {{animate: false}}) && null")
    k = pg.evaluate("window.risPlanner.pxPerMetre()")
    assert k == 2**ZOOM
    first, second, third = ROW - 1, ROW - 2, ROW - 3
    home = {i: (-10 + 0.5 * i, 0.0) for i in (first, second, third)}
    # 1 m (8 px, within reach) south of the north block's facade y = 5 (counter-clockwise)
    drag(pg, home[first], (3, 4))
    expect(pg.locator("#cand-summary")).to_contain_text(f"Moved candidate {first}")
    expect(pg.locator("#cand-summary")).to_contain_text("on the facade of north")
    c = pg.evaluate(f"window.risPlanner.state.cands[{first}]")
    assert c["position"][0] == pytest.approx(3, abs=PX_TOL / k)
    assert c["position"][1] == pytest.approx(5 - FACADE_OFFSET_M, abs=1e-9)
    assert c["position"][2] == 4
    assert c["orientation"][0] == pytest.approx(-math.pi / 2, abs=1e-12)  # facing south, out
    assert c["orientation"][1] == 0.17  # the tilt is kept
    assert c["name"] == f"C{first} (moved)"
    expect(pg.locator("#ce-azimuth")).to_have_value("180")
    # inside the south block, 7 m from its street facade y = −5 (56 px, beyond the reach) and
    # 9 m from its back: out through the nearest facade, facing north (a clockwise outline)
    drag(pg, home[second], (2, -12))
    expect(pg.locator("#cand-summary")).to_contain_text(f"Moved candidate {second}")
    c = pg.evaluate(f"window.risPlanner.state.cands[{second}]")
    assert c["position"][0] == pytest.approx(2, abs=PX_TOL / k)
    assert c["position"][1] == pytest.approx(-5 + FACADE_OFFSET_M, abs=1e-9)
    assert c["orientation"][0] == pytest.approx(math.pi / 2, abs=1e-12)
    assert c["name"] == f"C{second} (moved)"
    # moved again: the name says so once; 7 m (56 px) from every facade it stays where dropped
    drag(pg, tuple(c["position"][:2]), (0, -28))
    expect(pg.locator("#cand-summary")).to_contain_text("to x 0 m")
    c = pg.evaluate(f"window.risPlanner.state.cands[{second}]")
    assert math.hypot(c["position"][0], c["position"][1] + 28) <= PX_TOL / k
    assert c["name"] == f"C{second} (moved)"
    # snapping off: a site dropped 1 m off a facade stays there, renamed
    set_box(pg, "#snap-facades", False)
    drag(pg, home[third], (-3, 4))
    expect(pg.locator("#cand-summary")).to_contain_text(f"Moved candidate {third}")
    c = pg.evaluate(f"window.risPlanner.state.cands[{third}]")
    assert math.hypot(c["position"][0] + 3, c["position"][1] - 4) <= PX_TOL / k
    assert c["orientation"][0] == 0 and c["name"] == f"C{third} (moved)"
    expect(pg.locator("#validation-status")).to_contain_text(
        f"Valid: {ROW} candidate sites", timeout=WAIT_MS
    )
    expect(pg.locator("#candidates .site.inside")).to_have_count(0)
    shots.take(pg, "map-03-snapped", full_page=False)


def test_ue_points_inside_buildings_not_drawn(
    page: tuple[Page, Console], server: str, shots: Shots
) -> None:
    """Before candidates (the site preview lists every point) and after (the plan's preview lists
    the points it keeps), the map draws no UE point inside a building and the legend counts them
    as the plan drops them."""
    pg, console = page
    console.allow(r"status of 422")  # no candidates yet: validation refuses the document
    open_page(pg, server)
    upload(pg, block_doc(with_candidates=False), "no-sites.json")
    expect(pg.locator("#validation-status")).to_contain_text(
        "No candidate sites yet", timeout=WAIT_MS
    )
    pg.wait_for_function("() => window.risPlanner.mapInfo().ues.length > 0", timeout=WAIT_MS)
    (ue,) = map_info(pg)["ues"]
    assert (ue["listed"], ue["inside"], ue["drawn"]) == (961, INSIDE, 961 - INSIDE)
    legend = pg.locator("#legend")
    expect(legend).to_contain_text(f"{INSIDE} inside buildings not drawn – the plan drops them")
    shots.take(pg, "map-04-inside-points-site-preview", full_page=False)
    # with candidates the validation's preview has the plan's maps: the same points drawn
    upload(pg, block_doc(), "blocks.json")
    expect(pg.locator("#validation-status")).to_contain_text(
        "Valid: 40 candidate sites", timeout=WAIT_MS
    )
    preview = httpx.post(f"{server}/v1/plans/validate", json=block_doc(), timeout=HANG_S).json()
    assert preview["rx_points"] == 961 - INSIDE
    assert preview["dropped"] == {"tx": INSIDE, "rx": INSIDE}
    (ue,) = map_info(pg)["ues"]
    assert (ue["listed"], ue["inside"], ue["drawn"]) == (961 - INSIDE, 0, 961 - INSIDE)
    assert ue["droppedByPlan"] == INSIDE
    expect(legend).to_contain_text(f"{INSIDE} inside buildings not drawn")
    # off, the layer draws nothing and the legend still counts the dropped points
    set_box(pg, "#layer-ues", False)
    assert map_info(pg)["ues"][0]["drawn"] == 0
    expect(legend).to_contain_text(f"{INSIDE} inside buildings (dropped by the plan)")
