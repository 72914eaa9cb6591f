"""A realistic planning case: RISs on the facades around a road junction.

Two 8 m wide roads cross at the origin (the east–west main road carries twice the UE density
of the north–south side road); UEs sit at 1.5 m on a 4 m lattice along the roads. The four
corner buildings are prisms of the plan's ``environment`` (12–15 m high): they block every leg
through them, so the LOS between different arms of the junction and RIS legs around corners
are absent. Their road-facing facades, 6 m from the centre lines, carry candidate sites every
8.5 m at 5 m height with two downward tilts, all facing the street (64 candidates, 20×20 RISs,
P = 30 dBm). The objective is the weighted coverage Pr(PEB_R ≤ 0.5 m) over all unordered pairs
of road points, each counted in both directions with half the weight, for 2, 3 and 4 RISs
(``ris_planner/model/presets/plans/junction.json``).

Writes to ``--out``: ``plan.json`` (ranked layouts, per-count comparison), ``topview.png``,
``heatmap.png``, ``cdf.png``, ``by_count.csv`` and the plan document ``junction.json``. With
``--check-greedy`` it also runs the greedy search for the exhaustively searched counts and
prints whether it finds the same best layout.

    python examples/plan_junction.py --out out/junction [--workers 2] [--check-greedy]
"""

from __future__ import annotations

import argparse
import csv
import json
import tempfile
import time
from pathlib import Path

from ris_planner.planning import LocalExecutor, SerialExecutor, plan_preset, run_plan, write_figures
from ris_planner.planning.outputs.report import write_plan_json
from ris_planner.planning.search.layouts import greedy
from ris_planner.runtime.progress import ProgressBar


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("out/junction"))
    ap.add_argument("--workers", type=int, default=None, help="local worker processes")
    ap.add_argument("--check-greedy", action="store_true")
    ap.add_argument(
        "--smoke",
        action="store_true",
        help="tiny sizes, output in a temporary folder (seconds; tests/test_examples.py)",
    )
    args = ap.parse_args()
    doc = plan_preset("junction")
    if args.smoke:  # 1–2 RISs of 8×8 on 200 sampled pairs, in this process
        args.out, args.workers = Path(tempfile.mkdtemp(prefix="ris-smoke-")), 1
        doc |= {"ris": {"rows": 8, "cols": 8}, "pairs": {"sample": 200, "seed": 0}}
        doc |= {"ris_count": [1, 2]}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "junction.json").write_text(json.dumps(doc, indent=1))
    t0 = time.perf_counter()
    with LocalExecutor(args.workers) as ex:
        result = run_plan(doc, ProgressBar("junction"), ex)
    elapsed = time.perf_counter() - t0
    plan = result.to_json()
    write_plan_json(plan, args.out)
    figures = write_figures(result, args.out)
    with (args.out / "by_count.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["ris_count", "sites", "coverage", "median_m", "p90_m", "marginal_gain",
                    "method", "layouts_evaluated", "layouts_total"])  # fmt: skip
        for b in plan["by_count"]:
            w.writerow([b["ris_count"], " ".join(map(str, b["sites"])), b["objective"],
                        b["quantiles_m"]["0.5"], b["quantiles_m"]["0.9"], b["marginal_gain"],
                        b["method"], b["layouts_evaluated"], b["layouts_total"]])  # fmt: skip
    print(f"dropped UE points inside buildings: {plan['dropped_points']}")
    for warning in plan["warnings"]:
        print(f"warning: {warning}")
    n_flag = sum(c["far_field_flag"] for c in plan["candidates"])
    worst = max(c["near_field_fraction"] for c in plan["candidates"])
    print(f"{len(result.sites)} candidates, {n_flag} flagged: near field (d_T d_R/(d_T + d_R)"
          f" < 2D²/λ) for up to {worst:.1%} of the pairs; {result.pairs.size} pairs,"
          f" {elapsed:.1f} s")  # fmt: skip
    for b in plan["by_count"]:
        names = [result.sites[s].name for s in b["sites"]]
        gain = "" if b["marginal_gain"] is None else f", gain {b['marginal_gain']:+.3f}"
        print(f"{b['ris_count']} RIS ({b['method']}): coverage {b['objective']:.3f}{gain}"
              f"  median PEB_R {b['quantiles_m']['0.5']}")  # fmt: skip
        for n in names:
            print(f"    {n}")
    if args.check_greedy:
        for cr in result.counts:
            if cr.outcome.method != "exhaustive":
                continue
            g = greedy(result.scorer, len(result.sites), cr.ris_count, result.document.search,
                       SerialExecutor())  # fmt: skip
            (g_lay, g_loss), (e_lay, e_loss) = g.ranked(1)[0], cr.ranked[0]
            print(f"greedy for {cr.ris_count} RIS: {list(g_lay)} coverage {-g_loss:.3f}"
                  f" ({g.evaluated} of {cr.outcome.total_layouts} layouts); exhaustive:"
                  f" {list(e_lay)} coverage {-e_loss:.3f}")  # fmt: skip
    for p in figures.values():
        print(f"wrote {p}")


if __name__ == "__main__":
    main()
