"""A memory refusal explains every term its estimate can have: each term of a plan's and of a
power allocation's estimate is one entry of a table (``PLAN_MEMORY_TERMS``,
``POWER_MEMORY_TERMS``) holding its bytes with what the refusal says about it, so a new term
cannot lack its description. For each term (taken from the tables themselves) a shape dominated
by it is refused with a message that names it and the largest value that fits, or says that
nothing fits and which settings to change; the 512 × 512 RIS of the schema's maximum is refused
with 413 by the service and exit status 2 by the command line, never an internal error."""

from __future__ import annotations

import io
import json
import subprocess
import sys
from contextlib import redirect_stderr
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
from api_helpers import api_client
from test_api_plans import small_plan_doc
from test_limits import power_doc
from waits import HANG_S

from ris_planner.core.errors import LimitExceededError
from ris_planner.model.limits import (
    LIMITS,
    MemoryTerm,
    Sizes,
    advise_memory,
    check_sizes,
    memory_terms,
)
from ris_planner.planning import PlanDocument, plan_preset
from ris_planner.planning.resources.admission import (
    PLAN_MEMORY_TERMS,
    PlanShape,
    estimate_plan,
    largest_plan_shape,
    plan_memory,
    validate_plan,
)
from ris_planner.power.resources import (
    POWER_MEMORY_TERMS,
    PowerShape,
    estimate_power,
    power_shape,
    validate_power,
)

PLAN_SHAPE = PlanShape(
    sites=20,
    tx_points=200,
    rx_points=300,
    pairs=3000,
    csv_rows=100,
    layouts=5000,
    counts=2,
    max_count=3,
    elements=400,
    ris_side=(20, 20),
    transmissions=64,
    wavefront="planar",
    fixed_heatmap_tx=False,
    relaxed_counts=1,
    sizing_runs=2,
    validation_candidates=5000,
)
"""A small plan every term of whose estimate is above zero (a count searched greedily, the
sizing question and the validation included)."""

POWER_SHAPE = PowerShape(beams=64, positions=100, elements=800)

TABLES: dict[str, tuple[dict[str, Any], Any]] = {
    "plan": (PLAN_MEMORY_TERMS, PLAN_SHAPE),
    "district": (PLAN_MEMORY_TERMS, replace(PLAN_SHAPE, district=True)),
    "power": (POWER_MEMORY_TERMS, POWER_SHAPE),
}
"""Each estimate's table with a shape; a plan's terms split between the searches that
enumerate layouts and the district search (search.method 'district')."""
TERMS = [
    (table, name)
    for table, (terms, shape) in TABLES.items()
    for name, size in memory_terms(terms, shape).items()
    if size > 0
]


def test_every_term_is_tried_in_some_table() -> None:
    for terms, _ in TABLES.values():
        assert set(terms) <= {name for _, name in TERMS}


def _total(terms: dict[str, MemoryTerm[Any]], shape: Any) -> int:
    return sum(memory_terms(terms, shape).values())


def _dominated_by(table: str, name: str) -> tuple[dict[str, MemoryTerm[Any]], Any]:
    """The table with the term ``name`` ten times the largest other one, and its shape."""
    terms, shape = TABLES[table]
    sizes = memory_terms(terms, shape)
    assert sizes[name] > 0, (table, name, sizes)
    scale = 1 + 10 * max(sizes.values()) // sizes[name]
    term: MemoryTerm[Any] = terms[name]
    scaled = replace(term, bytes=lambda s: scale * term.bytes(s))
    return dict(terms) | {name: scaled}, shape


@pytest.mark.parametrize(("table", "name"), TERMS, ids=[f"{t}:{n}" for t, n in TERMS])
def test_a_shape_dominated_by_any_term_is_refused_naming_it(table: str, name: str) -> None:
    terms, shape = _dominated_by(table, name)
    term = terms[name]
    sizes = memory_terms(terms, shape)
    assert name in term.what(shape)  # the phrase names the term
    rest = _total(terms, shape) - sizes[name]
    fixed = sum(b for n, b in sizes.items() if terms[n].fixed and n != name)
    # a fixed term: at and far above the budget by itself; any other: the estimate just above
    # the budget (a knob, when the term has one, finds a value that fits), then the other
    # terms just below it and above it (lowering the term alone may not be enough)
    budgets = (
        [sizes[name], sizes[name] // 2]
        if term.fixed
        else [_total(terms, shape) - 1, rest + 1, (fixed + rest) // 2]
    )
    for budget in budgets:
        advice = advise_memory(terms, shape, budget)
        assert advice.term == name, (budget, advice.text)
        assert advice.text.startswith(f"dominated by {term.what(shape)}: "), advice.text
        if advice.knob is None:
            assert advice.value is None and term.otherwise in advice.text, advice.text
            assert "by itself" in advice.text or "nothing fits by lowering it alone" in advice.text
            continue
        # the value is exact: it fits, one more does not (the shape itself does not)
        knob, value = advice.knob, advice.value
        assert value is not None and knob.fits.format(knob.show(shape, value)) in advice.text
        assert _total(terms, knob.make(shape, value)) <= budget
        low, now = knob.span(shape)
        assert low <= value < now
        assert _total(terms, knob.make(shape, value + 1)) > budget
    first = advise_memory(terms, shape, budgets[0])
    assert (first.knob is not None) == bool(term.knobs), first.text


def test_the_estimates_are_the_sums_of_their_tables() -> None:
    """No estimate bypasses its table: a term it counts is a term its refusal explains."""
    assert set(plan_memory(PLAN_SHAPE)) == set(PLAN_MEMORY_TERMS)
    doc = PlanDocument.model_validate(small_plan_doc())
    assert estimate_plan(doc).memory_bytes == _total(PLAN_MEMORY_TERMS, largest_plan_shape(doc))
    sc = validate_power(power_doc(64, 20), "rx")
    assert estimate_power(sc).memory_bytes == _total(POWER_MEMORY_TERMS, power_shape(sc))


# --- the largest RIS of the schema --------------------------------------------------------


def big_ris_doc() -> dict[str, Any]:
    """The factory hall with 512 × 512 RISs (the schema's largest): about 7.5 GiB, most of
    it the codebook checks' [N, 512] steering blocks."""
    doc = plan_preset("hall")
    return doc | {"ris": doc["ris"] | {"rows": 512, "cols": 512}}


def _largest_side(msg: str) -> int:
    return int(msg.split("the largest RIS that fits is ")[1].split(" × ")[0])


def test_the_largest_ris_is_refused_with_the_side_that_fits() -> None:
    doc = big_ris_doc()
    with pytest.raises(LimitExceededError) as exc:
        validate_plan(doc, memory_mb=6144)
    msg = str(exc.value)
    assert "above the job memory budget of 6 144 MiB" in msg
    assert "dominated by the codebook checks (512 × 512 elements per RIS" in msg
    side = _largest_side(msg)
    assert 1 <= side < 512 and msg.endswith(f"{side} × {side}")
    validate_plan(doc | {"ris": doc["ris"] | {"rows": side, "cols": side}}, memory_mb=6144)
    with pytest.raises(LimitExceededError):
        big = doc["ris"] | {"rows": side + 1, "cols": side + 1}
        validate_plan(doc | {"ris": big}, memory_mb=6144)


def test_the_service_refuses_the_largest_ris_with_413(tmp_path: Path) -> None:
    doc = big_ris_doc()
    with api_client(tmp_path, workers=1, job_memory_mb=6144) as client:
        for route in ("/v1/plans", "/v1/plans/validate"):
            r = client.post(route, json=doc)
            assert r.status_code == 413, (route, r.text)
            body = r.json()
            assert body["error"] == "too_large" and body["limit"] == 6144, body
            assert "dominated by the codebook checks" in body["message"], body
            assert 1 <= _largest_side(body["message"]) < 512, body
        assert client.get("/v1/jobs").json()["total"] == 0  # nothing was queued


def test_the_command_line_refuses_the_largest_ris_in_one_line(tmp_path: Path) -> None:
    from ris_planner.cli import main

    src = tmp_path / "plan.json"
    src.write_text(json.dumps(big_ris_doc()))
    err = io.StringIO()
    with redirect_stderr(err):
        code = main(["plan", str(src), "--out", str(tmp_path / "out")])
    text = err.getvalue()
    assert code == 2 and text.count("\n") == 1 and text.startswith("error: the run needs"), text
    assert "codebook checks" in text and "the largest RIS that fits is" in text
    assert "Traceback" not in text and "KeyError" not in text and "cannot process" not in text
    assert not (tmp_path / "out").exists()
    # the installed entry point, as the user ran it
    proc = subprocess.run(
        [sys.executable, "-m", "ris_planner.cli", "plan", str(src), "--out", str(tmp_path / "o")],
        capture_output=True,
        text=True,
        timeout=HANG_S,
        env={"PATH": "/usr/bin:/bin", "OPENBLAS_NUM_THREADS": "1"},
        cwd=Path(__file__).parent.parent,
    )
    assert proc.returncode == 2 and proc.stdout == "", proc
    assert proc.stderr.count("\n") == 1 and "codebook checks" in proc.stderr, proc.stderr


# --- the other refusals: the base alone, a power allocation -------------------------------


def test_a_budget_below_the_base_says_so() -> None:
    with pytest.raises(LimitExceededError) as exc:
        validate_plan(small_plan_doc(), memory_mb=300)
    msg = str(exc.value)
    assert "dominated by the base (the interpreter and its imports): 420 MiB" in msg, msg
    assert "by itself" in msg and "RIS_PLANNER_JOB_MEMORY_MB" in msg


def test_a_power_allocation_is_refused_with_the_positions_that_fit() -> None:
    doc = power_doc(768, 200, rows=20)
    budget = 1500
    with pytest.raises(LimitExceededError) as exc:
        validate_power(doc, "rx", memory_mb=budget)
    msg = str(exc.value)
    assert "dominated by the beam information (" in msg, msg
    assert "pairs, sites or map sizes" not in msg  # the plan's advice, once given here too
    best = int(msg.split("the most design positions that fit are ")[1].split(" (")[0])
    assert 1 <= best < 200
    validate_power(power_doc(768, best, rows=20), "rx", memory_mb=budget)
    with pytest.raises(LimitExceededError):
        validate_power(power_doc(768, best + 1, rows=20), "rx", memory_mb=budget)


@pytest.mark.parametrize("name", list(LIMITS))
def test_each_size_limit_is_refused_naming_it(name: str) -> None:
    """The size limits are a table too (``LIMITS``): each is a quantity of :class:`Sizes`
    and is refused with its name, its limit and how to get below it."""
    limit, what, label, hint = LIMITS[name]
    with pytest.raises(LimitExceededError) as exc:
        check_sizes(Sizes(**{name: limit + 1}), memory_mb=None)
    assert str(exc.value) == (
        f"{limit + 1} {what} exceed the {label} limit of {limit} ({name}); {hint}"
    )
    assert exc.value.limit == limit
