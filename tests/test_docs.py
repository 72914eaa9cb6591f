"""The documentation site builds offline with ``mkdocs build --strict`` (docs/, mkdocs.yml), the
README stays a front page, and nothing cites a file outside the repository."""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

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
        timeout=300,
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
