"""Benchmark: beams and power for a recommended layout, time per stage.

Plans the preset (default ``hall``) for one RIS count, then for its best layout times:
the served masks per (pair, RIS), the map-drawn DIR / DIR+DER design, the stacked per-beam
information on the design positions, the γ_P search, the SDP, and the re-evaluation of each
design on the plan's full pair set. As a naive reference measured in the same run, the γ_P
search is repeated with ``compute_bounds`` for every evaluation (what the stacked information
replaces).

    python benchmarks/power/bench_beams.py [--preset hall] [--count 3] [--positions 64] [--quick]

``--quick``: the Fig. 10 anchor preset, 2 RISs, 16 design positions.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from ris_planner.environment import Scene
from ris_planner.planning import SerialExecutor, plan_preset, run_plan
from ris_planner.planning.beams import (
    design_beams,
    design_positions,
    evaluate_layout_beams,
    layout_scenario,
    served_pairs,
)
from ris_planner.power.gamma import search_gamma_p
from ris_planner.power.information import beam_information
from ris_planner.power.report import design_objective
from ris_planner.power.sdp import mean_trace_bound, objective_index, solve_power_sdp


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--preset", default="hall")
    ap.add_argument("--count", type=int, default=3)
    ap.add_argument("--positions", type=int, default=64)
    ap.add_argument("--quick", action="store_true", help="fig10-anchors, 2 RISs, 16 positions")
    args = ap.parse_args()
    if args.quick:
        args.preset, args.count, args.positions = "fig10-anchors", 2, 16
    doc = plan_preset(args.preset) | {"ris_count": [args.count]}
    doc.pop("beams", None)
    t0 = time.perf_counter()
    result = run_plan(doc, executor=SerialExecutor())
    t_plan = time.perf_counter() - t0
    plan = result.document
    lay = result.counts[0].ranked[0][0]
    ris = [result.sites[s].ris for s in lay]
    pairs = result.pairs
    env = getattr(plan, "environment", None)
    print(f"{args.preset}: {len(result.sites)} candidates, {pairs.size} pairs, plan {t_plan:.2f} s")
    print(f"best {args.count}-RIS layout {list(lay)}")
    stages: dict[str, float] = {}

    t = time.perf_counter()
    served = served_pairs(Scene.from_environment(env), ris, pairs)
    stages["served masks"] = time.perf_counter() - t
    t = time.perf_counter()
    beams = design_beams(plan.system, ris, pairs, served, seed=0)
    stages["DIR / DIR+DER design"] = time.perf_counter() - t
    scenario = layout_scenario(plan.system, ris, list(plan.known), env)
    metric = result.layout_metric(lay)
    pick = design_positions(pairs.weights, np.isfinite(metric[: pairs.size]), args.positions, 0)
    tx, rx = pairs.tx[pick], pairs.rx[pick]
    t = time.perf_counter()
    info = beam_information(scenario, tx, rx, beams.derivative)
    stages["stacked beam information"] = time.perf_counter() - t
    index = objective_index(info, "rx")
    t = time.perf_counter()
    fast = search_gamma_p(lambda p: mean_trace_bound(info, p, index), beams.beam_types)
    stages["γ_P search (stacked)"] = time.perf_counter() - t
    t = time.perf_counter()
    naive = search_gamma_p(
        design_objective(scenario, tx, rx, beams.derivative, "rx"), beams.beam_types
    )
    stages["γ_P search (compute_bounds each, naive)"] = time.perf_counter() - t
    t = time.perf_counter()
    sdp = solve_power_sdp(info, "rx")
    stages["SDP"] = time.perf_counter() - t
    t = time.perf_counter()
    report = evaluate_layout_beams(
        scenario,
        pairs,
        plan.objective,
        metric,
        served,
        positions=args.positions,
        mirror=result.scorer.mirror,
    )
    stages["whole evaluate_layout_beams"] = time.perf_counter() - t
    for name, secs in stages.items():
        print(f"  {name:42s} {secs:8.3f} s")
    ratio = stages["γ_P search (compute_bounds each, naive)"] / stages["γ_P search (stacked)"]
    print(f"  γ_P: stacked {fast.value:.4f} vs naive {naive.value:.4f}, {ratio:.1f}× faster")
    print(f"  SDP {sdp.status}, {len(pick)} design positions")
    for key, val in report.objective.items():
        print(f"  objective {key:18s} {val}")


if __name__ == "__main__":
    main()
