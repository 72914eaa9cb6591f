"""The benchmark suite's own structure (docs/validation/benchmarks.md, "How the benchmarks are
organised"): every script lies in an area and has a quick mode that ``make bench`` runs, the
shared fixtures build valid documents, and the A/B harness alternates its trees and reports
the ratio new / old with its spread. No timing is asserted."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "benchmarks"
sys.path.insert(0, str(BENCH))

import fixtures  # noqa: E402
import harness  # noqa: E402
import quick  # noqa: E402

from ris_planner.model.plan import PlanDocument  # noqa: E402
from ris_planner.model.scenario import Scenario  # noqa: E402


def test_every_script_lies_in_an_area_and_the_quick_pass_runs_it() -> None:
    scripts = {
        (p.parent.name, p.name)
        for p in BENCH.glob("*/*.py")
        if p.parent.name != "asv" and p.name != "__init__.py"
    }
    listed = {(area, argv[0]) for area, cmds in quick.QUICK.items() for argv in cmds}
    assert scripts == listed
    # the shared modules, and nothing else, at the top
    assert {p.name for p in BENCH.glob("*.py")} == {"fixtures.py", "harness.py", "quick.py"}
    for area, cmds in quick.QUICK.items():
        for argv in cmds:
            text = (BENCH / area / argv[0]).read_text()
            mode = next(a for a in argv[1:] if a in ("--quick", "--smoke") or "{work}" in a)
            harnessed = mode == "--quick" and "add_tree_arguments(" in text  # the harness's flag
            assert mode.startswith("{") or f'"{mode}"' in text or harnessed, (area, argv[0])


@pytest.mark.parametrize(
    "document",
    [
        fixtures.square_plan(),
        fixtures.hall_document([2, 3]),
        fixtures.small_hall(),
        fixtures.city_grid_document(2, 400, [2]),
        fixtures.smoke_document(),
        fixtures.street_document(counts=(2,)),
    ],
)
def test_the_planning_fixtures_are_valid_plan_documents(document: dict) -> None:
    PlanDocument.model_validate(document)


def test_the_bounds_fixtures_are_valid_scenarios() -> None:
    for layout in fixtures.FIG10_LAYOUTS:
        Scenario.model_validate(fixtures.fig10_document(layout, "random"))
        Scenario.model_validate(fixtures.fig10_document(layout, None))
    Scenario.model_validate(fixtures.spherical_document("4-ris"))
    Scenario.model_validate(fixtures.table1_document())
    tx, rx = fixtures.fig10_pairs()
    assert tx.shape == rx.shape == (4753, 3)


def test_the_kamppi_block_is_the_committed_example() -> None:
    from ris_planner.io.frames import to_local

    doc = fixtures.helsinki_block(1000)
    local = PlanDocument.model_validate(to_local(doc)[0])
    assert local.pairs.sample == 1000 and (local.ris.rows, local.ris.cols) == (64, 64)
    assert local.ris_count == [2, 3, 4] and len(local.candidates) == 26


def test_alternate_flips_the_order_every_round_and_compare_pairs_the_rounds() -> None:
    trees = {"old": harness.Tree("old", ROOT), "new": harness.Tree("new", ROOT)}
    calls: list[tuple[str, int]] = []
    warmed: list[str] = []

    def measure(tree: harness.Tree, r: int) -> float:
        calls.append((tree.name, r))
        return {"old": 2.0, "new": 1.0}[tree.name] * (1 + r)

    runs = harness.alternate(trees, measure, 3, warm=lambda t: warmed.append(t.name))
    assert warmed == ["old", "new"]
    assert calls == [("old", 0), ("new", 0), ("new", 1), ("old", 1), ("old", 2), ("new", 2)]
    c = harness.compare(runs["old"], runs["new"])
    assert (c.old, c.new, c.ratio, c.low, c.high, c.rounds) == (4.0, 2.0, 0.5, 0.5, 0.5, 3)
    spread = harness.compare([1.0, 2.0], [1.5, 2.0])
    assert (spread.low, spread.high) == (1.0, 1.5)


def test_a_base_tree_has_its_own_numba_cache_and_runs_its_own_code(tmp_path: Path) -> None:
    """A tree's processes import its code first and, for a base, use the cache inside it."""
    (tmp_path / "probe.py").write_text("VALUE = 'base'\n")
    base = harness.Tree("old", tmp_path, tmp_path / ".numba-cache")
    code = "import json, os, probe; print(json.dumps([probe.VALUE, os.environ['NUMBA_CACHE_DIR']]))"
    got = harness.run_in_tree(base, code)
    assert got == ["base", str(tmp_path / ".numba-cache")]
    # this checkout keeps the environment's cache (what make setup compiled)
    assert harness.this_tree().env().get("NUMBA_CACHE_DIR") == os.environ.get("NUMBA_CACHE_DIR")
