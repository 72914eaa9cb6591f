"""The planner page in a real headless Chromium (Debian's ``chromium`` driven by Playwright)
against a real uvicorn on 127.0.0.1: open a preset, edit it, submit, follow the progress to
100 %, see the layout, heatmap and contour, read a point's bound, switch counts, the table's
headers unbroken and its best sites by name, cancel a job, see validation errors next to their
fields, plan a district with sidelink pairs and a coverage target, the API docs offline, a
server that went down.

Screenshots go to a temporary folder, and to ``out/web/`` when ``RIS_PLANNER_SCREENSHOTS`` is
set. No console error is allowed except the browser's own line for an HTTP error response the
test provokes on purpose (a 422, a refused connection).
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx
import pytest
from waits import HANG_MS, HANG_S

from api.launch import served
from ris_planner.planning import plan_preset as plan_preset_doc

CHROMIUM = os.environ.get("RIS_PLANNER_CHROMIUM", "/usr/bin/chromium")
CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
INSTALL_HINT = (
    "the browser tests need Debian's Chromium at {path}: install it with"
    " `apt-get update && apt-get install -y chromium` (as root), or point"
    " RIS_PLANNER_CHROMIUM at a Chromium binary; and the playwright package"
    " (`pip install -e '.[dev]'`; never `playwright install`)"
)
WAIT_MS = HANG_MS
"""How long a page's wait for an element, a text or a job's end may last before it counts as a
hang (tests/waits.py): every wait of these tests is for an event, none for a fixed time."""

BOUND_DIGITS_RTOL = 5e-3
"""The page prints bounds with 3 significant digits: relative rounding ≤ 5e-3."""


def _browser_available() -> str | None:
    """None if Chromium and Playwright are there, else what to install."""
    problems = []
    if not (Path(CHROMIUM).is_file() and os.access(CHROMIUM, os.X_OK)):
        problems.append("chromium")
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        problems.append("playwright")
    return INSTALL_HINT.format(path=CHROMIUM) if problems else None


_MISSING = _browser_available()
if _MISSING is not None:
    if os.environ.get("CI") == "true":  # CI installs both (.ci/run): missing is a failure
        pytest.fail(_MISSING, pytrace=False)
    pytest.skip(_MISSING, allow_module_level=True)

from playwright.sync_api import Browser, ConsoleMessage, Page, expect, sync_playwright  # noqa: E402

expect.set_options(timeout=WAIT_MS)  # every expect(...) without its own timeout, too


def slow_plan_doc() -> dict[str, Any]:
    """A plan of many seconds (24 sites, C(24, 4) = 10626 layouts × 4000 pairs) to cancel."""
    cands = []
    for k in range(24):
        phi = 2 * math.pi * k / 24
        cands.append(
            {
                "position": [8 * math.cos(phi), 8 * math.sin(phi), 2.0 + (k % 3)],
                "orientation": [phi + math.pi, 0.4, 0.0],
            }
        )
    grid = {"grid": {"x": [-5, 5, 0.5], "y": [-5, 5, 0.5], "z": [0, 0, 1]}}
    return {
        "description": "slow ring (browser test: cancel)",
        "candidates": cands,
        "tx_map": grid,
        "rx_map": grid,
        "pairs": {"sample": 4000, "seed": 0},
        "objective": {"kind": "mean_capped", "metric": "rx", "cap_m": 1.0},
        "ris_count": [4],
    }


@dataclass
class Shots:
    """Screenshot folder(s): always a temporary one, ``out/web`` too when asked for."""

    folder: Path
    copy_to: Path | None
    taken: list[Path] = field(default_factory=list)

    def take(self, page: Page, name: str, full_page: bool = True) -> Path:
        path = self.folder / f"{name}.png"
        page.screenshot(path=str(path), full_page=full_page)
        self.taken.append(path)
        if self.copy_to is not None:
            self.copy_to.mkdir(parents=True, exist_ok=True)
            shutil.copy(path, self.copy_to / path.name)
        return path


@pytest.fixture(scope="module")
def shots(tmp_path_factory: pytest.TempPathFactory) -> Shots:
    copy = Path("out/web") if os.environ.get("RIS_PLANNER_SCREENSHOTS") else None
    return Shots(tmp_path_factory.mktemp("screenshots"), copy)


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    tmp = tmp_path_factory.mktemp("web-server")
    with served(tmp / "jobs.db", workers=2, log=tmp / "server.log") as srv:
        yield srv.url


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    with sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_FLAGS)
        try:
            yield b
        finally:
            b.close()


class Console:
    """Console errors and page errors of a page; ``allow`` adds an expected pattern."""

    def __init__(self, page: Page) -> None:
        self.errors: list[str] = []
        self.allowed: list[re.Pattern[str]] = []
        page.on("console", self._on_console)
        page.on("pageerror", lambda exc: self.errors.append(f"page error: {exc}"))

    def _on_console(self, msg: ConsoleMessage) -> None:
        if msg.type in ("error", "assert"):
            self.errors.append(msg.text)

    def allow(self, pattern: str) -> None:
        self.allowed.append(re.compile(pattern))

    def unexpected(self) -> list[str]:
        return [e for e in self.errors if not any(p.search(e) for p in self.allowed)]


@pytest.fixture
def page(browser: Browser) -> Iterator[tuple[Page, Console]]:
    context = browser.new_context(viewport={"width": 1280, "height": 900})
    context.set_default_timeout(WAIT_MS)  # clicks, fills, waits for a locator
    pg = context.new_page()
    console = Console(pg)
    try:
        yield pg, console
        assert console.unexpected() == []
    finally:
        context.close()


def open_page(pg: Page, url: str) -> None:
    pg.goto(url + "/")
    expect(pg.locator("#server-status")).to_contain_text("Server ok")
    expect(pg.locator("#preset option[value='fig10-anchors']")).to_be_attached()


def load_preset(pg: Page, name: str) -> None:
    pg.select_option("#preset", name)
    pg.click("#load-preset")
    expect(pg.locator("#validation-status")).to_contain_text("Valid:", timeout=WAIT_MS)


def screen_of(pg: Page, x: float, y: float) -> tuple[float, float]:
    """Page (client) coordinates of the local point (x, y) on the map, to the whole pixel (the
    browser takes a mouse event's position to whole pixels: a pointer put there is within
    half a pixel of the point along each axis)."""
    got: list[float] = pg.evaluate("([x, y]) => window.risPlanner.screenOf(x, y)", [x, y])
    return round(got[0]), round(got[1])


def quiet(pg: Page) -> None:
    """Wait out the page's automatic validation after an edit (a 300 ms debounce, then the
    request, the status text and a redraw: window.risPlanner.busy()) – these move the page
    under the pointer, so a click during them can miss on a busy machine."""
    pg.wait_for_function("() => !window.risPlanner.busy()", timeout=WAIT_MS)


def settle(pg: Page) -> None:
    """:func:`quiet`, and the validation said the document is valid (no redraw replaces a
    marker under the pointer)."""
    quiet(pg)
    expect(pg.locator("#validation-status")).to_have_text(re.compile(r"^Valid: "))


def set_box(pg: Page, selector: str, checked: bool = True) -> None:
    """Tick or clear a checkbox once the page is :func:`quiet` (the clock offset box missed a
    click during a validation's redraw in a CI run of 7 December 2026)."""
    quiet(pg)
    pg.set_checked(selector, checked)


def map_info(pg: Page) -> dict[str, Any]:
    """What the map draws: per UE map the points drawn and those inside buildings, the sites."""
    info: dict[str, Any] = pg.evaluate("window.risPlanner.mapInfo()")
    return info


def drawn_ue_points(pg: Page) -> int:
    return sum(m["drawn"] for m in map_info(pg)["ues"])


def split_header_words(pg: Page, selector: str) -> list[str]:
    """Words of the header cells matching ``selector`` that the browser laid out on more than
    one line (a word broken inside, as "RI S")."""
    found: list[str] = pg.evaluate(
        """(sel) => {
          const out = [];
          for (const th of document.querySelectorAll(sel)) {
            if (th.offsetParent === null) continue;  // not shown
            const walk = document.createTreeWalker(th, NodeFilter.SHOW_TEXT);
            for (let n = walk.nextNode(); n; n = walk.nextNode()) {
              const re = /\\S+/g;
              let m;
              while ((m = re.exec(n.textContent))) {
                const r = document.createRange();
                r.setStart(n, m.index);
                r.setEnd(n, m.index + m[0].length);
                const tops = new Set([...r.getClientRects()].filter((q) => q.width > 0)
                  .map((q) => Math.round(q.top)));
                if (tops.size !== 1) out.push(`${th.textContent.trim()}: ${m[0]}`);
              }
            }
          }
          return out;
        }""",
        selector,
    )
    return found


def path_vertices(path: Any) -> tuple[list[float], list[float]]:
    """The x and y pixel coordinates of an SVG path's vertices (its "d": M x y L x y … z)."""
    nums = [float(v) for v in re.findall(r"-?\d+(?:\.\d+)?", path.get_attribute("d") or "")]
    return nums[0::2], nums[1::2]


def js_num(v: float) -> str:
    """A number as the page prints it (app.js ``fmtNum``, 3 significant digits): "0.253", "0.16",
    "1230", "1.23e-4"."""
    if v == 0:
        return "0"
    if abs(v) >= 1e4 or abs(v) < 1e-3:
        mant, exp = f"{v:.2e}".split("e")
        return f"{mant}e{int(exp):+d}"
    x = float(f"{v:.3g}")
    return str(int(x)) if x.is_integer() else repr(x)


def page_share(v: float, share: float) -> str:
    """An objective value of a coverage and its share of the servable pairs as the page prints
    them: "0.253 = 25.4 % of the servable pairs"."""
    return f"{js_num(v)} = {100 * share:.1f} % of the servable pairs"


DENOMINATOR = re.compile(
    r"\s+of (?:the servable pairs|all pairs|the bound|the better layout's objective"
    r"|this point's pairs|the \d+ checked pairs|the (?:pair |map )?weight)(?![A-Za-z])"
)
"""The page's rule for a share of a plan: every "x %" it prints in the results and in a point's
box is followed at once by "of" and what it is a share of – the servable pairs (the coverage,
its bound and gap, the sizing target), all pairs (the servable and blind pairs' weight, the
diagnosis's served fraction), the bound (a relative gap), the better layout's objective (the
diagnosis's spread), this point's pairs (a point's served fraction), the N checked pairs (the
estimator check) or the weight (the diagnosis's messages, written by the server: of all pairs'
or of the map's weight). No bare percentage."""


def undeclared_percentages(pg: Page, selector: str = "#results, #point-info") -> list[str]:
    """Every "x %" in the text of the ``selector`` boxes (hidden parts included, each text node
    on its own) not followed by its denominator (:data:`DENOMINATOR`), with its text node."""
    texts: list[str] = pg.evaluate(
        """(sel) => [...document.querySelectorAll(sel)].flatMap((box) => {
          const out = [];
          const walk = document.createTreeWalker(box, NodeFilter.SHOW_TEXT);
          for (let n = walk.nextNode(); n; n = walk.nextNode()) out.push(n.textContent);
          return out;
        })""",
        selector,
    )
    return [
        text
        for text in texts
        for m in re.finditer(r"\d(?:[\d.]*\d)?\s*%", text)
        if not DENOMINATOR.match(text, m.end())
    ]


def no_horizontal_scroll(pg: Page) -> None:
    width = pg.evaluate("document.documentElement.scrollWidth")
    assert width <= 1280, f"page is {width} px wide at a 1280 px window"


def unlabelled_controls(pg: Page) -> list[str]:
    """Visible inputs, selects and buttons without an accessible name."""
    found: list[str] = pg.evaluate(
        """(() => [...document.querySelectorAll('input, select, button')]
          .filter(el => el.offsetParent !== null)
          .filter(el => !((el.labels && el.labels.length) || el.getAttribute('aria-label')
                          || el.getAttribute('aria-labelledby')
                          || (el.tagName === 'BUTTON' && el.textContent.trim())))
          .map(el => el.id || el.outerHTML.slice(0, 80)))()"""
    )
    return found


def low_contrast_text(pg: Page) -> list[str]:
    """HTML elements with their own visible text whose colour against the first opaque
    background behind them is below WCAG AA (4.5:1; 3:1 for large text)."""
    found: list[str] = pg.evaluate(
        """(() => {
          const rgb = (c) => (c.match(/[0-9.]+/g) || []).map(Number);
          const lum = ([r, g, b]) => {
            const f = (v) => {
              v /= 255;
              return v <= 0.03928 ? v / 12.92 : ((v + 0.055) / 1.055) ** 2.4;
            };
            return 0.2126 * f(r) + 0.7152 * f(g) + 0.0722 * f(b);
          };
          const bg = (el) => {
            for (let e = el; e; e = e.parentElement) {
              const c = rgb(getComputedStyle(e).backgroundColor);
              if (c.length === 3 || (c.length === 4 && c[3] === 1)) return c.slice(0, 3);
            }
            return [255, 255, 255];
          };
          const out = [];
          for (const el of document.body.querySelectorAll('*')) {
            if (el.closest('svg') || el.offsetParent === null) continue;
            const own = [...el.childNodes].some(n => n.nodeType === 3 && n.textContent.trim());
            if (!own) continue;
            const st = getComputedStyle(el);
            const a = lum(rgb(st.color)), b = lum(bg(el));
            const ratio = (Math.max(a, b) + 0.05) / (Math.min(a, b) + 0.05);
            const size = parseFloat(st.fontSize), bold = Number(st.fontWeight) >= 700;
            const need = size >= 24 || (bold && size >= 18.66) ? 3 : 4.5;
            if (ratio < need) out.push(`${el.tagName}#${el.id}: ${ratio.toFixed(2)}`);
          }
          return out;
        })()"""
    )
    return found


def test_plan_job_end_to_end(page: tuple[Page, Console], server: str, shots: Shots) -> None:
    pg, _ = page
    open_page(pg, server)
    load_preset(pg, "fig10-anchors")
    # the site to scale: 4 candidates with facing arrows, the 98-point UE map
    assert pg.locator("#candidates .site").count() == 4
    assert drawn_ue_points(pg) == 98
    expect(pg.locator("#validation-status")).to_contain_text("4 candidate sites, 4753 TX–RX pairs")
    shots.take(pg, "01-preset-loaded")
    # edit: coverage of PEB_R ≤ 2 cm (a contour that cuts through the map), counts 2 and 4
    pg.select_option("#f-objective-kind", "coverage")
    expect(pg.locator("#label-objective-level")).to_have_text("Coverage threshold [m]")
    pg.fill("#f-objective-level", "0.02")
    pg.fill("#f-ris_count", "2, 4")
    pg.click("#validate")
    expect(pg.locator("#validation-status")).to_contain_text("2 RIS: 6 layouts")
    pg.click("#submit")
    expect(pg.locator("#progress-text")).to_have_text("100 %", timeout=WAIT_MS)
    expect(pg.locator("#job-status")).to_contain_text("succeeded")
    assert pg.locator("#progress").get_attribute("value") == "100"
    expect(pg.locator("#heatmap-image")).to_be_attached(timeout=WAIT_MS)
    job_id = pg.evaluate("window.risPlanner.state.job.id")
    view = httpx.get(f"{server}/v1/jobs/{job_id}", timeout=HANG_S).json()
    plan = view["result"]
    objective = {k: v for k, v in view["request"]["objective"].items() if v is not None}
    assert objective == {"kind": "coverage", "metric": "rx", "threshold_m": 0.02}
    assert [b["ris_count"] for b in plan["by_count"]] == [2, 4]
    # layout of the largest count on the map, heatmap and contour drawn, legend
    assert pg.locator("#candidates .site.chosen").count() == 4
    for i in plan["by_count"][-1]["sites"]:  # labelled by name and index
        label = pg.locator(f"#candidates .site.chosen[data-site='{i}'] svg > text")
        expect(label).to_contain_text(f"{plan['candidates'][i]['name']} [{i}] · ")
    assert len(pg.locator("#contour").get_attribute("d") or "") > 20
    expect(pg.locator("#legend")).to_contain_text("coverage threshold 0.02 m")
    expect(pg.locator("#count-table tbody tr")).to_have_count(2)
    assert pg.locator("#cdf polyline").count() == 2
    shots.take(pg, "02-results-4-ris")
    # per count the objective with its share of the servable pairs, certified optimal (an
    # exhaustive search), the best sites by name with their index as the command line prints
    # them (plan.json site_names), the search with the layouts it evaluated
    servable = plan["pairs_summary"]["servable_weight"]
    for row, entry in zip(pg.locator("#count-table tbody tr").all(), plan["by_count"], strict=True):
        expect(row.locator("td.objective")).to_have_text(
            page_share(entry["objective"], entry["share_of_servable"])
        )
        assert entry["certificate"]["exact"]
        expect(row.locator("td.bound")).to_have_text("optimal")
        sites = ", ".join(
            f"{n} [{i}]" for n, i in zip(entry["site_names"], entry["sites"], strict=True)
        )
        expect(row.locator("td.sites")).to_have_text(sites)
        expect(row.locator("td.search")).to_have_text(
            f"{entry['method']}, {entry['layouts_evaluated']} of {entry['layouts_total']}"
            " layouts evaluated"
        )
    expect(pg.locator("#pairs-note")).to_contain_text(
        f"{100 * servable:.1f} % of all pairs by weight – those some layout of the candidates"
        " can locate at all; every share below is of them"
    )
    expect(pg.locator("#search-why")).to_have_count(0)  # the search asked for ran
    # click a point: the page shows plan.json's bound for it
    target = plan["points"][10]
    x, y = target["position"][:2]
    pg.locator("#map").scroll_into_view_if_needed()
    pg.mouse.click(*screen_of(pg, x, y))
    row = pg.locator(f"#point-info tr[data-point='{target['index']}']")
    expect(row).to_be_visible()
    shown = row.locator("td[data-count='4'] .bound").inner_text()
    assert float(shown.split()[0]) == pytest.approx(target["bound_m"]["4"], rel=BOUND_DIGITS_RTOL)
    names = [c["name"] for c in plan["candidates"]]
    serving = ", ".join(f"{names[s]} [{s}]" for s in target["serving"]["4"])
    expect(row.locator("td[data-count='4']")).to_contain_text(f"sites {serving}")
    served = target["served_fraction"]["4"]
    expect(row.locator("td[data-count='4'] .served")).to_have_text(
        f"served: {100 * served:.1f} % of this point's pairs"
    )
    # every share printed for the plan says what it is a share of
    assert undeclared_percentages(pg) == []
    shots.take(pg, "03-point-clicked")
    # keyboard: the map takes focus, an arrow key moves to a neighbouring point
    pg.focus("#map")
    pg.keyboard.press("ArrowRight")
    moved = pg.evaluate("window.risPlanner.state.selected")
    assert plan["points"][moved]["position"][0] > x
    # another count by keyboard (radio group: arrow keys): its best layout (2 sites)
    pg.focus("#count-4")
    pg.keyboard.press("ArrowLeft")
    expect(pg.locator("#count-2")).to_be_checked()
    expect(pg.locator("#count-2")).to_be_focused()
    assert pg.locator("#candidates .site.chosen").count() == 2
    assert (
        pg.locator("#candidates .site.chosen").evaluate_all(
            "els => els.map(e => Number(e.dataset.site))"
        )
        == plan["by_count"][0]["sites"]
    )
    # downloads: plan.json and every file of the job
    links = pg.locator("#downloads a")
    names = links.all_inner_texts()  # PNG figures, then the GIS files (GeoJSON, GeoTIFF, CSV)
    assert names[:4] == ["plan.json", "topview", "heatmap", "cdf"]
    assert {"geojson", "geotiff", "points_csv"} <= set(names[4:])
    with pg.expect_download() as dl:
        links.first.click()
    saved = json.loads(Path(dl.value.path()).read_text())
    assert saved["by_count"] == plan["by_count"]
    for name, url in view["figures"].items():
        assert pg.locator(f"#downloads a[href='{url}']").inner_text() == name
    # the list is generic over a job's files: figures and any "files" (dict or list) appear
    listed = pg.evaluate(
        "window.risPlanner.jobFiles({figures: {cdf: '/v1/jobs/x/figures/cdf'},"
        " files: {coverage: '/v1/jobs/x/files/coverage.geojson',"
        " raster: {url: '/v1/jobs/x/files/peb.tif'}}})"
    )
    assert [(f["name"], f["ext"]) for f in listed] == [
        ("cdf", "PNG"),
        ("coverage", "GEOJSON"),
        ("raster", "TIF"),
    ]
    listed = pg.evaluate("window.risPlanner.jobFiles({files: [{name: 'a.csv', url: '/f/1'}]})")
    assert [(f["name"], f["url"], f["ext"]) for f in listed] == [("a.csv", "/f/1", "CSV")]
    # the job list has it, with what it was
    row = pg.locator(f"#jobs-body tr[data-job='{job_id}']")
    expect(row).to_contain_text("succeeded")
    expect(row).to_contain_text("2/4 RIS · coverage")
    no_horizontal_scroll(pg)
    assert unlabelled_controls(pg) == []
    assert low_contrast_text(pg) == []
    shots.take(pg, "04-count-2")
    # headers break between words only, also in a narrow window (the counts table's 9 columns
    # and long site names squeeze them)
    for width in (1280, 1024, 800):
        pg.set_viewport_size({"width": width, "height": 900})
        assert split_header_words(pg, "#count-table th, #jobs-table th") == [], width
        assert pg.locator("#count-table thead th").first.inner_text() == "RIS"


def test_validation_errors_next_to_their_fields(
    page: tuple[Page, Console], server: str, shots: Shots
) -> None:
    pg, console = page
    console.allow(r"status of 422")  # the browser logs each 422 answer it receives
    open_page(pg, server)
    load_preset(pg, "fig10-anchors")
    pg.fill("#f-ris-rows", "0")
    pg.fill("#f-power", "loud")
    pg.click("#validate")
    rows_err = pg.locator("#err-f-ris-rows")
    expect(rows_err).to_contain_text("ris.rows: Input should be greater than or equal to 1")
    expect(pg.locator("#err-f-power")).to_contain_text("system.tx_power_dbm")
    assert pg.locator("#f-ris-rows").get_attribute("aria-invalid") == "true"
    assert pg.locator("#f-ris-cols").get_attribute("aria-invalid") is None
    shots.take(pg, "05-validation-errors")
    # an engine check without a field path lands at the field its message names
    pg.fill("#f-ris-rows", "10")
    pg.fill("#f-power", "30")
    pg.fill("#f-ris_count", "2, 9")
    pg.click("#submit")
    expect(pg.locator("#err-f-ris_count")).to_contain_text("ris_count 9 exceeds the 4 candidate")
    expect(pg.locator("#err-f-ris-rows")).to_be_hidden()
    assert httpx.get(f"{server}/v1/jobs?status=queued", timeout=HANG_S).json()["total"] == 0
    body = pg.locator("body").inner_text()
    assert "Traceback" not in body and "Internal Server Error" not in body


def test_cancel_a_running_job(page: tuple[Page, Console], server: str, shots: Shots) -> None:
    pg, _ = page
    open_page(pg, server)
    pg.set_input_files(
        "#upload",
        files=[
            {
                "name": "slow.json",
                "mimeType": "application/json",
                "buffer": json.dumps(slow_plan_doc()).encode(),
            }
        ],
    )
    expect(pg.locator("#validation-status")).to_contain_text("24 candidate sites", timeout=WAIT_MS)
    expect(pg.locator("#doc-name")).to_contain_text("slow.json")
    pg.click("#submit")
    expect(pg.locator("#job-status")).to_contain_text("running", timeout=WAIT_MS)
    expect(pg.locator("#cancel")).to_be_enabled()
    shots.take(pg, "06-running")
    pg.click("#cancel")
    expect(pg.locator("#job-status")).to_contain_text("cancelled", timeout=WAIT_MS)
    expect(pg.locator("#cancel")).to_be_disabled()
    job_id = pg.evaluate("window.risPlanner.state.job.id")
    assert httpx.get(f"{server}/v1/jobs/{job_id}", timeout=HANG_S).json()["status"] == "cancelled"
    expect(pg.locator(f"#jobs-body tr[data-job='{job_id}']")).to_contain_text("cancelled")
    assert int(pg.locator("#progress").get_attribute("value") or "0") < 100
    shots.take(pg, "07-cancelled")


def test_obstacles_drawn_to_scale(page: tuple[Page, Console], server: str, shots: Shots) -> None:
    """A document's environment: a 4 m × 2 m prism as a polygon and a 6 m wall as a line, at the
    map's scale (pixels per metre the same along x and y)."""
    pg, console = page
    console.allow(r"status of 422")  # a server whose plans take no environment yet says so
    doc = plan_preset_doc("fig10-anchors")
    doc["environment"] = {
        "obstacles": [
            {
                "kind": "prism",
                "name": "cabinet",
                "footprint": [[-1, -1], [3, -1], [3, 1], [-1, 1]],
                "base_m": 0,
                "height_m": 2,
            },
            {"kind": "wall", "start": [-2, -3], "end": [-2, 3], "base_m": 0, "height_m": 2.5},
        ]
    }
    open_page(pg, server)
    pg.set_input_files(
        "#upload",
        files=[
            {"name": "env.json", "mimeType": "application/json", "buffer": json.dumps(doc).encode()}
        ],
    )
    expect(pg.locator("#doc-name")).to_contain_text("env.json")
    # the view is fitted to the site once its preview (with the UE map) is there
    expect(pg.locator("#validation-status")).to_contain_text("Valid:", timeout=WAIT_MS)
    prism = pg.locator("path.prism")
    expect(prism).to_have_count(1)
    k = pg.evaluate("window.risPlanner.pxPerMetre()")
    xs, ys = path_vertices(prism)
    # the map puts vertices on whole pixels: each side within a pixel of its length
    assert max(xs) - min(xs) == pytest.approx(4 * k, abs=1.01)
    assert max(ys) - min(ys) == pytest.approx(2 * k, abs=1.01)
    wall = pg.locator("path.wall")
    expect(wall).to_have_count(1)
    xs_w, ys_w = path_vertices(wall)
    assert max(ys_w) - min(ys_w) == pytest.approx(6 * k, abs=1.01) and len(set(xs_w)) == 1
    # the prism's corner (−1, −1) where the map puts that point
    box = prism.bounding_box()
    x0, y1 = screen_of(pg, -1, -1)
    # (the box holds the outline's stroke, 1.2 px wide, around the vertices)
    assert box is not None and (box["x"], box["y"] + box["height"]) == (
        pytest.approx(x0, abs=1.11),
        pytest.approx(y1, abs=1.11),
    )
    assert "cabinet" in (prism.locator("title").text_content() or "")
    shots.take(pg, "08-obstacles")


SITE_ORIGIN = (24.9400, 60.1650)
"""Where the browser test's small GeoJSON site lies (central Helsinki)."""


def small_site(bowtie: bool = False) -> dict[str, Any]:
    """A GeoJSON site written here: two buildings (one with levels, one with the default
    height), a residential street between them and three mounting points facing it; with
    ``bowtie`` the first building's outline crosses itself."""
    lon0, lat0 = SITE_ORIGIN
    dlon, dlat = 1 / 55_600, 1 / 111_200  # ≈ 1 m at 60° N

    def ring(x0: float, y0: float, x1: float, y1: float) -> list[list[float]]:
        pts = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
        if bowtie:
            pts = [(x0, y0), (x1, y1), (x1, y0), (x0, y1)]
        return [[lon0 + x * dlon, lat0 + y * dlat] for x, y in [*pts, pts[0]]]

    def feature(geom: dict[str, Any], **props: Any) -> dict[str, Any]:
        return {"type": "Feature", "properties": props, "geometry": geom}

    def point(x: float, y: float) -> dict[str, Any]:
        return {"type": "Point", "coordinates": [lon0 + x * dlon, lat0 + y * dlat]}

    street = [[lon0 - 30 * dlon, lat0], [lon0 + 30 * dlon, lat0]]
    return {
        "type": "FeatureCollection",
        "features": [
            feature(
                {"type": "Polygon", "coordinates": [ring(-20, 8, 0, 20)]},
                building="yes",
                **{"building:levels": 4, "name": "North block"},
            ),
            feature({"type": "Polygon", "coordinates": [ring(0, -22, 25, -8)]}, building="yes"),
            feature({"type": "LineString", "coordinates": street}, highway="residential"),
            feature(point(-10, 7.9), azimuth_deg=180, height=6, tilt_deg=10, name="N1"),
            feature(point(12, -7.9), azimuth_deg=0, height=5, tilt_deg=10, name="S1"),
            feature(point(24, -7.9), azimuth_deg=0, height=5, tilt_deg=10, name="S2"),
        ],
    }


def test_import_a_geojson_site(page: tuple[Page, Console], server: str, shots: Shots) -> None:
    """Upload a GeoJSON site: POST /v1/import turns it into a plan document in WGS84; the page
    draws its buildings, street points and mounting sites in local metres, validates it, plans
    it; outlines that cross themselves are repaired and listed in the report; a building given
    as [lat, lon] is a message next to the file input."""
    pg, console = page
    console.allow(r"status of 422")  # the broken file's answer
    open_page(pg, server)
    expect(pg.locator("#geojson-box")).to_be_visible()  # the server's OpenAPI lists /v1/import
    site = {"name": "block.geojson", "mimeType": "application/geo+json"}
    pg.set_input_files(
        "#upload-geojson", files=[site | {"buffer": json.dumps(small_site()).encode()}]
    )
    expect(pg.locator("#validation-status")).to_contain_text(
        "Valid: 3 candidate sites", timeout=WAIT_MS
    )
    expect(pg.locator("#doc-name")).to_contain_text("block.geojson (imported)")
    expect(pg.locator("#doc-name")).to_contain_text("geographic frame")
    report = pg.locator("#import-report")
    expect(report.locator("tr", has_text="Buildings").first).to_contain_text("2")
    expect(report.locator("tr", has_text="Candidate sites")).to_contain_text("3")
    expect(report.locator("tr", has_text="given the default height")).to_contain_text("1")
    expect(pg.locator("path.prism")).to_have_count(2)
    assert pg.locator("#candidates .site").count() == 3
    doc = pg.evaluate("window.risPlanner.state.doc")
    assert doc["frame"]["origin"][:2] == pytest.approx(SITE_ORIGIN, abs=1e-3)
    n_points = pg.evaluate("window.risPlanner.state.preview.rx_map.total")
    assert drawn_ue_points(pg) == n_points > 0
    # drawn in local metres: the 20 m × 12 m north block at the map's scale
    k = pg.evaluate("window.risPlanner.pxPerMetre()")
    xs, _ = path_vertices(pg.locator("path.prism").first)
    # 1/55 600 ° ≈ 1.000 m at 60.165° N; vertices on whole pixels
    assert max(xs) - min(xs) == pytest.approx(20 * k, rel=0.01, abs=1.01)
    shots.take(pg, "09-imported-site")
    # a plan of the imported (geographic) document runs as a job
    pg.click("#submit")
    expect(pg.locator("#progress-text")).to_have_text("100 %", timeout=WAIT_MS)
    expect(pg.locator("#heatmap-image")).to_be_attached(timeout=WAIT_MS)
    job_id = pg.evaluate("window.risPlanner.state.job.id")
    view = httpx.get(f"{server}/v1/jobs/{job_id}", timeout=HANG_S).json()
    assert view["request"]["frame"] == doc["frame"] and "frame" in view["result"]
    assert "geojson" in view["figures"]
    link = pg.locator(f"#downloads a[href='{view['figures']['geojson']}']")
    assert (link.get_attribute("download") or "").endswith(".geojson")
    shots.take(pg, "10-imported-site-planned")
    # outlines that cross themselves: repaired by default, each named in the report
    broken = site | {"name": "broken.geojson", "buffer": json.dumps(small_site(True)).encode()}
    pg.set_input_files("#upload-geojson", files=[broken])
    expect(pg.locator("#doc-name")).to_contain_text("broken.geojson (imported)", timeout=WAIT_MS)
    repaired = report.locator("tr", has_text="Outlines repaired")
    expect(repaired).to_contain_text("2")
    expect(repaired).to_contain_text("North block at [24.93964")
    # one building as [lat, lon]: the server's message next to the input, the document kept
    swapped = small_site()
    geom = swapped["features"][0]["geometry"]
    geom["coordinates"] = [[[p[1], p[0]] for p in r] for r in geom["coordinates"]]
    bad = site | {"name": "swapped.geojson", "buffer": json.dumps(swapped).encode()}
    pg.set_input_files("#upload-geojson", files=[bad])
    err = pg.locator("#err-upload-geojson")
    expect(err).to_contain_text("swapped.geojson: feature 0 (name 'North block') at [60.165")
    expect(err).to_contain_text("swapped?")
    assert pg.locator("#upload-geojson").get_attribute("aria-invalid") == "true"
    expect(pg.locator("#doc-name")).to_contain_text("broken.geojson (imported)")
    shots.take(pg, "11-import-error")


def test_district_plan_from_the_page(page: tuple[Page, Console], server: str, shots: Shots) -> None:
    """A street site planned with the district search from the page's controls: the methods
    listed as GET /v1/search-methods lists them, a control enabled exactly when the chosen
    method honours its option (a document asking the district search for one it does not –
    a sweep – refused with the server's message);
    sidelink pairs at most 30 m apart along the streets with line of sight, a coverage target of
    80 %; the job runs through POST /v1/plans with its progress, and the page shows the one
    results view of every plan: per count the objective with its share of the servable pairs,
    the certified bound and the gap, the sites by name and index, the sizing in the unified
    shape, the CDF and gain charts, district.png; every share with its denominator."""
    from district_site import street_doc

    pg, console = page
    console.allow(r"status of 422")  # the document asking the district search for a sweep
    doc = street_doc(counts=(2, 3))
    doc["pairs"] = {"sample": 300, "seed": 3}  # the page adds the pair model
    del doc["search"]  # and the method
    open_page(pg, server)
    spec = httpx.get(f"{server}/openapi.json", timeout=HANG_S).json()["components"]["schemas"]
    pair_props = spec["PairSample"]["properties"]
    listed = httpx.get(f"{server}/v1/search-methods", timeout=HANG_S).json()
    district = next(m for m in listed["methods"] if m["name"] == "district")
    caps = district["capabilities"]

    def upload(document: dict[str, Any], name: str) -> None:
        buffer = json.dumps(document).encode()
        files = [{"name": name, "mimeType": "application/json", "buffer": buffer}]
        pg.set_input_files("#upload", files=files)
        expect(pg.locator("#doc-name")).to_contain_text(name)

    # a document asking for a parameter sweep: the district search refuses it, the page says
    # so with the server's message (the option is in the document, not in a control)
    upload(doc | {"sweep": {"ris_size": [[16, 16], [32, 32]]}}, "streets-swept.json")
    expect(pg.locator("#validation-status")).to_contain_text("14 candidate sites", timeout=WAIT_MS)
    pg.select_option("#f-search-method", "district")
    expect(pg.locator("#other-errors")).to_contain_text(
        "sweep: search method 'district' does not give", timeout=WAIT_MS
    )
    upload(doc, "streets.json")
    expect(pg.locator("#validation-status")).to_contain_text("14 candidate sites", timeout=WAIT_MS)
    # the methods: auto and the registered ones, labelled as the server says; the schema's
    # default chosen
    options = pg.locator("#f-search-method option").evaluate_all(
        "els => els.map(e => [e.value, e.textContent])"
    )
    assert options == [[m["name"], m["label"]] for m in [listed["auto"], *listed["methods"]]]
    expect(pg.locator("#f-search-method")).to_have_value(
        spec["SearchSpec"]["properties"]["method"]["default"]
    )
    expect(pg.locator("#f-pairs-separation")).to_have_value(pair_props["separation"]["default"])
    assert pg.is_checked("#f-pairs-los") == pair_props["line_of_sight"]["default"]
    limit = pair_props["max_separation_m"]["anyOf"][0]["maximum"]
    expect(pg.locator("#hint-pairs-maxsep")).to_contain_text(f"{limit:,}".replace(",", " "))
    expect(pg.locator("#f-pairs-maxsep")).to_have_value("")

    def controls(option: str) -> Any:
        return pg.locator(f"[data-plan-option='{option}']")

    # district: a control is enabled exactly when the method honours its option (the sizing
    # and the estimator check it does: their hints keep their own text), the pair models and
    # wavefronts it does not take cannot be picked, the note says what it takes; another
    # method again: enabled
    pg.select_option("#f-search-method", "district")
    for o in listed["options"]:
        for k in range(controls(o["name"]).count()):
            if o["name"] in caps["options"]:
                expect(controls(o["name"]).nth(k)).to_be_enabled()
            else:
                expect(controls(o["name"]).nth(k)).to_be_disabled()
    assert {"sizing", "validation"} <= set(caps["options"])
    expect(pg.locator("#validate-plan")).to_be_enabled()
    expect(pg.locator("#hint-validate-plan")).not_to_contain_text("Not with the")
    choices = (("#f-pairs-mode", caps["pair_models"]), ("#f-wavefront", caps["wavefronts"]))
    for sel, allowed in choices:
        for value in pg.locator(f"{sel} option").evaluate_all("els => els.map(e => e.value)"):
            disabled = pg.locator(f"{sel} option[value='{value}']").is_disabled()
            assert disabled == (value not in allowed), (sel, value)
    expect(pg.locator("#method-note")).to_contain_text(
        f"coverage objectives, at most {caps['max_ris']} RISs"
    )
    pg.select_option("#f-search-method", "exhaustive")
    expect(pg.locator("#validate-plan")).to_be_enabled()
    expect(pg.locator("#f-pairs-mode option[value='unordered']")).to_be_enabled()
    # district search, pairs within 30 m along the streets in line of sight, target 80 %
    pg.select_option("#f-search-method", "district")
    pg.fill("#f-pairs-maxsep", "30")
    pg.select_option("#f-pairs-separation", "street")
    set_box(pg, "#f-pairs-los")
    pg.fill("#f-sizing-target", "80")
    pg.click("#submit")
    expect(pg.locator("#job-status")).to_contain_text("Job ", timeout=WAIT_MS)
    expect(pg.locator("#progress-text")).to_have_text("100 %", timeout=WAIT_MS)
    job_id = pg.evaluate("window.risPlanner.state.job.id")
    view = httpx.get(f"{server}/v1/jobs/{job_id}", timeout=HANG_S).json()
    assert view["status"] == "succeeded", view["error"]
    request, plan = view["request"], view["result"]
    assert request["search"]["method"] == "district"
    assert request["pairs"] == {
        "sample": 300,
        "seed": 3,
        "max_separation_m": 30,
        "separation": "street",
        "line_of_sight": True,
    }
    assert request["sizing"]["target"] == {"objective": 0.8}
    assert plan["search_method"]["used"] == "district" and "district" in view["figures"]
    # the one table of every plan: objective, certified bound and gap with their shares of the
    # servable pairs, the sites by name and index, the search
    servable = plan["pairs_summary"]["servable_weight"]
    table = pg.locator("#count-table")
    expect(table).to_be_visible(timeout=WAIT_MS)
    heads = table.locator("thead th").all_inner_texts()
    assert heads[:4] == ["RIS", "Objective", "Certified bound", "Gap"]
    rows = table.locator("tbody tr")
    expect(rows).to_have_count(len(plan["by_count"]))
    for row, entry in zip(rows.all(), plan["by_count"], strict=True):
        cert = entry["certificate"]
        assert cert["bound_side"] == "upper" and not cert["exact"]
        expect(row.locator("th")).to_have_text(str(entry["ris_count"]))
        expect(row.locator("td.objective")).to_have_text(
            page_share(entry["objective"], entry["share_of_servable"])
        )
        bound = cert["objective_bound"]
        expect(row.locator("td.bound")).to_have_text(f"≤ {page_share(bound, bound / servable)}")
        gap = cert["gap"]
        expect(row.locator("td.gap")).to_have_text(
            f"{page_share(gap, gap / servable)}; {100 * cert['relative_gap']:.1f} % of the bound"
        )
        sites = ", ".join(
            f"{n} [{i}]" for n, i in zip(entry["site_names"], entry["sites"], strict=True)
        )
        expect(row.locator("td.sites")).to_have_text(sites)
        expect(row.locator("td.search")).to_have_text(f"{entry['method']}: {entry['found_by']}")
    assert split_header_words(pg, "#count-table th") == []
    expect(pg.locator("#search-note")).to_contain_text(f"Search: {district['label']}")
    expect(pg.locator("#pairs-note")).to_contain_text(
        f"coverable at this RIS size: {100 * plan['pairs_summary']['coverable_share']:.1f} %"
        " of the servable pairs"
    )
    # the sizing: the server's answer, the certified interval, the sizes tried
    sizing = plan["sizing"]
    answer = sizing["answer"]
    expect(pg.locator("#sizing-answer")).to_contain_text(sizing["message"])
    if answer is not None:
        expect(pg.locator("#sizing-answer")).to_have_attribute("data-count", str(answer["count"]))
        if answer["lower_bound"] is not None and answer["lower_bound"] < answer["count"]:
            expect(pg.locator("#sizing-interval")).to_contain_text(
                f"Certified interval: {answer['lower_bound']} to {answer['count']} RISs"
            )
        expect(pg.locator("#sizing").get_by_role("button", name="Use this size")).to_be_visible()
    expect(pg.locator("#sizing-target")).to_contain_text("at least 80.0 % of the servable pairs")
    expect(pg.locator("#sizing-table tbody tr")).to_have_count(len(sizing["sizes"]))
    # the figure (the job has it), the charts and top layouts of every plan, the shown count's
    # sites on the map
    figure = pg.locator("#district-figure")
    expect(figure).to_be_visible(timeout=WAIT_MS)
    expect(figure).to_have_attribute("data-loaded", "true", timeout=WAIT_MS)
    assert figure.evaluate("img => img.naturalWidth") > 0
    expect(pg.locator("#charts")).to_be_visible()
    expect(pg.locator("#cdf polyline")).to_have_count(len(plan["by_count"]))
    expect(pg.locator("#top-layouts li")).to_have_count(len(plan["by_count"][-1]["top_layouts"]))
    shown = plan["by_count"][-1]["sites"]
    chosen = pg.locator("#candidates .site.chosen")
    expect(chosen).to_have_count(len(shown))
    assert sorted(chosen.evaluate_all("els => els.map(e => Number(e.dataset.site))")) == shown
    assert undeclared_percentages(pg) == []
    no_horizontal_scroll(pg)
    assert unlabelled_controls(pg) == []
    assert low_contrast_text(pg) == []
    shots.take(pg, "13-district")


def test_api_docs_work_offline(browser: Browser, server: str, shots: Shots) -> None:
    """Every request of /docs and /redoc stays on the server (others would be aborted)."""
    context = browser.new_context(viewport={"width": 1280, "height": 900})
    context.set_default_timeout(WAIT_MS)
    outside: list[str] = []

    def only_local(route: Any) -> None:
        url = route.request.url
        if url.startswith(server) or url.startswith(("data:", "blob:")):
            route.continue_()
        else:
            outside.append(url)
            route.abort()

    context.route("**/*", only_local)
    pg = context.new_page()
    console = Console(pg)
    try:
        pg.goto(f"{server}/docs")
        expect(pg.locator(".swagger-ui .info .title")).to_contain_text(
            "ris_planner", timeout=WAIT_MS
        )
        expect(pg.locator(".swagger-ui").get_by_text("/v1/plans/validate")).to_be_visible()
        shots.take(pg, "09-swagger-ui", full_page=False)
        pg.goto(f"{server}/redoc")
        expect(pg.locator("h1").first).to_contain_text("ris_planner", timeout=WAIT_MS)
        shots.take(pg, "10-redoc", full_page=False)
    finally:
        context.close()
    assert outside == []
    assert console.unexpected() == []


def test_server_error_is_a_notice_not_a_traceback(
    page: tuple[Page, Console], server: str, shots: Shots
) -> None:
    """A 500 (here a proxy's HTML page with a traceback, and the service's own JSON 500)
    becomes a short notice; the page never shows the body's traceback."""
    pg, console = page
    console.allow(r"status of 500")
    trace = 'Traceback (most recent call last):\n  File "x.py", line 1\nKeyError: boom'
    pg.route(
        "**/v1/plans/validate",
        lambda route: route.fulfill(status=500, content_type="text/html", body=trace),
    )
    open_page(pg, server)
    pg.select_option("#preset", "fig10-anchors")
    pg.click("#load-preset")
    expect(pg.locator("#banner-text")).to_contain_text("internal problem (HTTP 500)")
    body = json.dumps({"status": 500, "error": "internal_error", "message": trace})
    pg.unroute("**/v1/plans/validate")
    pg.route(
        "**/v1/plans/validate",
        lambda route: route.fulfill(status=500, content_type="application/json", body=body),
    )
    pg.click("#validate")
    expect(pg.locator("#banner-text")).to_contain_text("the server log has the details")
    assert "Traceback" not in pg.locator("body").inner_text()
    assert "KeyError" not in pg.locator("body").inner_text()
    shots.take(pg, "12-server-error", full_page=False)


def test_server_down_gives_a_clear_message(
    page: tuple[Page, Console], tmp_path: Path, shots: Shots
) -> None:
    pg, console = page
    console.allow(r"ERR_CONNECTION_REFUSED")
    with served(tmp_path / "jobs.db", workers=1) as srv:
        open_page(pg, srv.url)
    # the server has stopped
    pg.click("#refresh-jobs")
    expect(pg.locator("#banner")).to_be_visible()
    expect(pg.locator("#banner-text")).to_contain_text("does not answer")
    expect(pg.locator("#server-status")).to_have_text("Server unreachable")
    shots.take(pg, "11-server-down")
