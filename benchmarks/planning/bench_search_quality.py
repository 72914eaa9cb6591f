"""Search quality on random small instances against exhaustive search.

For each of ``--instances`` random problems (12–20 random candidate sites, 40–120 random pairs,
a random objective – median, upper quantile, capped mean or coverage of PEB_R, PEB_T or their
maximum –, LOS or not, random known parts; tests/search_quality.py) and each RIS count 2–4, the
greedy search's best layout is compared with the exhaustive optimum, for the greedy search as it
was before the search-quality work (``pre_quality_greedy``, tests/old_search.py) and for
today's greedy search, each without random restarts and with the default 3, in the same run:

* fraction of counts within 1 % of the optimum, worst gap, mean gap;
* counts where the search returned an infinite objective while a finite layout exists;
* layouts evaluated, against the C(S, L) of exhaustive search, and the searches' time ratio.

    python benchmarks/planning/bench_search_quality.py [--instances 200] [--first 0] [--quick]

``--quick``: 3 instances.

Timings are ratios measured in one run; absolute seconds need a quiet machine.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
from old_search import pre_quality_greedy
from search_quality import Comparison, compare_many

from ris_planner.model.plan import SearchSpec
from ris_planner.planning.search.layouts import greedy


def summary(name: str, rows: list[Comparison], seconds: float) -> dict[str, float]:
    gaps = np.array([r.gap for r in rows])
    within = float(np.mean(gaps <= 0.01))
    finite = gaps[np.isfinite(gaps)]
    worst = float(gaps.max()) if gaps.size else 0.0
    inf_bad = sum(r.infinite_when_finite for r in rows)
    evaluated = sum(r.evaluated for r in rows)
    total = sum(r.total for r in rows)
    print(
        f"{name:22s} within 1 %: {within:6.1%}  worst gap: {worst:8.3g}"
        f"  (worst finite {float(finite.max()) if finite.size else 0.0:.3g},"
        f" mean {float(finite.mean()) if finite.size else 0.0:.2e})"
        f"  infinite-when-finite: {inf_bad:3d}  layouts evaluated: {evaluated}"
        f" ({evaluated / total:.2f}× exhaustive's {total})  search time {seconds:.1f} s"
    )
    return {"within": within, "worst": worst, "inf": inf_bad, "evaluated": evaluated}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--instances", type=int, default=200)
    ap.add_argument("--first", type=int, default=0, help="first instance seed")
    ap.add_argument("--verbose", action="store_true", help="print every count off by > 1 %")
    ap.add_argument("--quick", action="store_true", help="3 instances")
    args = ap.parse_args()
    if args.quick:
        args.instances = 3
    seeds = range(args.first, args.first + args.instances)
    results: dict[str, tuple[list[Comparison], float]] = {}
    no_restarts = SearchSpec(restarts=0)
    runs = (
        ("before, no restarts", pre_quality_greedy, no_restarts),
        ("before (restarts 3)", pre_quality_greedy, None),
        ("now, no restarts", greedy, no_restarts),
        ("default now", greedy, None),
    )
    for name, _, _ in runs:
        results[name] = ([], 0.0)
    for s in seeds:
        rows_s, spent_s = compare_many(s, [(fn, spec) for _, fn, spec in runs])
        for (name, _, _), r, t in zip(runs, rows_s, spent_s, strict=True):
            results[name] = (results[name][0] + r, results[name][1] + t)
    print(
        f"{args.instances} random instances × counts 2–4 = {len(results['default now'][0])}"
        " comparisons with exhaustive search"
    )
    by_kind: dict[str, list[int]] = {}
    for i, r in enumerate(results["default now"][0]):
        by_kind.setdefault(r.kind, []).append(i)
    for name, (rows, spent) in results.items():
        summary(name, rows, spent)
        for kind, idx in sorted(by_kind.items()):
            summary(f"  {kind}", [rows[i] for i in idx], math.nan)
    t_old, t_new = results["before (restarts 3)"][1], results["default now"][1]
    print(f"search time ratio now / before: {t_new / t_old:.2f}")
    if args.verbose:
        for name, (rows, _) in results.items():
            for r in rows:
                if r.gap > 0.01:
                    print(f"  {name}: seed {r.seed} {r.kind} L={r.n_ris}: {r.found} vs {r.optimum}")


if __name__ == "__main__":
    main()
