"""Fit the time model's coefficients
(:data:`ris_planner.planning.resources.time_estimate.TIME_COEFFICIENTS`) to
the per-stage CPU seconds of a ``bench_memory.py --stages --json FILE`` run
(docs/validation/resources.md, "The time estimate per stage").

A linear programme over the coefficients (all ≥ 0): minimise the sum over cases and stages of
|model − measured| / max(measured, 0.05 s) (each stage close to its own measurement), subject
to ``--low`` ≤ MARGIN · model / wall ≤ ``--high`` for every case's whole plan (the estimate's
contract: never below the measured time, within 2× of it, with room on both sides for another
machine's load). Prints the coefficients as Python for ``time_estimate.py`` and the ratios they
give.
A case whose checks ran beside the fields and the figures (``"beside"``: their CPU seconds are
counted in those stages) is fitted per stage only for :data:`BEFORE_CHECKS`, and its whole
plan with ``time_estimate.py``'s overlap rule
(:data:`~ris_planner.planning.resources.time_estimate.CHECKS_BESIDE_SHARE`; which of the checks and
the later
stages is the shorter is read from ``time_estimate.py``'s coefficients, so the rule stays linear).
A coefficient of a term that no case exercises (all its sizes 0) or in :data:`NOT_FITTED`
stays what ``time_estimate.py`` has.

The sizes are recomputed from each row's document with today's ``time_estimate.py`` (a bench_memory
case's :func:`case_document`, or the ``--document`` file and variant), so rows measured before
a change of the model's terms still serve; the ``sizing`` stage's size is the modelled seconds
of its runs, so the fit is repeated with its own coefficients until they settle. With ``--cpu``
the whole-plan bounds hold against each row's CPU seconds instead of its wall time (rows
measured on a loaded machine, where the wall time is the load's).

    python benchmarks/resources/bench_memory.py --stages --json runs.json
    python benchmarks/resources/fit_time_model.py runs.json [more.json …] [--low 1.15 --high 1.9]
        [--cpu]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import linprog

from ris_planner.planning.resources.time_estimate import (
    CHECKS_BESIDE_SHARE,
    CHECKS_HIDDEN_BY,
    MARGIN,
    TIME_COEFFICIENTS,
)

BEFORE_CHECKS = {"inputs", "visibility", "cache", "search", "branch_and_bound", "exports"}
"""Stages whose CPU seconds the checks' thread does not share (before it starts, or after it
has been waited for): a case whose checks ran beside keeps its per-stage fit for these."""


def whole_plan_weights(r: dict[str, Any], cols: list[tuple[str, str]]) -> np.ndarray:
    """Per coefficient, its weight in the case's whole-plan model: its size, and for a case
    whose checks ran beside the later stages the overlap rule's subtraction of
    (1 − share) × the shorter of the checks and the later stages (as ``time_estimate.py``'s
    coefficients order them)."""
    sizes = np.array([r["terms"].get(st, {}).get(t, 0.0) for st, t in cols])
    if not r.get("beside"):
        return sizes
    model = {st: 0.0 for st, _ in cols}
    for (st, t), v in zip(cols, sizes, strict=True):
        model[st] += TIME_COEFFICIENTS[st][t] * v
    hidden = (
        ("checks",)
        if model["checks"] <= sum(model[st] for st in CHECKS_HIDDEN_BY)
        else CHECKS_HIDDEN_BY
    )
    return np.array(
        [
            v * (CHECKS_BESIDE_SHARE if st in hidden else 1.0)
            for (st, _), v in zip(cols, sizes, strict=True)
        ]
    )


NOT_FITTED = {("visibility", "per_site_point")}
"""Terms kept at work.py's value: the visibility stage without obstacles takes ≤ 0.02 s on
every case (below the fit's 0.05 s floor, where the programme would use it as slack; the
hall's rate)."""


def fit(
    rows: list[dict[str, Any]], low: float, high: float, cpu: bool = False
) -> tuple[dict[str, dict[str, float]], list[float]]:
    """(the fitted coefficients, each case's MARGIN · model / wall – or / CPU seconds with
    ``cpu``)."""
    stages = list(TIME_COEFFICIENTS)
    cols = [(st, t) for st in stages for t in TIME_COEFFICIENTS[st]]
    used = [
        (st, t) not in NOT_FITTED and any(r["terms"].get(st, {}).get(t, 0.0) > 0 for r in rows)
        for st, t in cols
    ]
    free = [j for j, u in enumerate(used) if u]
    n_x, n_slack = len(free), len(rows) * len(stages)
    cost = np.r_[np.zeros(n_x), np.ones(n_slack)]
    a_ub: list[np.ndarray] = []
    b_ub: list[float] = []
    k = n_x
    for r in rows:
        sizes = [r["terms"].get(st, {}).get(t, 0.0) for st, t in cols]
        fixed = {st: 0.0 for st in stages}  # the terms no case exercises: work.py's value
        for j, (st, t) in enumerate(cols):
            if not used[j]:
                fixed[st] += TIME_COEFFICIENTS[st][t] * sizes[j]
        weights = whole_plan_weights(r, cols)
        for st in stages:
            a = np.zeros(n_x + n_slack)
            for i, j in enumerate(free):
                if cols[j][0] == st:
                    a[i] = sizes[j]
            y = r["cpu_stages_s"].get(st, 0.0) - fixed[st]
            scale = max(r["cpu_stages_s"].get(st, 0.0), 0.05)
            if r.get("beside") and st not in BEFORE_CHECKS:  # CPU shared with the checks' thread
                a, y = np.zeros_like(a), 0.0
            for sign in (1.0, -1.0):
                row = sign * a / scale
                row[k] = -1.0
                a_ub.append(row)
                b_ub.append(sign * y / scale)
            k += 1
        whole = np.zeros(n_x + n_slack)
        whole[:n_x] = [weights[j] for j in free]
        rest = sum(
            TIME_COEFFICIENTS[st][t] * weights[j] for j, (st, t) in enumerate(cols) if not used[j]
        )
        wall = r["cpu_s"] if cpu else r["seconds"]
        a_ub.append(-MARGIN * whole / wall)
        b_ub.append(-low + MARGIN * rest / wall)
        a_ub.append(MARGIN * whole / wall)
        b_ub.append(high - MARGIN * rest / wall)
    res = linprog(cost, A_ub=np.array(a_ub), b_ub=np.array(b_ub), bounds=(0, None), method="highs")
    if res.status != 0:
        raise SystemExit(f"no coefficients meet [{low}, {high}] on every case: {res.message}")
    coef = {st: dict(TIME_COEFFICIENTS[st]) for st in stages}
    for i, j in enumerate(free):
        st, t = cols[j]
        coef[st][t] = float(f"{res.x[i]:.3g}")
    ratios = [
        MARGIN
        * sum(coef[st][t] * w for (st, t), w in zip(cols, whole_plan_weights(r, cols), strict=True))
        / (r["cpu_s"] if cpu else r["seconds"])
        for r in rows
    ]
    return coef, ratios


def row_terms(r: dict[str, Any]) -> dict[str, dict[str, float]]:
    """A row's sizes (``terms``) from its document with today's ``time_estimate.py``: a bench_memory
    case (its site-cache tier's budget set as the bench sets it) or a ``--document`` row."""
    import os
    import sys

    sys.path.insert(0, str(Path(__file__).parent))
    from bench_memory import Case, cache_budget_mb, case_document, variant_document

    from ris_planner.io.frames import to_local
    from ris_planner.planning import PlanDocument
    from ris_planner.planning.resources.time_estimate import stage_terms

    case = r["case"]
    before = os.environ.get("RIS_PLANNER_CACHE_MEMORY_MB")
    try:
        if "document" in case:
            doc = variant_document(json.loads(Path(case["document"]).read_text()), r["variant"])
        else:
            c = Case(**{**case, "ris_count": tuple(case["ris_count"])})
            os.environ["RIS_PLANNER_CACHE_MEMORY_MB"] = str(cache_budget_mb(c))
            doc = case_document(c)
        return stage_terms(PlanDocument.model_validate(to_local(doc)[0]))
    finally:
        if before is None:
            os.environ.pop("RIS_PLANNER_CACHE_MEMORY_MB", None)
        else:
            os.environ["RIS_PLANNER_CACHE_MEMORY_MB"] = before


def main(argv: list[str] | None = None) -> None:
    from ris_planner.planning.resources import time_estimate as work

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", type=Path, nargs="+", help="bench_memory.py --stages --json output")
    ap.add_argument("--low", type=float, default=1.15)
    ap.add_argument("--high", type=float, default=1.9)
    ap.add_argument("--cpu", action="store_true", help="bound the estimate / CPU seconds")
    ap.add_argument("--rounds", type=int, default=3, help="fits (the sizing stage's size)")
    opts = ap.parse_args(argv)
    rows = [r for f in opts.runs for r in json.loads(f.read_text()) if "terms" in r]
    coef: dict[str, dict[str, float]] = {}
    ratios: list[float] = []
    for _ in range(opts.rounds):
        for r in rows:
            r["terms"] = row_terms(r)
        coef, ratios = fit(rows, opts.low, opts.high, opts.cpu)
        for st, terms in coef.items():  # the next round's sizing sizes use these
            work.TIME_COEFFICIENTS[st].update(terms)
    print("TIME_COEFFICIENTS = {")
    for st, terms in coef.items():
        print(f'    "{st}": {{' + ", ".join(f'"{t}": {v:.3g}' for t, v in terms.items()) + "},")
    print("}")
    for r, q in zip(rows, ratios, strict=True):
        print(f"{r['case']['name']:40s} estimate / {'CPU' if opts.cpu else 'wall'} {q:.2f}")


if __name__ == "__main__":
    main()
