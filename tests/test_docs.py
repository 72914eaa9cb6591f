"""The documentation site builds offline with ``mkdocs build --strict`` (docs/, mkdocs.yml), the
README stays a front page, nothing cites a file outside the repository, every cited path and
module exists, speed figures live on the validation pages only, the explaining pages narrate no
history, and no code or page names an issue by its number."""

from __future__ import annotations

import importlib
import importlib.util
import json
import os
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from waits import HANG_MS, HANG_S

ROOT = Path(__file__).resolve().parent.parent
README_MAX_LINES = 150
FORBIDDEN = (b"DESIGN.md", b"shared/")
SKIP_PARTS = {"__pycache__", ".mypy_cache", ".ruff_cache", ".pytest_cache"}


def _mkdocs_or_skip() -> None:
    if importlib.util.find_spec("mkdocs") is None or importlib.util.find_spec("material") is None:
        message = (
            "mkdocs / mkdocs-material are not installed: the docs build needs the 'docs' extra"
            " (pip install -e '.[docs]'; '.[dev]' includes it)"
        )
        if os.environ.get("CI") == "true":
            pytest.fail(message)
        pytest.skip(message)


API_PAGES = (
    "ris_planner",
    "model",
    "bounds",
    "planning",
    "power",
    "estimation",
    "environment",
    "io",
    "runtime",
)
SPHINX_ROLE = re.compile(r":(?:py:)?(?:func|class|mod|meth|attr|data|exc|obj):")


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The site, built once with ``mkdocs build --strict`` (a warning fails the build)."""
    _mkdocs_or_skip()
    site = tmp_path_factory.mktemp("docs") / "site"
    env = dict(os.environ, PYTHONPATH=str(ROOT), NO_MKDOCS_2_WARNING="1")
    run = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(site)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=HANG_S,
    )
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-4000:]
    return site


def test_docs_build_strict_offline(site: Path) -> None:
    # the pages generated from the code are there and not empty
    rest = (site / "reference" / "rest.html").read_text(encoding="utf-8")
    assert "/v1/bounds" in rest and "/v1/plans" in rest
    schemas = (site / "reference" / "schemas.html").read_text(encoding="utf-8")
    assert "Scenario document" in schemas and "clock_offset_m" in schemas
    settings = (site / "reference" / "settings.html").read_text(encoding="utf-8")
    assert "RIS_PLANNER_MAX_PAIRS" in settings and "RIS_PLANNER_CACHE_MEMORY_MB" in settings
    assert "ris-planner plan" in (site / "reference" / "cli.html").read_text(encoding="utf-8")
    assert "compute_bounds" in (site / "reference" / "python.html").read_text(encoding="utf-8")
    numerics = (site / "concepts" / "numerics.html").read_text(encoding="utf-8")
    assert 'id="comparing-results"' in numerics  # tests/tolerance.py points there
    # offline: no page loads a stylesheet, script or font from another origin
    remote = re.compile(r'<(?:script|link|img)\b[^>]*\b(?:src|href)="(?:https?:)?//', re.I)
    for page in site.rglob("*.html"):
        text = page.read_text(encoding="utf-8")
        for match in remote.finditer(text):
            tag = text[match.start() : text.find(">", match.start()) + 1]
            # <link rel="canonical"> style metadata is not a load; anything else is
            assert 'rel="canonical"' in tag, f"{page.relative_to(site)} loads {tag}"


def test_python_api_is_a_reference(site: Path) -> None:
    """One page per public area; entries of their own for the top-level functions, signatures
    with annotations, no private helpers, no Sphinx role printed raw."""
    pages = {name: (site / "reference" / "api" / f"{name}.html") for name in API_PAGES}
    texts = {name: page.read_text(encoding="utf-8") for name, page in pages.items()}
    top = texts["ris_planner"]
    for name in ("load_scenario", "compute_bounds", "BoundsResult"):
        assert f'id="ris_planner.{name}"' in top, name
    assert 'id="ris_planner.power.run_power"' in texts["power"]
    assert 'id="ris_planner.planning.run_plan"' in texts["planning"]
    # separate signatures with their annotations (the return type of compute_bounds)
    signature = top.split('id="ris_planner.compute_bounds"')[1]
    assert "doc-signature" in signature and "BoundsResult" in signature
    # numpy sections: BoundsResult's attribute descriptions are descriptions, not types
    attributes = top.split('id="ris_planner.BoundsResult"')[1].split('id="ris_planner.')[0]
    rows = re.findall(r'<tr class="doc-section-item">(.*?)</tr>', attributes, flags=re.S)
    cells = [re.findall(r"<td>(.*?)</td>", row, flags=re.S) for row in rows]
    ceb = next(c for c in cells if ">ceb<" in c[0])
    assert "FloatArray" in ceb[1] and "clock-offset error bound" in ceb[2]
    assert not any("error bound" in c[1] for c in cells), "a description in the Type column"
    for name, text in texts.items():
        assert not SPHINX_ROLE.search(text), f"{name}: raw Sphinx role"
        private = re.findall(r'id="ris_planner(?:\.\w+)*\._[a-z]\w*"', text)
        assert not private, f"{name}: private entries {private[:3]}"
        assert len(text) < 400_000, f"{name}: {len(text)} bytes on one page"
    overview = (site / "reference" / "python.html").read_text(encoding="utf-8")
    for name in API_PAGES:
        assert f"api/{name}.html" in overview, name


def test_model_equations_are_typeset(site: Path) -> None:
    """The model page's formulas are LaTeX for KaTeX (arithmatex, generic), numbered with the
    paper's labels; KaTeX is served from the site itself."""
    model = (site / "concepts" / "model.html").read_text(encoding="utf-8")
    assert model.count('class="arithmatex"') >= 13
    outside = re.sub(r'<(span|div) class="arithmatex">.*?</\1>', "", model, flags=re.S)
    assert "^{" not in outside and "_{" not in outside, "a formula left as raw text"
    for label in ("FIM\\_measurement", "crb\\_sidelink", "PEBT", "PEBR", "CEB"):
        assert label in model, label
    assert model.count("\\tag*{(") == 13
    katex = site / "javascripts" / "katex"
    assert (katex / "katex.min.js").stat().st_size > 100_000
    assert (katex / "katex.min.css").is_file()
    assert list((katex / "fonts").glob("KaTeX_Main-Regular.woff2"))
    assert 'src="../javascripts/katex/katex.min.js"' in model
    assert 'href="../javascripts/katex/katex.min.css"' in model
    css = (katex / "katex.min.css").read_text(encoding="utf-8")
    assert "http://" not in css and "https://" not in css
    for url in re.findall(r"url\((fonts/[^)]+\.woff2)\)", css):
        assert (katex / url).is_file(), url


def test_readme_is_a_front_page() -> None:
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines"


def test_no_citation_outside_the_repository() -> None:
    hits = []
    for top in ("ris_planner", "api", "docs"):
        for path in sorted((ROOT / top).rglob("*")):
            if not path.is_file() or SKIP_PARTS & set(path.parts):
                continue
            data = path.read_bytes()
            hits += [f"{path.relative_to(ROOT)}: {f.decode()}" for f in FORBIDDEN if f in data]
    assert not hits, "cite docs pages and the paper's labels instead:\n" + "\n".join(hits)


# --- the pages' text: cited paths, speed figures, history, issue numbers -------------------

PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
CITED_PATH = re.compile(
    r"(?<![\w/.(-])((?:ris_planner|tests|benchmarks|examples|api|docs|scripts)/[\w./-]*\w)"
)
CITED_MODULE = re.compile(r"(?<![\w/.])(ris_planner(?:\.\w+)+)")
IGNORED_PATHS = {"benchmarks/asv/.asv"}
"""Cited paths that are made by a run (asv's results folder, ignored by git)."""
EXPLAINING_PAGES = [
    ROOT / "README.md",
    ROOT / "docs" / "index.md",
    ROOT / "docs" / "getting-started.md",
    *sorted((ROOT / "docs" / "concepts").glob("*.md")),
    *sorted((ROOT / "docs" / "guides").glob("*.md")),
    *sorted((ROOT / "docs" / "reference").rglob("*.md")),
]
"""Pages that explain (README, start, concepts, guides, reference): no speed figures there."""
TIMING = re.compile(
    r"(?<![\w.])\d+(?:[.,]\d+)?(?:\s*[–-]\s*\d+(?:\.\d+)?)?\s?(?:s|ms|min|µs|h)\b(?![-\w])"
)
NOT_A_SPEED = re.compile(
    r"every|≤|backoff|backs off|doubling|lock|timeout|default|at most|bound|_S`|lasts|busy"
)
"""Durations that are settings, not speeds: intervals, timeouts, limits (the words beside)."""
HISTORY = (
    "as before",
    "before this",
    "used to",
    "previously",
    "this round",
    "we changed",
    "the issue",
    "is now",
    "are now",
    "went from",
)
"""Phrases that narrate the code's history; docs/history.md is the one place for it."""
ISSUE_NUMBER = re.compile(r"\bissues?[ -]#?\d+", re.I)
CODE_DIRS = ("ris_planner", "api", "tests", "benchmarks", "examples", "scripts")


def _prose(page: Path) -> Iterator[tuple[int, str]]:
    """(line number, line) of a page outside its fenced blocks and HTML comments."""
    inside = False
    for number, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1):
        if line.lstrip().startswith(("```", "~~~")):
            inside = not inside
            continue
        if not inside and not line.lstrip().startswith("<!--"):
            yield number, line


def test_every_cited_path_exists_and_module_imports() -> None:
    missing, unknown = [], []
    for page in PAGES:
        text = re.sub(r"\]\([^)]*\)", "]", page.read_text(encoding="utf-8"))  # link targets
        name = page.relative_to(ROOT)
        for path in sorted(set(CITED_PATH.findall(text)) - IGNORED_PATHS):
            if not (ROOT / path).exists():
                missing.append(f"{name}: {path}")
        for dotted in sorted(set(CITED_MODULE.findall(text))):
            if not _resolves(dotted):
                unknown.append(f"{name}: {dotted}")
    assert not missing, "cited paths that do not exist:\n" + "\n".join(missing)
    assert not unknown, "cited names that do not import:\n" + "\n".join(unknown)


def _resolves(dotted: str) -> bool:
    """``ris_planner.a.b`` names a module, or a module's attribute (a function, a class)."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for attr in parts[cut:]:
            if not hasattr(obj, attr):
                return False
            obj = getattr(obj, attr)
        return True
    return False


def test_speed_figures_only_on_validation_pages() -> None:
    hits = []
    for page in EXPLAINING_PAGES:
        for number, line in _prose(page):
            for match in TIMING.finditer(line):
                context = line[max(0, match.start() - 30) : match.end() + 15]
                if not NOT_A_SPEED.search(context):
                    hits.append(f"{page.relative_to(ROOT)}:{number}: {context.strip()}")
    assert not hits, (
        "speed figures belong on docs/validation/ with their date and machine"
        " (docs/validation/measured-times.md):\n" + "\n".join(hits)
    )


def test_concepts_and_guides_do_not_narrate_history() -> None:
    hits = []
    for page in EXPLAINING_PAGES:
        for number, line in _prose(page):
            for phrase in HISTORY:
                if re.search(rf"\b{phrase}\b", line, re.I):
                    hits.append(f"{page.relative_to(ROOT)}:{number}: {phrase!r}")
    assert not hits, "explain what is, not how it came to be:\n" + "\n".join(hits)


def test_no_issue_numbers_in_code_or_docs() -> None:
    hits = []
    files = [p for d in CODE_DIRS for p in sorted((ROOT / d).rglob("*.py"))]
    files += [p for p in PAGES if p.name != "history.md"]
    for path in files:
        if SKIP_PARTS & set(path.parts):
            continue
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if ISSUE_NUMBER.search(line):
                hits.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()[:80]}")
    assert not hits, "say what an issue asked for, not its number:\n" + "\n".join(hits)


ENDPOINT = re.compile(r"`(GET|POST|PUT|PATCH|DELETE) (/[^`?\s]*)")
PATH_PARAMETER = re.compile(r"\{[^}]*\}")


def _route(method: str, path: str) -> str:
    """``METHOD /path`` with every path parameter written ``{}``."""
    return f"{method.upper()} {PATH_PARAMETER.sub('{}', path)}"


def test_rest_guide_lists_every_route() -> None:
    """The REST guide's endpoint table names every operation of the service's OpenAPI
    document (method and path, any name for a path parameter), and nothing else but the page
    at ``GET /``."""
    from api.main import create_app
    from api.settings import Settings

    spec = create_app(Settings()).openapi()
    served = {_route(m, p) for p, item in spec["paths"].items() for m in item}
    text = (ROOT / "docs" / "guides" / "rest.md").read_text(encoding="utf-8")
    table = text.split("| endpoint | what |", 1)[1].split("\n\n", 1)[0]
    first_cells = [row.split("|")[1] for row in table.splitlines() if row.count("|") > 2]
    listed = {_route(m, p) for cell in first_cells for m, p in ENDPOINT.findall(cell)}
    assert served <= listed, f"routes missing from the REST guide: {sorted(served - listed)}"
    assert listed - served <= {"GET /"}, f"listed, not served: {sorted(listed - served)}"


def test_import_guide_names_each_option_as_each_entry_point_does() -> None:
    """The import guide's table of options gives, per option, the name of the Python field
    (``ImportOptions``), of the command line's flag and of the REST query parameter, and its
    default: each is that entry point's own, and every option of each is in the table."""
    import argparse
    import dataclasses

    from api.main import create_app
    from api.settings import Settings
    from ris_planner.cli.app import build_parser
    from ris_planner.io.import_options import ImportOptions

    python = {f.name: f.default for f in dataclasses.fields(ImportOptions)}
    parser = build_parser("import")
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    cli = {s: a.default for a in sub.choices["import"]._actions for s in a.option_strings}
    spec = create_app(Settings()).openapi()["paths"]["/v1/import"]["post"]["parameters"]
    rest = {p["name"]: p["schema"].get("default") for p in spec if p["in"] == "query"}
    text = (ROOT / "docs" / "guides" / "import.md").read_text(encoding="utf-8")
    table = text.split("| Python (`ImportOptions`) | CLI | REST query | Default |", 1)[1]
    rows = [r.split("|")[1:5] for r in table.split("\n\n", 1)[0].splitlines()[2:]]
    seen: dict[str, set[str]] = {"python": set(), "cli": set(), "rest": set()}
    for cells in rows:
        py, flag, query, default = (c.strip().strip("`") for c in cells)
        assert py in python and flag in cli and query in rest, cells
        seen["python"].add(py)
        seen["cli"].add(flag)
        seen["rest"].add(query)
        number = re.fullmatch(r"([\d.]+) m", default)
        if number:
            value = float(number.group(1))
            assert python[py] == cli[flag] == rest[query] == value, (cells, python[py])
    assert seen["python"] == set(python), set(python) - seen["python"]
    # the flags and query parameters that are not import options: output, frame origin, DXF
    assert set(cli) - seen["cli"] == {
        "-h",
        "--help",
        "--out",
        "--plan",
        "--candidates",
        "--origin",
        "--layer",
        "--units",
    }
    assert set(rest) - seen["rest"] == {"format", "origin", "layer", "units"}


def _mkdocs_hooks() -> Any:
    """scripts/mkdocs_hooks.py, which generates the schemas page."""
    spec = importlib.util.spec_from_file_location("mkdocs_hooks", ROOT / "scripts/mkdocs_hooks.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _expected_default(info: Any) -> str:
    """A field's default as the page shows it: JSON, ``{}`` for a nested model of defaults."""
    from pydantic import BaseModel
    from pydantic_core import to_jsonable_python

    if info.is_required():
        return "required"
    value = info.get_default(call_default_factory=True)
    if isinstance(value, BaseModel):
        assert value == type(value)(), f"{value!r} is not its model's defaults"
        return "{}"
    return json.dumps(to_jsonable_python(value), ensure_ascii=False)


def test_every_document_model_lists_its_fields_types_and_defaults(site: Path) -> None:
    """Each model of the JSON documents (PlanDocument, SearchSpec, Sizing, PairSample, … – every
    model of the schemas page) has its entry on an API page with a table of every field: its
    type, its default, its unit and its description; the schemas page has one section per
    model with that model's own JSON schema."""
    import html as html_module

    hooks = _mkdocs_hooks()
    models = hooks.schema_models()
    assert {"PlanDocument", "SearchSpec", "Sizing", "PairSample", "Scenario"} <= set(models)
    pages = {p: p.read_text(encoding="utf-8") for p in (site / "reference" / "api").glob("*.html")}
    schemas = (site / "reference" / "schemas.html").read_text(encoding="utf-8")
    for name in models:
        path = hooks._model_path(name)
        assert path is not None, name
        model = getattr(importlib.import_module(path.rpartition(".")[0]), name)
        # its entry: at its module, or where a package above it exports it
        parts = path.split(".")
        ids = [f'id="{".".join(parts[:k])}.{name}"' for k in range(len(parts) - 1, 1, -1)]
        found = [(t, i) for i in ids for t in pages.values() if i in t]
        assert found, f"{path} has no entry on an API page"
        page, anchor = found[0]
        entry = page.split(anchor, 1)[1]
        table = entry.split(f"Fields of <code>{name}</code>", 1)[1].split("</table>", 1)[0]
        assert 'href="../schemas.html#' + name.lower() + '"' in entry.split("<table>", 1)[0]
        rows = re.findall(r"<tr>\s*(.*?)</tr>", table, flags=re.S)[1:]
        cells = {}
        for row in rows:
            cell = [
                re.sub(r"<[^>]+>", "", c).strip()
                for c in re.findall(r"<td>(.*?)</td>", row, flags=re.S)
            ]
            cells[cell[0]] = [html_module.unescape(c) for c in cell]
        assert list(cells) == list(model.model_fields), (name, list(cells))
        for field, info in model.model_fields.items():
            _, type_text, default, unit, _, description = cells[field]
            assert type_text, (name, field)
            assert default == _expected_default(info), (name, field, default)
            shown = " ".join(re.sub(r"`+", "", info.description or "").split())
            assert description == shown, (name, field)
            if field.endswith("_m") and info.annotation in (float, float | None):
                assert unit == "m", (name, field, unit)
        # the schemas page: a section of its own with the model's own schema
        section = schemas.split(f'id="{name.lower()}"', 1)
        assert len(section) == 2, f"no section for {name} on the schemas page"
        block = section[1].split("<details", 1)[1].split("</details>", 1)[0]
        code = block.split("<code>", 1)[1].split("</code>", 1)[0]
        assert json.loads(html_module.unescape(re.sub(r"<[^>]+>", "", code))) == models[name][0]
    assert schemas.count("<details") == len(models), "one JSON schema per model"


TAGGED_EQUATIONS = """() => [...document.querySelectorAll('.katex-display')].flatMap((d) => {
  const tag = d.querySelector('.katex-html > .tag');
  if (!tag) return [];
  const box = (e) => {
    const r = e.getBoundingClientRect();
    return [r.left, r.top, r.right, r.bottom];
  };
  return [{tag: tag.textContent, box: box(tag),
           formula: [...d.querySelectorAll('.katex-html > .base')].map(box)}];
})"""
"""Each numbered display equation of a page: its tag's box and its formula's boxes (KaTeX's
``.base`` spans), in CSS pixels."""


@pytest.mark.parametrize("width", [1280, 1600])
def test_equation_numbers_do_not_cover_their_formulas(site: Path, width: int) -> None:
    """The model page rendered by headless Chromium at a desktop width: no equation tag's box
    intersects its formula's (docs/stylesheets/equations.css)."""
    import functools
    import http.server
    import threading

    from test_web import CHROMIUM, CHROMIUM_FLAGS  # skips (fails under CI) without Chromium

    sync_playwright = importlib.import_module("playwright.sync_api").sync_playwright

    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, *args: Any) -> None:
            pass

    handler = functools.partial(Quiet, directory=str(site))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_FLAGS)
            try:
                page = browser.new_page(viewport={"width": width, "height": 900})
                page.set_default_timeout(HANG_MS)
                page.goto(f"http://127.0.0.1:{server.server_address[1]}/concepts/model.html")
                page.wait_for_function(
                    "document.querySelectorAll('.katex-display .katex-html > .tag').length >= 13",
                    timeout=HANG_MS,
                )
                page.evaluate("document.fonts.ready")
                equations = page.evaluate(TAGGED_EQUATIONS)
            finally:
                browser.close()
    finally:
        server.shutdown()
        server.server_close()
        thread.join()
    assert len(equations) == 13
    for eq in equations:
        left, top, right, bottom = eq["box"]
        assert right > left and bottom > top, eq["tag"]
        for f_left, f_top, f_right, f_bottom in eq["formula"]:
            apart = right <= f_left or f_right <= left or bottom <= f_top or f_bottom <= top
            assert apart, f"at {width} px the tag {eq['tag']!r} covers its formula"
