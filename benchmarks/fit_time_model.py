"""Fit the time model's coefficients (:data:`ris_planner.planning.work.TIME_COEFFICIENTS`) to
the per-stage CPU seconds of a ``bench_memory.py --stages --json FILE`` run
(docs/validation/resources.md, "The time estimate per stage").

A linear programme over the coefficients (all ≥ 0): minimise the sum over cases and stages of
|model − measured| / max(measured, 0.05 s) (each stage close to its own measurement), subject
to ``--low`` ≤ MARGIN · model / wall ≤ ``--high`` for every case's whole plan (the estimate's
contract: never below the measured time, within 2× of it, with room on both sides for another
machine's load). Prints the coefficients as Python for ``work.py`` and the ratios they give.
A coefficient of a term that no case exercises (all its sizes 0) or in :data:`NOT_FITTED`
stays what ``work.py`` has.

    python benchmarks/bench_memory.py --stages --json runs.json
    python benchmarks/fit_time_model.py runs.json [--low 1.08 --high 1.85]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import linprog

from ris_planner.planning.work import MARGIN, TIME_COEFFICIENTS

NOT_FITTED = {("visibility", "per_site_point_obstacle"), ("rollout", "per_layout_pair")}
"""Terms kept at work.py's value: no case has obstacles, and the nested chain's layouts cost
what the search's do (no case runs a nested roll-out)."""


def fit(
    rows: list[dict[str, Any]], low: float, high: float
) -> tuple[dict[str, dict[str, float]], list[float]]:
    """(the fitted coefficients, each case's MARGIN · model / wall)."""
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
        for st in stages:
            a = np.zeros(n_x + n_slack)
            for i, j in enumerate(free):
                if cols[j][0] == st:
                    a[i] = sizes[j]
            y = r["cpu_stages_s"].get(st, 0.0) - fixed[st]
            scale = max(r["cpu_stages_s"].get(st, 0.0), 0.05)
            for sign in (1.0, -1.0):
                row = sign * a / scale
                row[k] = -1.0
                a_ub.append(row)
                b_ub.append(sign * y / scale)
            k += 1
        whole = np.zeros(n_x + n_slack)
        whole[:n_x] = [sizes[j] for j in free]
        rest = sum(fixed.values())
        wall = r["seconds"]
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
        * sum(coef[st][t] * v for st, sz in r["terms"].items() for t, v in sz.items())
        / r["seconds"]
        for r in rows
    ]
    return coef, ratios


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", type=Path, help="bench_memory.py --stages --json output")
    ap.add_argument("--low", type=float, default=1.08)
    ap.add_argument("--high", type=float, default=1.85)
    opts = ap.parse_args(argv)
    rows = [r for r in json.loads(opts.runs.read_text()) if "terms" in r]
    coef, ratios = fit(rows, opts.low, opts.high)
    print("TIME_COEFFICIENTS = {")
    for st, terms in coef.items():
        print(f'    "{st}": {{' + ", ".join(f'"{t}": {v:.3g}' for t, v in terms.items()) + "},")
    print("}")
    for r, q in zip(rows, ratios, strict=True):
        print(f"{r['case']['name']:40s} estimate / wall {q:.2f}")


if __name__ == "__main__":
    main()
