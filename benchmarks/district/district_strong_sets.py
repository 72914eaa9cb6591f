"""The district certificate's diagnostic: per pair, the size of its strong set (the serving
sites outside its longest non-covering prefix of weakest sites: a covering layout holds one of
them) and m_p (the fewest serving sites that can cover it), as a histogram figure and a table.

    python benchmarks/district/bench_district.py --only headline --out DIR   # DIR/headline.json
    python benchmarks/district/district_strong_sets.py DIR/headline.json \
        [--png docs/img/district-strong-sets.png]
    python benchmarks/district/district_strong_sets.py --quick   # the suite's street site

The plan document is read as ``ris-planner plan`` reads it (geographic frames converted).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("plan", type=Path, nargs="?", help="a district plan document")
    ap.add_argument("--png", type=Path, default=None, help="write the histogram figure here")
    ap.add_argument("--quick", action="store_true", help="the suite's small street site")
    args = ap.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from fixtures import district_inputs, quick_street_plan

    if args.quick:
        args.plan = quick_street_plan("strong-sets-")
    elif args.plan is None:
        ap.error("a plan document is needed (or --quick)")

    from ris_planner.planning.certify.district_cuts import static_cuts
    from ris_planner.planning.certify.district_lp import sites_needed
    from ris_planner.planning.scoring.sparse import build_problem

    inputs = district_inputs(args.plan)
    t0 = time.perf_counter()
    problem = build_problem(inputs)
    t1 = time.perf_counter()
    needs = sites_needed(problem)
    t2 = time.perf_counter()
    cuts = static_cuts(problem, needs.need)
    t3 = time.perf_counter()
    live = needs.need > 0
    serving = np.diff(problem.pair_start)[live]
    strong = cuts.strong[live]
    print(
        f"# Strong sets ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}): {args.plan.name},"
        f" {problem.n_sites} candidates, {problem.n_pairs} pairs, {int(live.sum())} coverable"
    )
    print(
        f"information {t1 - t0:.1f} s, m_p {t2 - t1:.1f} s, static cuts {t3 - t2:.1f} s"
        f" ({cuts.tests} exact evaluations, {cuts.rows.n_rows} rows,"
        f" {int((cuts.rows.y_coef == 2).sum())} of them two-site rows)"
    )
    q = [0, 10, 25, 50, 75, 90, 100]
    print("| per coverable pair | " + " | ".join(f"{p} %" for p in q) + " | mean |")
    print("|---|" + "---|" * (len(q) + 1))
    for name, v in (("serving sites", serving), ("strong set", strong)):
        cells = " | ".join(f"{x:.0f}" for x in np.percentile(v, q))
        print(f"| {name} | {cells} | {v.mean():.1f} |")
    m, n = np.unique(needs.need[live], return_counts=True)
    print("m_p: " + ", ".join(f"{int(a)}: {int(b)} pairs" for a, b in zip(m, n, strict=True)))
    if args.png is None:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 3.6))
    bins = np.arange(0, max(int(serving.max()), 1) + 10, 10)
    left.hist(serving, bins=bins, alpha=0.5, label="serving sites S_p")
    left.hist(strong, bins=bins, alpha=0.8, label="strong set (S_p minus longest non-cover)")
    left.set_xlabel("sites per coverable pair")
    left.set_ylabel("pairs")
    left.legend(fontsize=8)
    right.bar([str(int(a)) for a in m], n)
    right.set_xlabel("m_p (fewest serving sites that can cover the pair)")
    right.set_ylabel("pairs")
    title = f"{args.plan.stem}: {problem.n_sites} candidates, {int(live.sum())} coverable pairs"
    fig.suptitle(title)
    fig.tight_layout()
    args.png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.png, dpi=110)
    print(f"wrote {args.png}")


if __name__ == "__main__":
    main()
